"""The radial distortion added to a distortion-free map, block by block, with a proven bound.

Per block of ``block`` x ``block`` cells the distortion's pixel correction (exact pixel minus
distortion-free pixel) is evaluated exactly at the block's corner cells and blended bilinearly
inside, *only* when the blend's error is provably below ``tolerance_px``. With ``L`` the
Lipschitz constant of the distortion field ``δ(p) = measured(p) - p`` (from the camera's table
or polynomial, :func:`toolbox.ortho.sensor.distortion_lipschitz`), ``κ`` the condition number
of the fiducial -> pixel transform and ``D`` the diagonal of the block's distortion-free pixel
box, the correction is ``κ·L``-Lipschitz in pixel space, so a blend of corner values (weights
>= 0, sum 1) differs from the exact correction by at most ``κ·L·D`` pixels. Blocks over the
bound are computed exactly. On a DEM window D is taken from a box known to hold the block's
pixels before they are computed (:func:`block_modes_on_dem`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from toolbox.ortho.codes import (  # noqa: F401 - (re-exported)
    BLOCK_EXACT,
    BLOCK_INTERPOLATED,
    BLOCK_PROJECTIVE,
    DEFAULT_BLOCK,
    DEFAULT_TOLERANCE_PX,
)
from toolbox.ortho.jit import FAST
from toolbox.photogrammetry.kernels import _distort, _project2d, _tuple9


def block_modes(cols: np.ndarray, rows: np.ndarray, block: int, lipschitz_px: float,
                tolerance_px: float) -> np.ndarray:
    """Per block of ``block`` x ``block`` cells of a distortion-free map: BLOCK_INTERPOLATED
    where every cell has an image point and ``lipschitz_px·D <= tolerance_px``, D the diagonal
    of the block's pixel box (widened by 1e-3 px for the float32 rounding), else BLOCK_EXACT."""
    h, w = cols.shape
    nby, nbx = -(-h // block), -(-w // block)

    def per_block(ufunc, values, fill):
        """``ufunc`` reduced over every block (padded with ``fill``): down the block's rows
        first (whole rows at a time, vectorised), then along the short result."""
        if (nby * block, nbx * block) != (h, w):
            values = np.pad(values, ((0, nby * block - h), (0, nbx * block - w)),
                            constant_values=fill)
        down = ufunc.reduce(values.reshape(nby, block, nbx * block), axis=1)
        return ufunc.reduce(down.reshape(nby, nbx, block), axis=2)

    gap = per_block(np.logical_or, np.isnan(cols), False)
    size = np.hypot(per_block(np.fmax, cols, np.nan) - per_block(np.fmin, cols, np.nan),
                    per_block(np.fmax, rows, np.nan) - per_block(np.fmin, rows, np.nan)) + 1e-3
    with np.errstate(invalid="ignore"):
        interpolate = ~gap & (lipschitz_px * size <= tolerance_px)
    return np.where(interpolate, BLOCK_INTERPOLATED, BLOCK_EXACT).astype(np.int8)


@njit(**FAST)
def block_modes_on_dem(dem, dgx0, dgy0, dcx, dcy, xs, ys, a, m, block, lipschitz_px,
                       tolerance_px, modes):
    """:func:`block_modes` of a window's map from its DEM part (as
    :func:`ortho_window_projective` takes it) instead of its cells: per block a box that holds
    every cell's distortion-free pixel, the image of the block's cells x the heights of the
    DEM nodes around them (a bilinear height lies in their range; ``den`` is affine, so the 8
    corners in front of the camera mean the whole box, and a central projection keeps
    convexity there: the corners' pixels bound it). BLOCK_INTERPOLATED when
    ``lipschitz_px·D <= tolerance_px`` with D the box's diagonal (+ 1e-3 px), else
    BLOCK_EXACT, also where a node is NaN, the block leaves the DEM or a corner is not in
    front. A box at least the cells' own, so the bound holds; no pass over the map (0.05
    against 0.7 ms per 1024 x 1024 window, measured)."""
    nrow, ncol = dem.shape
    h, w = ys.shape[0], xs.shape[0]
    for bi in range(modes.shape[0]):
        i0 = bi * block
        i1 = min(i0 + block, h) - 1
        fy0, fy1 = (dgy0 - ys[i0]) / dcy, (dgy0 - ys[i1]) / dcy
        for bj in range(modes.shape[1]):
            j0 = bj * block
            j1 = min(j0 + block, w) - 1
            modes[bi, bj] = BLOCK_EXACT
            fx0, fx1 = (xs[j0] - dgx0) / dcx, (xs[j1] - dgx0) / dcx
            if not (min(fx0, fx1) >= -0.5 and max(fx0, fx1) <= ncol - 0.5
                    and min(fy0, fy1) >= -0.5 and max(fy0, fy1) <= nrow - 0.5):
                continue  # leaves the DEM's cells: no height somewhere
            # the outer half cell holds the edge nodes' heights (as ortho_window_projective)
            fx0, fx1 = min(max(fx0, 0.0), ncol - 1.0), min(max(fx1, 0.0), ncol - 1.0)
            fy0, fy1 = min(max(fy0, 0.0), nrow - 1.0), min(max(fy1, 0.0), nrow - 1.0)
            r_lo, r_hi = int(min(fy0, fy1)), min(int(max(fy0, fy1)) + 1, nrow - 1)
            c_lo, c_hi = int(min(fx0, fx1)), min(int(max(fx0, fx1)) + 1, ncol - 1)
            z_lo, z_hi, nan_node = np.inf, -np.inf, False
            for r in range(r_lo, r_hi + 1):
                for c in range(c_lo, c_hi + 1):
                    z_lo = min(z_lo, dem[r, c])
                    z_hi = max(z_hi, dem[r, c])
                    nan_node = nan_node or math.isnan(dem[r, c])
            if nan_node:  # a cell without height somewhere
                continue
            u_lo = v_lo = np.inf
            u_hi = v_hi = -np.inf
            ahead = True
            for k in range(8):
                j = j0 if k % 2 == 0 else j1
                i = i0 if (k // 2) % 2 == 0 else i1
                zc = z_lo if k < 4 else z_hi
                ahead = ahead and a[2, 0] * j + a[2, 1] * i + a[2, 2] * zc + a[2, 3] < 0.0
                q = 1.0 / (m[2, 0] * j + m[2, 1] * i + m[2, 2] * zc + m[2, 3])
                u = (m[0, 0] * j + m[0, 1] * i + m[0, 2] * zc + m[0, 3]) * q
                v = (m[1, 0] * j + m[1, 1] * i + m[1, 2] * zc + m[1, 3]) * q
                u_lo, u_hi = min(u_lo, u), max(u_hi, u)
                v_lo, v_hi = min(v_lo, v), max(v_hi, v)
            size = math.sqrt((u_hi - u_lo) ** 2 + (v_hi - v_lo) ** 2) + 1e-3
            if ahead and lipschitz_px * size <= tolerance_px:
                modes[bi, bj] = BLOCK_INTERPOLATED


@njit(cache=True, error_model="numpy")
def _exact_pixel(a, j, i, zc, c, px, py, mt, dmode, dr, dd, dk, di):
    """Photo pixel of cell (j, i) at height zc with the distortion (ideal point -> distortion
    -> principal point -> fiducial -> pixel); ok flag. One function with the ideal point (a
    function more is a compilation more)."""
    den = a[2, 0] * j + a[2, 1] * i + a[2, 2] * zc + a[2, 3]
    if not den < 0.0:  # behind the camera, or NaN height
        return np.nan, np.nan, False
    q = -c / den
    xi = (a[0, 0] * j + a[0, 1] * i + a[0, 2] * zc + a[0, 3]) * q
    eta = (a[1, 0] * j + a[1, 1] * i + a[1, 2] * zc + a[1, 3]) * q
    xd, yd = _distort(xi, eta, dmode, dr, dd, dk, di)
    u, v = _project2d(mt, xd + px, yd + py)
    return u, v, True


@njit(**FAST)
def distort_blocks(z, a, c, pp, dmode, dr, dd, dk, di, f2p, block, modes, shift, cols, rows):
    """Add the radial distortion to a distortion-free map (:func:`project_tile_projective`),
    block by block as ``modes`` (:func:`block_modes`) says (see the module docstring); the map
    is in pixels minus ``shift`` (2,) (zeros, or the OpenCV shift of a planned map).

    BLOCK_INTERPOLATED: the distortion's pixel correction exactly at the block's four corner
    cells (ideal point -> distortion -> principal point -> fiducial -> pixel, minus the
    distortion-free pixel), blended bilinearly inside; BLOCK_EXACT: every cell exactly."""
    h, w = cols.shape
    mt = _tuple9(f2p)
    px, py = pp[0], pp[1]
    sc, sr = shift[0], shift[1]
    for bi in range(modes.shape[0]):
        i0 = bi * block
        i1 = min(i0 + block, h) - 1
        for bj in range(modes.shape[1]):
            j0 = bj * block
            j1 = min(j0 + block, w) - 1
            if modes[bi, bj] != BLOCK_INTERPOLATED:
                for i in range(i0, i1 + 1):
                    for j in range(j0, j1 + 1):
                        u, v, _ = _exact_pixel(a, j, i, z[i, j], c, px, py, mt, dmode, dr, dd,
                                               dk, di)
                        cols[i, j], rows[i, j] = u - sc, v - sr
                continue
            d0u = d0v = d1u = d1v = d2u = d2v = d3u = d3v = 0.0
            for k in range(4):
                corner_i = i0 if k < 2 else i1
                corner_j = j0 if k % 2 == 0 else j1
                u, v, _ = _exact_pixel(a, corner_j, corner_i, z[corner_i, corner_j], c, px, py,
                                       mt, dmode, dr, dd, dk, di)
                du = u - sc - cols[corner_i, corner_j]
                dv = v - sr - rows[corner_i, corner_j]
                if k == 0:
                    d0u, d0v = du, dv
                elif k == 1:
                    d1u, d1v = du, dv
                elif k == 2:
                    d2u, d2v = du, dv
                else:
                    d3u, d3v = du, dv
            step_i = 1.0 / (i1 - i0) if i1 > i0 else 0.0
            step_j = 1.0 / (j1 - j0) if j1 > j0 else 0.0
            for i in range(i0, i1 + 1):
                ti = (i - i0) * step_i
                # corrections along the block's top and bottom rows, blended down the rows
                lu = d0u + ti * (d2u - d0u)
                lv = d0v + ti * (d2v - d0v)
                su = (d1u + ti * (d3u - d1u)) - lu
                sv = (d1v + ti * (d3v - d1v)) - lv
                cr, rr = cols[i, j0:j1 + 1], rows[i, j0:j1 + 1]  # slices: it vectorises
                for j in range(cr.shape[0]):
                    tj = j * step_j
                    cr[j] = cr[j] + (lu + tj * su)
                    rr[j] = rr[j] + (lv + tj * sv)
