"""Visibility (true ortho): which output cells the camera does not see over a DSM."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from toolbox.photogrammetry.kernels import _dem_height

SKY_BLOCK = 8  # DSM cells per side of the blocks whose maxima let rays skip free ground


def block_maxima(dsm: np.ndarray, block: int = SKY_BLOCK) -> np.ndarray:
    """Highest DSM value of every ``block`` x ``block`` group of cells, widened by one cell on
    every side (the bilinear surface inside a block uses its neighbours), NaN ignored
    (-inf where a block has no value)."""
    rows, cols = dsm.shape
    nb_r, nb_c = -(-rows // block), -(-cols // block)
    padded = np.full((nb_r * block + 2, nb_c * block + 2), -np.inf)
    padded[1:rows + 1, 1:cols + 1] = np.where(np.isfinite(dsm), dsm, -np.inf)
    from scipy.ndimage import maximum_filter

    grown = maximum_filter(padded, size=3, mode="nearest")[1:-1, 1:-1]
    return np.ascontiguousarray(grown.reshape(nb_r, block, nb_c, block).max(axis=(1, 3)))


@njit(parallel=True, cache=True)
def hidden_cells(xs, ys, z, centre, dsm, gx0, gy0, cx, cy, zmax, tolerance, bmax, block, out):
    """Occlusion test of ground cells ``(xs[j], ys[i], z[i, j])`` against a DSM.

    The ray from each cell towards the projection centre is walked over the DSM (bilinear
    between cell centres, the edge value held across the outer half cell) in half-cell steps
    until it rises above the DSM's highest point ``zmax``; the cell is hidden (``out = 1``)
    where the surface stands more than ``tolerance`` above the ray, i.e. the camera sees
    something else along that line of sight (the object-space form of a Z-buffer: no depth
    tolerance between image and ground samples, no holes). Where
    the ray enters a block of ``block`` x ``block`` DSM cells above that block's highest value
    (``bmax``, :func:`block_maxima`) it jumps to the block's exit: the ray only rises, so nothing
    in that block can hide the cell. Cells without height get 0; beyond the DSM the ray is free. A
    cell above the camera is walked the whole way to it, without jumps.
    """
    x0, y0, z0 = centre[0], centre[1], centre[2]
    step = 0.5 * min(cx, cy)
    rows, cols = dsm.shape
    for i in prange(ys.shape[0]):
        for j in range(xs.shape[0]):
            out[i, j] = 0
            zc = z[i, j]
            if not math.isfinite(zc):
                continue
            dxh = x0 - xs[j]
            dyh = y0 - ys[i]
            rho = math.sqrt(dxh * dxh + dyh * dyh)
            rise = z0 - zc
            if rho < 1e-9:
                continue
            ux = dxh / rho
            uy = dyh / rho
            slope = rise / rho
            # a cell above the camera (a valley flight looking up a slope): its line of sight
            # descends to the camera, the whole way, and no block can be skipped
            descends = not rise > 0.0
            s_max = rho if descends else min(rho, (zmax - zc) / slope)
            dfx = ux / cx  # DSM column index per metre along the ray
            dfy = -uy / cy  # DSM row index per metre
            s = step
            while s < s_max:
                px = xs[j] + s * ux
                py = ys[i] + s * uy
                fx = (px - gx0) / cx
                fy = (gy0 - py) / cy
                ray = zc + s * slope
                if not descends and fx >= -0.5 and fy >= -0.5 and fx <= cols - 0.5 and \
                        fy <= rows - 0.5:
                    bi = int(min(max(fy, 0.0), rows - 1.0)) // block  # (the outer half cell:
                    bj = int(min(max(fx, 0.0), cols - 1.0)) // block  # the edge's block)
                    if ray > bmax[bi, bj] + tolerance:  # free above this block: to its exit
                        tx = 1e300  # (the first blocks reach over the outer half cell: -0.5)
                        ty = 1e300
                        if dfx > 0.0:
                            tx = ((bj + 1) * block - fx) / dfx
                        elif dfx < 0.0:
                            tx = (bj * block - (0.5 if bj == 0 else 0.0) - fx) / dfx
                        if dfy > 0.0:
                            ty = ((bi + 1) * block - fy) / dfy
                        elif dfy < 0.0:
                            ty = (bi * block - (0.5 if bi == 0 else 0.0) - fy) / dfy
                        s += max(min(tx, ty), 0.0) + 1e-6 * step
                        continue
                hgt, code = _dem_height(px, py, dsm, gx0, gy0, cx, cy)
                if code == 0 and hgt > ray + tolerance:
                    out[i, j] = 1
                    break
                s += step


def visibility_mask(xs: np.ndarray, ys: np.ndarray, z: np.ndarray, centre: np.ndarray,
                    surface: Any, maxima: np.ndarray | None = None) -> np.ndarray:
    """Hidden cells (uint8 1) of the grid ``xs`` x ``ys`` with heights ``z`` seen from
    ``centre`` over the DSM ``surface`` (:class:`~toolbox.photogrammetry.surface.DemSurface`);
    ``maxima`` from :func:`block_maxima` (computed when missing)."""
    maxima = block_maxima(surface.z) if maxima is None else maxima
    out = np.zeros(z.shape, dtype=np.uint8)
    hidden_cells(np.ascontiguousarray(xs, dtype="float64"),
                 np.ascontiguousarray(ys, dtype="float64"), np.ascontiguousarray(z),
                 np.asarray(centre, dtype="float64"), surface.z, surface.x0, surface.y0,
                 surface.cell_x, surface.cell_y, surface.z_range[1],
                 0.01 * min(surface.cell_x, surface.cell_y), maxima, SKY_BLOCK, out)
    return out
