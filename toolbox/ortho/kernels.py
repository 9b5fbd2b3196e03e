"""The map kernels of an output window: heights, the distortion-free collinearity map and the
report's counts in one compiled pass (:func:`ortho_window_projective`), the counts again after
the distortion (:func:`count_window`), the plain projective map of given heights
(:func:`project_tile_projective`) and the box of a map (:func:`window_box`).

Arrays and numbers in, arrays out; the matrices ``a``, ``m`` come from
:func:`toolbox.ortho.sensor.tile_matrices`. A planned map's empty cells get the value the
caller passes (``empty``; the warp's sentinel), so the kernels know nothing of the warp.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from toolbox.ortho.codes import (  # noqa: F401 - (fields of ``stats``: re-exported)
    RELIEF_ROWS,
    STAT_COL_MAX,
    STAT_COL_MIN,
    STAT_MAX_RELIEF,
    STAT_MISSING,
    STAT_OUTSIDE_DEM,
    STAT_OUTSIDE_PHOTO,
    STAT_ROW_MAX,
    STAT_ROW_MIN,
)
from toolbox.ortho.jit import FAST


@njit(**FAST)
def project_tile_projective(z, a, m, cols, rows):
    """Source pixels of a tile without distortion: exactly ``M·(j, i, Z, 1)`` per cell (see
    :func:`tile_matrices`), NaN where Z is NaN or the point is not in front of the camera;
    returns the number of NaN cells (the box: :func:`window_box`)."""
    h, w = z.shape
    a20, a22 = a[2, 0], a[2, 2]
    m00, m02, m10, m12, m20, m22 = m[0, 0], m[0, 2], m[1, 0], m[1, 2], m[2, 0], m[2, 2]
    missing = 0
    for i in range(h):
        zr, cr, rr = z[i], cols[i], rows[i]
        ud = m[0, 1] * i + m[0, 3]
        vd = m[1, 1] * i + m[1, 3]
        wd = m[2, 1] * i + m[2, 3]
        dd = a[2, 1] * i + a[2, 3]
        for j in range(w):  # branch-free, so that it vectorises
            zc = zr[j]
            ahead = dd + a20 * j + a22 * zc < 0.0  # in front of the camera (False for NaN)
            q = 1.0 / (wd + m20 * j + m22 * zc)
            cr[j] = (ud + m00 * j + m02 * zc) * q if ahead else np.nan
            rr[j] = (vd + m10 * j + m12 * zc) * q if ahead else np.nan
            missing += 0 if ahead else 1
    return missing


def window_box(cols: np.ndarray, rows: np.ndarray, box: np.ndarray) -> None:
    """The bounding box of the finite ``cols``, ``rows`` into ``box[:4]`` (col_min, row_min,
    col_max, row_max; 1e300 / -1e300 when there is none; ``box[4]`` must hold the number of NaN
    cells). NumPy's fmin/fmax reductions are vectorised and skip NaN: 0.2 ms per Mpx."""
    if box[4] < cols.size:
        box[:4] = (np.fmin.reduce(cols, axis=None), np.fmin.reduce(rows, axis=None),
                   np.fmax.reduce(cols, axis=None), np.fmax.reduce(rows, axis=None))
    else:
        box[:4] = (1e300, 1e300, -1e300, -1e300)




@njit(**FAST)
def _relief_row_bits(cr, rr, zr, dx2, dy2, photo, reference_height, z0, line):
    """The largest squared relief displacement (m², :func:`relief_displacement`) of one row's
    cells inside ``photo`` (4,), as the bits of its float64 (0: none): branch-free into
    ``line``, then an integer maximum (non-negative doubles order as their int64 patterns,
    and an integer maximum vectorises where a float one does not without fastmath; the
    caller takes the square root once). ``dx2`` the squared x offsets of the columns from the
    projection centre, ``dy2`` the row's."""
    c_lo, c_hi, r_lo, r_hi = photo[0], photo[1], photo[2], photo[3]
    for j in range(zr.shape[0]):
        u, v, zc = cr[j], rr[j], zr[j]
        inside = (u >= c_lo) & (u <= c_hi) & (v >= r_lo) & (v <= r_hi)
        ratio = (zc - reference_height) / (z0 - zc)
        value = (dx2[j] + dy2) * ratio * ratio
        line[j] = value if inside & (value < np.inf) else 0.0  # (and not NaN)
    return line.view(np.int64).max()


