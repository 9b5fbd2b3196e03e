"""The camera protocol: what every algorithm that touches photos may ask of a camera.

Ground coordinates are those of the camera's exterior orientation (a projected CRS, metres;
heights as the DEM's). Pixels ``(col, row)``: columns right, rows down, the top-left pixel's
centre at ``(0.5, 0.5)``. Every method is vectorised over N points; a point that has no answer
(behind the camera, outside the model's valid field, an undistortion that did not converge)
comes back NaN, never a wrong number.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class CameraModel(Protocol):
    """A posed camera: ground <-> pixel."""

    @property
    def image_size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        ...

    @property
    def centre(self) -> np.ndarray:
        """Projection centre ``(X0, Y0, Z0)`` (3,); NaN for a camera without one (RPC)."""
        ...

    def project(self, xyz: np.ndarray) -> np.ndarray:
        """Ground points (N, 3) -> pixels (N, 2)."""
        ...

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> unit ray directions in ground axes (N, 3), from the camera towards
        the scene."""
        ...

    def pixel_to_ground(self, pixels: np.ndarray, z) -> np.ndarray:
        """Pixels (N, 2) -> ground points (N, 3) on the height(s) ``z`` (scalar or (N,))."""
        ...


@runtime_checkable
class GridProjector(Protocol):
    """A camera that maps a grid of cells in one compiled pass (what the ortho's coordinate map
    uses when the camera offers it)."""

    def project_grid(self, gx: np.ndarray, gy: np.ndarray, z: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cells ``(gx, gy, z)`` (broadcastable to (h, w)) -> float32 ``(cols, rows)`` (h, w;
        NaN: no image) and ``(col_min, row_min, col_max, row_max, NaN count)``."""
        ...
