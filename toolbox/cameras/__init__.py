"""Camera models: one protocol (:class:`CameraModel`: ``project``, ``unproject``,
``pixel_to_ground``, ``centre``), the interior models (pinhole, Brown-Conrady, the full OpenCV
model, the OpenCV fisheye), the film camera wrapped (:class:`FilmFrame`), RPC satellite cameras,
and the factory that builds them from a camera spec (Orthority's interior schema) or an OpenSfM
camera. Pixels: top-left pixel centre at (0.5, 0.5); see :mod:`toolbox.cameras.intrinsics`."""

from toolbox.cameras.base import CameraModel, GridProjector
from toolbox.cameras.factory import MODEL_TYPES, create_camera, create_intrinsics, from_opensfm
from toolbox.cameras.frame import FilmFrame, FrameCamera
from toolbox.cameras.intrinsics import DEFAULT_TOLERANCE_PX, Intrinsics
from toolbox.cameras.rpc import RpcCamera, RpcCoefficients, read_rpc, refine_bias

__all__ = ["CameraModel", "GridProjector", "MODEL_TYPES", "create_camera", "create_intrinsics",
           "from_opensfm", "FilmFrame", "FrameCamera", "DEFAULT_TOLERANCE_PX", "Intrinsics", "RpcCamera",
           "RpcCoefficients", "read_rpc", "refine_bias"]