@njit(**FAST)
def ortho_window_projective(dem, dgx0, dgy0, dcx, dcy, xs, ys, a, m, centre, reference_height,
                            photo, blank, slack, z, cols, rows, stats):
    """Heights, coordinate map and statistics of one output window in one pass, row by row,
    without distortion.

    The DEM part ``dem`` and the cell centres ``xs``, ``ys`` as :func:`heights_on_grid`; ``a``,
    ``m`` of :func:`tile_matrices`; ``z`` (h, w) gets the heights, or is (0, 0) when they are
    not wanted. ``photo`` (4,) is the photo ``[col0, col1] x [row0, row1]`` in the map's
    coordinates (``[0, width] x [0, height]``, or shifted with ``m``: see
    :meth:`~toolbox.ortho.sensor.CollinearityMap.project_on_dem`); ``blank`` is the value of
    every cell outside it or without image point (the warp's sentinel for a planned map), or
    NaN: then only the cells without image point are NaN and the others keep their
    coordinates. ``stats`` (8,) gets (after the box, left to
    :func:`window_box`) the number of cells without image point, the cells without height, the
    cells with an image point outside the photo and the largest relief displacement (m,
    :func:`relief_displacement`, on every :data:`RELIEF_ROWS`-th row, cells inside the
    photo).

    With ``slack >= 0`` (px), each row is first split into spans, without touching its
    cells: the edges' conditions ``col >= col0`` etc. are affine in (column, height) once
    multiplied by the homogeneous ``w`` (of one sign over the row's cells x heights, checked at
    the corners), so with the row's heights in the range of its two DEM rows, solving them
    over that range gives the columns surely outside the photo by more than ``slack`` (with
    ``blank``: blanked at once, counted outside), surely inside by more than ``slack`` (the map
    alone: no tests, no counts), and the rest, tested cell by cell as without spans; 0.01 px
    more covers the float32 rounding. ``slack`` is 0 for a final map, the distortion's largest
    shift for one the distortion pass still moves. An edge window spends nothing on its cells
    outside the photo, an inner one skips the tests (0.53 ms against 1.2 ms per 1024 x 1024
    window, with the relief below, measured). ``slack < 0``: no spans.

    The arithmetic of :func:`heights_on_grid` + :func:`project_tile_projective` (equal results,
    tested), written out in one function rather than calling their helpers, and the box left to
    NumPy (:func:`window_box`): numba compiles every called function on its own, and a cold
    start paid 8.5 s for the helpers against 2 s for this (measured on the loaded 2-core
    machine)."""
    h, w = ys.shape[0], xs.shape[0]
    nrow, ncol = dem.shape
    jj = np.empty(w, dtype=np.uint64)  # as _dem_columns; unsigned: the loops vectorise
    tx = np.empty(w)
    spans = slack >= 0.0  # the rows' spans (below) need every column on the DEM
    for j in range(w):  # (the outer half cell of the DEM clamped to its edge, as _dem_columns)
        fx = (xs[j] - dgx0) / dcx
        inside_dem = fx >= -0.5 and fx <= ncol - 0.5
        fx = min(max(fx, 0.0), ncol - 1.0)
        jj[j] = min(int(fx), ncol - 2) if inside_dem else 0
        tx[j] = fx - jj[j] if inside_dem else np.nan
        spans = spans and inside_dem
    # per DEM row its lowest and highest height (NaN if it has a NaN): a grid row between DEM
    # rows r and r + 1 has its heights in the range of the two
    low, high = np.empty(nrow if spans else 0), np.empty(nrow if spans else 0)
    for dem_row in range(low.shape[0]):  # (own names: c and r are the heights' below)
        lo = hi = dem[dem_row, 0]
        for value in dem[dem_row]:
            lo = min(lo, value)
            hi = max(hi, value)
            if math.isnan(value):
                lo = hi = np.nan
                break
        low[dem_row], high[dem_row] = lo, hi
    top, bottom, line = np.empty(w), np.empty(w), np.empty(w)
    held = -2
    a20, a22 = a[2, 0], a[2, 2]
    m00, m02, m10, m12, m20, m22 = m[0, 0], m[0, 2], m[1, 0], m[1, 2], m[2, 0], m[2, 2]
    missing = outside = no_height = 0
    relief_bits = 0  # the largest relief displacement, squared, as the bits of a float64
    x0, y0, z0 = centre[0], centre[1], centre[2]
    dx2 = (xs - x0) ** 2  # the relief's squared x offsets from the projection centre
    relief_line = np.empty(w)
    c_lo, c_hi, r_lo, r_hi = photo[0], photo[1], photo[2], photo[3]
    # margin of the spans' tests, pixels: beyond the float32 rounding of a coordinate
    margin = 0.01 + slack + 1e-6 * max(abs(c_lo), abs(c_hi), abs(r_lo), abs(r_hi))
    empty = np.float32(blank)
    keep_outside = math.isnan(blank)
    for i in range(h):
        zr = z[i] if z.shape[0] == h else line
        fy = (dgy0 - ys[i]) / dcy
        row_on_dem = fy >= -0.5 and fy <= nrow - 0.5
        fy = min(max(fy, 0.0), nrow - 1.0)  # the outer half cell: the edge row's heights
        ud = m[0, 1] * i + m[0, 3]
        vd = m[1, 1] * i + m[1, 3]
        wd = m[2, 1] * i + m[2, 3]
        dd = a[2, 1] * i + a[2, 3]
        # the row's spans: cells [0, p0) and [p1, w) surely outside the photo, [q0, q1) surely
        # inside, the rest tested cell by cell (all of it: p0 = 0, q0 = q1 = p1 = w)
        p0, q0, q1, p1 = 0, w, w, w
        if not row_on_dem:
            zr[:] = np.nan
        else:  # heights: the DEM rows around the grid row along x (kept), blended
            r = min(int(fy), nrow - 2)
            ty = fy - r
            if r != held:
                for k in range(2):
                    d, o = dem[r + k], top if k == 0 else bottom
                    for j in range(w):
                        c, t = jj[j], tx[j]
                        o[j] = d[c] * (1.0 - t) + d[c + 1] * t
                held = r
            for j in range(w):
                zr[j] = top[j] * (1.0 - ty) + bottom[j] * ty
            if spans and not math.isnan(low[r] + low[r + 1]):
                zlo, zhi = min(low[r], low[r + 1]), max(high[r], high[r + 1])
                # the row's cells x [zlo, zhi]: den and the homogeneous w are affine in (j, z),
                # so their extremes are at the corners
                d_hi = dd + max(0.0, a20 * (w - 1)) + max(a22 * zlo, a22 * zhi)
                w_lo = wd + min(0.0, m20 * (w - 1)) + min(m22 * zlo, m22 * zhi)
                w_hi = wd + max(0.0, m20 * (w - 1)) + max(m22 * zlo, m22 * zhi)
                scale = abs(dd) + abs(a20) * w + abs(a22) * max(abs(zlo), abs(zhi))
                if d_hi < -1e-12 * scale and (w_lo > 0.0 or w_hi < 0.0):  # ahead, w one sign
                    sign = 1.0 if w_lo > 0.0 else -1.0
                    p_lo, p_hi, q_lo, q_hi = 0.0, w - 1.0, 0.0, w - 1.0
                    for k in range(8):  # 4 edges x (surely inside, possibly inside)
                        edge, sure = k // 2, k % 2 == 0
                        upper = edge % 2 == 1
                        n0, nj, nz = (ud, m00, m02) if edge < 2 else (vd, m10, m12)
                        bound = photo[edge] + (margin if sure != upper else -margin)
                        # the edge's condition: s·(N - bound·w) >= 0, s = ±sign, affine in j
                        s = -sign if upper else sign
                        alpha = s * (n0 - bound * wd)
                        beta = s * (nj - bound * m20)
                        g_lo, g_hi = s * (nz - bound * m22) * zlo, s * (nz - bound * m22) * zhi
                        alpha += min(g_lo, g_hi) if sure else max(g_lo, g_hi)
                        lo, hi = (q_lo, q_hi) if sure else (p_lo, p_hi)
                        if beta > 0.0:
                            lo = max(lo, -alpha / beta)
                        elif beta < 0.0:
                            hi = min(hi, -alpha / beta)
                        elif alpha < 0.0:
                            lo = np.inf
                        if sure:
                            q_lo, q_hi = lo, hi
                        else:
                            p_lo, p_hi = lo, hi
                    p0 = int(math.ceil(min(max(p_lo, 0.0), w)))
                    p1 = max(int(math.floor(min(max(p_hi, -1.0), w - 1.0))) + 1, p0)
                    q0 = min(max(int(math.ceil(min(max(q_lo, 0.0), w))), p0), p1)
                    q1 = min(max(int(math.floor(min(max(q_hi, -1.0), w - 1.0))) + 1, q0), p1)
                    if keep_outside:  # no cell blanked: the surely outside ones are tested
                        p0, p1 = 0, w
        for span in range(3):  # [p0, q0) and [q1, p1) tested, [q0, q1) surely inside
            start, stop = (p0, q0) if span == 0 else ((q1, p1) if span == 1 else (q0, q1))
            # zero-based loops on slices (a start from the spans' arithmetic stops LLVM
            # vectorising a loop: 2x slower measured)
            cr, rr, zs = cols[i, start:stop], rows[i, start:stop], zr[start:stop]
            us, vs, ws = ud + m00 * start, vd + m10 * start, wd + m20 * start
            ds = dd + a20 * start
            if span == 2:  # the map alone
                for j in range(zs.shape[0]):
                    zc = zs[j]
                    q = 1.0 / (ws + m20 * j + m22 * zc)
                    cr[j] = np.float32((us + m00 * j + m02 * zc) * q)
                    rr[j] = np.float32((vs + m10 * j + m12 * zc) * q)
                continue
            for j in range(zs.shape[0]):  # the map and the counts, branch-free
                zc = zs[j]
                no_height += 1 if math.isnan(zc) else 0
                ahead = ds + a20 * j + a22 * zc < 0.0  # in front of the camera (False for NaN)
                q = 1.0 / (ws + m20 * j + m22 * zc)
                u = np.float32((us + m00 * j + m02 * zc) * q)
                v = np.float32((vs + m10 * j + m12 * zc) * q)
                inside = (u >= c_lo) & (u <= c_hi) & (v >= r_lo) & (v <= r_hi)
                keep = ahead & (inside | keep_outside)
                cr[j] = u if keep else empty
                rr[j] = v if keep else empty
                missing += 0 if ahead else 1
                outside += 1 if ahead & ~inside else 0
        cr, rr = cols[i], rows[i]
        cr[:p0] = empty
        rr[:p0] = empty
        cr[p1:] = empty
        rr[p1:] = empty
        outside += p0 + w - p1
        if i % RELIEF_ROWS == 0:
            relief_bits = max(relief_bits, _relief_row_bits(
                cr, rr, zr, dx2, (ys[i] - y0) ** 2, photo, reference_height, z0, relief_line))
    stats[STAT_MISSING] = missing
    stats[STAT_OUTSIDE_DEM] = no_height
    stats[STAT_OUTSIDE_PHOTO] = outside
    stats[STAT_MAX_RELIEF] = math.sqrt(np.array([relief_bits]).view(np.float64)[0])


