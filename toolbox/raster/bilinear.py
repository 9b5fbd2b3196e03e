"""Bilinear interpolation of a raster's heights at map points: the one implementation the
profile, the DEM surface of monoplotting and the checks use (compiled kernels that must run
inside numba keep their own: :mod:`toolbox.photogrammetry.kernels`)."""

from __future__ import annotations

import numpy as np


def bilinear(z: np.ndarray, x0: float, y0: float, dx: float, dy: float,
             xy: np.ndarray, half_cell: bool = False) -> np.ndarray:
    """Bilinear heights of a grid at map points; ``x0, y0`` is the centre of cell (0, 0) and
    ``dx, dy`` the steps between centres. NaN outside the centres' hull or next to NaN cells.

    ``half_cell``: a point in the outer half cell of the grid (inside its cells, beyond the
    outer centres) takes the value at the nearest point of the centres' hull, the surface held
    level across that half cell, as GDAL's bilinear resampling does at a raster's edge; NaN
    only outside the cells."""
    col = (xy[:, 0] - x0) / dx
    row = (xy[:, 1] - y0) / dy
    rows, cols = z.shape
    if half_cell:
        inside = (col >= -0.5) & (col <= cols - 0.5) & (row >= -0.5) & (row <= rows - 0.5)
        col, row = np.clip(col, 0, cols - 1), np.clip(row, 0, rows - 1)
    else:
        inside = (col >= 0) & (col <= cols - 1) & (row >= 0) & (row <= rows - 1)
    c0 = np.clip(np.floor(col).astype(np.int64), 0, max(cols - 2, 0))
    r0 = np.clip(np.floor(row).astype(np.int64), 0, max(rows - 2, 0))
    fc, fr = col - c0, row - r0
    c1, r1 = np.minimum(c0 + 1, cols - 1), np.minimum(r0 + 1, rows - 1)
    top = z[r0, c0] * (1 - fc) + z[r0, c1] * fc
    bottom = z[r1, c0] * (1 - fc) + z[r1, c1] * fc
    out = top * (1 - fr) + bottom * fr
    return np.where(inside, out, np.nan)
