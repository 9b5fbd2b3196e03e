"""Posed frame cameras: an interior model (:mod:`toolbox.cameras.intrinsics`) or the film camera,
with the product's exterior orientation.

Exterior orientation (:mod:`toolbox.photogrammetry.rotation`): ``X - X0 = λ·R·(x, y, -c)``,
``R = R(omega, phi, kappa)`` mapping the photogrammetric image frame (x right, y up, z backwards)
onto ground axes. The OpenCV camera frame (x right, y down, z forward) is that frame with y and
z flipped, so a ground point's camera coordinates are ``D·Rᵀ·(X - X0)``, ``D = diag(1, -1, -1)``
(Orthority and Pix4D convert the same way).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.cameras.intrinsics import Intrinsics
from toolbox.errors import InputDataError

FLIP = np.array([1.0, -1.0, -1.0])  # photogrammetric image frame <-> OpenCV camera frame


def ground_points(xyz: Any) -> np.ndarray:
    """(N, 3) float64 from an (..., 3) array or an (X, Y, Z) tuple of equal-shape arrays."""
    if isinstance(xyz, tuple):
        return np.column_stack([np.asarray(v, dtype="float64").ravel() for v in xyz])
    return np.asarray(xyz, dtype="float64").reshape(-1, 3)


def rays_to_heights(centre: np.ndarray, rays: np.ndarray, z: Any) -> np.ndarray:
    """Points where rays from ``centre`` meet the heights ``z``; NaN for rays that are
    horizontal or meet the height behind the camera."""
    z = np.broadcast_to(np.asarray(z, dtype="float64"), (len(rays),))
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (z - centre[2]) / rays[:, 2]
        t = np.where(t > 0, t, np.nan)
    return centre + t[:, None] * rays


@dataclass(frozen=True, eq=False)
class FrameCamera:
    """An :class:`Intrinsics` model posed by an exterior orientation (the
    :class:`~toolbox.cameras.base.CameraModel` protocol)."""

    intrinsics: Intrinsics
    exterior: Any  # ExteriorOrientation

    @property
    def image_size(self) -> tuple[int, int]:
        return tuple(self.intrinsics.image_size_px)

    @property
    def centre(self) -> np.ndarray:
        return self.exterior.centre

    def to_camera(self, xyz: Any) -> np.ndarray:
        """Ground (N, 3) -> OpenCV camera frame (N, 3): ``D·Rᵀ·(X - X0)``, written out by
        components (numpy's matmul of an (N, 3) by a 3 x 3 is ~30 times slower)."""
        pts = ground_points(xyz)
        r = self.exterior.rotation
        d = [pts[:, k] - self.centre[k] for k in range(3)]
        out = np.empty_like(pts)
        for i, sign in enumerate(FLIP):
            out[:, i] = sign * (r[0, i] * d[0] + r[1, i] * d[1] + r[2, i] * d[2])
        return out

    def project(self, xyz: Any) -> np.ndarray:
        return self.intrinsics.camera_to_pixel(self.to_camera(xyz))

    def project_grid(self, gx: np.ndarray, gy: np.ndarray, z: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`project` of the cells ``(gx, gy, z)`` (arrays broadcastable to z's (h, w)
        shape) as float32 maps ``(cols, rows)`` (NaN: no image) and their ``box``
        (col_min, row_min, col_max, row_max, NaN count), in one compiled pass
        (:func:`toolbox.cameras.kernels.grid_to_pixels`)."""
        from toolbox.cameras.kernels import KIND_FISHEYE, KIND_PERSPECTIVE, grid_to_pixels

        m = self.intrinsics
        z = np.asarray(z, dtype="float64")
        gx = np.broadcast_to(np.asarray(gx, dtype="float64"), z.shape)
        gy = np.broadcast_to(np.asarray(gy, dtype="float64"), z.shape)
        fisheye = m.kind == "fisheye"
        k = np.zeros(12)
        k[:4 if fisheye else 12] = m.opencv_coefficients()
        cols = np.empty(z.shape, dtype="float32")
        rows = np.empty(z.shape, dtype="float32")
        box = np.empty(5)
        grid_to_pixels(gx, gy, z, np.asarray(self.centre, dtype="float64"),
                       np.ascontiguousarray(self.exterior.rotation),
                       KIND_FISHEYE if fisheye else KIND_PERSPECTIVE, k,
                       np.array(m.focal_px, dtype="float64"),
                       np.array(m.principal_point_px, dtype="float64"),
                       min(float(m.valid_radius), 1e300), cols, rows, box)
        return cols, rows, box

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        rays, _ = self.intrinsics.pixel_to_camera(pixels)
        return (rays * FLIP) @ self.exterior.rotation.T

    def pixel_to_ground(self, pixels: np.ndarray, z: Any) -> np.ndarray:
        return rays_to_heights(self.centre, self.unproject(pixels), z)


@dataclass(frozen=True, eq=False)
class FilmFrame:
    """The film (or metric digital) camera of a :class:`~toolbox.photogrammetry.photo.Photo`
    (fiducial interior orientation; radial table, or polynomial k1-k3 with decentring p1, p2)
    behind the :class:`~toolbox.cameras.base.CameraModel` protocol: its own compiled
    collinearity kernels do the work."""

    photo: Any

    @property
    def image_size(self) -> tuple[int, int]:
        size = self.photo.camera.image_size_px
        if size is None:
            raise InputDataError(f"photo {self.photo.id!r}: the camera "
                                 f"{self.photo.camera.name!r} has no image_size_px")
        return tuple(size)

    @property
    def centre(self) -> np.ndarray:
        return self.photo.require_exterior().centre

    def project(self, xyz: Any) -> np.ndarray:
        return self.photo.ground_to_pixel(ground_points(xyz), behind="nan")

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        px = np.asarray(pixels, dtype="float64").reshape(-1, 2)
        p2f = self.photo.require_pixel_transform().pixel_to_fiducial
        hom = np.column_stack([px, np.ones(len(px))]) @ p2f.T
        cam = self.photo.camera
        ideal = cam.image_to_camera(hom[:, :2] / hom[:, 2:])
        rays = np.column_stack([ideal, np.full(len(px), -cam.c)]) @ \
            self.photo.require_exterior().rotation.T
        return rays / np.linalg.norm(rays, axis=1)[:, None]

    def pixel_to_ground(self, pixels: np.ndarray, z: Any) -> np.ndarray:
        return rays_to_heights(self.centre, self.unproject(pixels), z)