@njit(**FAST)
def count_window(z, xs, ys, cols, rows, centre, reference_height, photo, blank, stats):
    """The counts of :func:`ortho_window_projective` that the distortion changes, recomputed on
    the final map: ``stats[STAT_OUTSIDE_PHOTO]`` and ``stats[STAT_MAX_RELIEF]`` (from the
    window's heights ``z``, on its relief rows only); unless ``blank`` is NaN the cells outside
    ``photo`` (or without image point) get the value ``blank`` here. The
    cells without image point or height stay the kernel's counts: the distortion moves a point
    but never makes or removes one (an exact pixel is NaN exactly where the distortion-free
    one is, and a blended block has none)."""
    outside = 0
    relief_bits = 0
    x0, y0, z0 = centre[0], centre[1], centre[2]
    dx2 = (xs - x0) ** 2
    relief_line = np.empty(xs.shape[0])
    c_lo, c_hi, r_lo, r_hi = photo[0], photo[1], photo[2], photo[3]
    empty = np.float32(blank)
    blanking = not math.isnan(blank)
    for i in range(ys.shape[0]):
        cr, rr = cols[i], rows[i]
        for j in range(xs.shape[0]):  # branch-free, so that it vectorises
            u, v = cr[j], rr[j]
            inside = (u >= c_lo) & (u <= c_hi) & (v >= r_lo) & (v <= r_hi)
            outside += 0 if inside | math.isnan(u) else 1
            if blanking:
                cr[j] = u if inside else empty
                rr[j] = v if inside else empty
        if i % RELIEF_ROWS == 0:
            relief_bits = max(relief_bits, _relief_row_bits(
                cr, rr, z[i], dx2, (ys[i] - y0) ** 2, photo, reference_height, z0,
                relief_line))
    stats[STAT_OUTSIDE_PHOTO] = outside
    stats[STAT_MAX_RELIEF] = math.sqrt(np.array([relief_bits]).view(np.float64)[0])
