"""Cameras from specs: the product's camera spec (Orthority's interior-parameter schema) and
OpenSfM's camera dictionaries.

Camera spec (a mapping; the ``model:`` of a project YAML camera)::

    type: brown                  # pinhole | brown | opencv | fisheye | frame (film) | rpc
    im_size: [4000, 3000]        # (width, height), pixels
    focal_len: 0.78              # or [fx, fy]: with sensor_size in its units (mm), else
                                 #   normalised by max(width, height)
    sensor_size: [13.2, 8.8]     # optional, (width, height), same units as focal_len
    cx: 0.0                      # principal point offsets from the image centre, normalised
    cy: 0.0                      #   by max(width, height) (Orthority's and OpenSfM's c_x, c_y)
    k1: -0.26                    # distortion terms of the type (missing: 0):
    k2: 0.10                     #   brown  k1 k2 k3 p1 p2; opencv k1-k6 p1 p2 s1-s4;
    p1: 0.0007                   #   fisheye k1-k4 (OpenCV's fisheye)
    ...

The principal point in the product's pixels (top-left pixel centre at 0.5) is
``(w/2 + cx·max(w, h), h/2 + cy·max(w, h))``; Orthority's is the same point in OpenCV pixels
(``(w - 1)/2 + ...``). A normalised focal length is multiplied by ``max(w, h)`` (Orthority's
documentation and OpenSfM's definition; Orthority's code multiplies by the width, the same for
landscape images). ``type: frame`` is the film camera: the project YAML describes it with its
own fields (principal_distance_mm, fiducials_mm, distortion...) and a loaded photo wraps it as
:class:`~toolbox.cameras.frame.FilmFrame` (``Photo.sensor()``); ``type: rpc`` takes
``rpc:`` (Orthority's RPC schema: offsets, scales, the four 20-term polynomials) and
``im_size``, or ``path:`` of an image whose RPCs GDAL reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from toolbox.cameras.intrinsics import (
    FISHEYE_TERMS,
    PERSPECTIVE_TERMS,
    Intrinsics,
    as_pair,
    coefficients_from,
)
from toolbox.errors import InputDataError

MODEL_TYPES = ("pinhole", "brown", "opencv", "fisheye", "frame", "rpc")
#: OpenSfM projection types -> the product's types
OPENSFM_TYPES = {"perspective": "brown", "simple_radial": "brown", "radial": "brown",
                 "brown": "brown", "fisheye": "fisheye", "fisheye_opencv": "fisheye"}


def _kind(spec: Mapping[str, Any], where: str) -> str:
    kind = spec.get("type", spec.get("cam_type"))
    kind = str(getattr(kind, "value", kind)).strip().lower() if kind is not None else None
    if kind not in MODEL_TYPES:
        raise InputDataError(f"{where}: type must be one of {', '.join(MODEL_TYPES)}; got "
                             f"{kind!r}")
    return kind


def create_intrinsics(spec: Mapping[str, Any], name: str = "", tolerance_px: float | None = None
                      ) -> Intrinsics:
    """An interior model (pinhole, brown, opencv, fisheye) from a camera spec (module
    docstring). Unknown keys and terms that the type does not have are errors."""
    where = f"camera {name!r}" if name else "camera"
    if not isinstance(spec, Mapping):
        raise InputDataError(f"{where}: the model must be a mapping, got {spec!r}")
    kind = _kind(spec, where)
    if kind in ("frame", "rpc"):
        raise InputDataError(f"{where}: type {kind} is not a frame model (pinhole, brown, "
                             "opencv, fisheye); a film camera takes the film fields, an rpc "
                             "camera comes from create_camera")
    terms = FISHEYE_TERMS if kind == "fisheye" else PERSPECTIVE_TERMS[kind]
    known = {"type", "cam_type", "im_size", "focal_len", "sensor_size", "cx", "cy", *terms}
    unknown = sorted(set(map(str, spec)) - known)
    if unknown:
        raise InputDataError(f"{where}: a {kind} camera has no {', '.join(unknown)} (keys: "
                             f"{', '.join(sorted(known - {'cam_type'}))})")
    for key in ("im_size", "focal_len"):
        if spec.get(key) is None:
            raise InputDataError(f"{where}: {key} is required")
    w, h = as_pair(spec["im_size"], "im_size", where)
    if not (w == int(w) and h == int(h) and w > 0 and h > 0):
        raise InputDataError(f"{where}: im_size must be two whole numbers of pixels > 0, got "
                             f"{spec['im_size']!r}")
    w, h = int(w), int(h)
    focal = as_pair(spec["focal_len"], "focal_len", where)
    if spec.get("sensor_size") is not None:
        sw, sh = as_pair(spec["sensor_size"], "sensor_size", where)
        if not (sw > 0 and sh > 0):
            raise InputDataError(f"{where}: sensor_size must be > 0, got {spec['sensor_size']!r}")
        fx, fy = focal[0] * w / sw, focal[1] * h / sh
    else:
        fx, fy = focal[0] * max(w, h), focal[1] * max(w, h)
    cx, cy = (float(as_pair(spec.get(k, 0.0) or 0.0, k, where)[0]) for k in ("cx", "cy"))
    s = max(w, h)
    return Intrinsics(kind, (w, h), (fx, fy), (w / 2 + cx * s, h / 2 + cy * s),
                      coefficients_from(spec, terms, where), name, dict(spec),
                      *(() if tolerance_px is None else (tolerance_px,)))


def create_camera(spec: Mapping[str, Any], exterior: Any = None, name: str = "",
                  crs: Any = None) -> Any:
    """A posed camera (:class:`~toolbox.cameras.base.CameraModel`) from a camera spec and the
    exterior orientation (:class:`~toolbox.photogrammetry.exterior.ExteriorOrientation`;
    not used by RPC cameras, whose ground coordinates are in ``crs``)."""
    where = f"camera {name!r}" if name else "camera"
    if not isinstance(spec, Mapping):
        raise InputDataError(f"{where}: the model must be a mapping, got {spec!r}")
    kind = _kind(spec, where)
    if kind == "rpc":
        from toolbox.cameras.rpc import RpcCamera, RpcCoefficients, read_rpc

        if spec.get("path") is not None:
            return read_rpc(spec["path"], crs)
        if spec.get("rpc") is None or spec.get("im_size") is None:
            raise InputDataError(f"{where}: an rpc camera needs 'rpc' and 'im_size', or 'path'")
        w, h = as_pair(spec["im_size"], "im_size", where)
        return RpcCamera(RpcCoefficients.from_mapping(spec["rpc"], where), (int(w), int(h)), crs)
    if kind == "frame":
        raise InputDataError(f"{where}: a film camera (type frame) is described by the project "
                             "YAML's camera fields (principal_distance_mm, fiducials_mm, ...); "
                             "a loaded photo gives its posed camera (Photo.sensor())")
    if exterior is None:
        raise InputDataError(f"{where}: a {kind} camera needs an exterior orientation")
    from toolbox.cameras.frame import FrameCamera

    return FrameCamera(create_intrinsics(spec, name), exterior)


def from_opensfm(camera: Mapping[str, Any], name: str = "") -> dict[str, Any]:
    """OpenSfM's camera dictionary (``reconstruction.json`` / ``cameras.json``: projection_type,
    width, height, focal or focal_x/focal_y, c_x, c_y, k1...) as the product's camera spec.
    OpenSfM normalises focal lengths and c_x, c_y by max(width, height), as the spec does."""
    where = f"OpenSfM camera {name!r}" if name else "OpenSfM camera"
    if not isinstance(camera, Mapping):
        raise InputDataError(f"{where}: expected a mapping, got {camera!r}")
    for key in ("projection_type", "width", "height"):
        if key not in camera:
            raise InputDataError(f"{where}: {key} is missing")
    projection = str(camera["projection_type"]).lower()
    if projection not in OPENSFM_TYPES:
        raise InputDataError(f"{where}: projection_type {projection!r} is not supported "
                             f"(supported: {', '.join(OPENSFM_TYPES)})")
    kind = OPENSFM_TYPES[projection]
    if "focal" in camera:
        focal: Any = camera["focal"]
    elif "focal_x" in camera and "focal_y" in camera:
        focal = [camera["focal_x"], camera["focal_y"]]
    else:
        raise InputDataError(f"{where}: 'focal', or 'focal_x' and 'focal_y', are missing")
    spec: dict[str, Any] = {"type": kind, "im_size": [int(camera["width"]),
                                                      int(camera["height"])],
                            "focal_len": focal, "cx": camera.get("c_x", 0.0),
                            "cy": camera.get("c_y", 0.0)}
    terms = FISHEYE_TERMS if kind == "fisheye" else PERSPECTIVE_TERMS[kind]
    known = {"projection_type", "width", "height", "focal", "focal_x", "focal_y", "c_x", "c_y"}
    unknown = sorted(set(camera) - known - set(terms))
    if unknown:
        raise InputDataError(f"{where}: {projection} has no {', '.join(unknown)}")
    spec.update({k: camera[k] for k in terms if k in camera})
    return spec
