"""Marching squares over a grid for every contour level in one pass (numba), arrays in and out.

The surface is contourpy's (serial, ``corner_mask=True``, linear interpolation), which
:mod:`tests <tests.toolbox.cartography.test_contour_kernel>` keep as the oracle: a node is above a
level when ``z > level``; a line crosses a grid edge where its two nodes are on either side,
at the linear interpolation of the edge's heights; a square with all four nodes valid holds one
segment per level it spans, or two at a saddle, split as the mean of its four heights says; a
square with one node missing (NaN) is the triangle of the other three, cut along its diagonal;
a square with two or more missing holds nothing.

Coordinates: node (row, column) is at x = ``xs[column]``, y = ``ys[row]`` (by default its column
and row), and a crossing is interpolated between its edge's nodes with contourpy's arithmetic
(``x_above·f + x_below·(1 - f)``, ``f = (z_below - level) / (z_below - z_above)``), so the two
tracers give the same vertices bit for bit, and a block traced with its nodes' coordinates in the
whole grid gives the whole grid's vertices (tests). Lines keep the higher ground on their right
in the (x, y) frame taken as right-handed; closed lines repeat their first vertex.

Each level's crossings on each edge get a dense id (edges in a fixed order, levels ascending on
each edge), so linking the segments into lines needs no search: every square writes the
successor of its entering crossing, and the lines are walked from the crossings no square leads
into, then the rings from what is left. One pass over the squares whatever the number of levels
(contourpy makes one per level).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from toolbox.cache import skip_numba_blas_probe

skip_numba_blas_probe()  # no scipy.linalg import for loading these kernels

# the corners of square (r, c) counter-clockwise in the (x = column, y = row) frame, and the
# quad edges between consecutive corners: edge i runs from corner i to corner i + 1
_DR = np.array([0, 0, 1, 1])
_DC = np.array([0, 1, 1, 0])


@njit(cache=True, nogil=True)
def _bands(z: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """How many ``levels`` (ascending) lie below each node (a node is above level ``k`` when
    ``k < band``); -1 for NaN nodes."""
    rows, cols = z.shape
    band = np.empty((rows, cols), dtype=np.int64)
    for r in range(rows):
        for c in range(cols):
            band[r, c] = -1 if np.isnan(z[r, c]) else np.searchsorted(levels, z[r, c], "left")
    return band


@njit(cache=True, nogil=True, inline="always")
def _edge_id(r: int, c: int, kind: int, rows: int, cols: int) -> int:
    """Id of edge ``kind`` of square (r, c) (0 bottom: nodes (r, c)-(r, c+1), 1 right,
    2 top, 3 left, in the (x = column, y = row) frame): horizontal edges first (row-major),
    then vertical ones, then one diagonal per square."""
    n_h = rows * (cols - 1)
    if kind == 0:
        return r * (cols - 1) + c
    if kind == 2:
        return (r + 1) * (cols - 1) + c
    if kind == 1:
        return n_h + r * cols + c + 1
    return n_h + r * cols + c


@njit(cache=True, nogil=True, inline="always")
def _missing_corner(band: np.ndarray, r: int, c: int) -> int:
    """-1 when the square's four nodes are valid, the missing corner (0-3) when one is NaN,
    4 when two or more are."""
    missing = -1
    for i in range(4):
        if band[r + _DR[i], c + _DC[i]] < 0:
            if missing >= 0:
                return 4
            missing = i
    return missing


@njit(cache=True, nogil=True, inline="always")
def _edge(z: np.ndarray, band: np.ndarray, levels: np.ndarray, e: int, r0: int, c0: int,
          r1: int, c1: int, first: np.ndarray, x: np.ndarray, y: np.ndarray,
          level: np.ndarray, total: int, xs: np.ndarray, ys: np.ndarray) -> int:
    """Edge ``e`` from node (r0, c0) to (r1, c1): without ``x`` (empty), give it its crossing
    ids and return the new total; with it, fill its crossings (linear along the edge, nodes at
    ``xs``, ``ys``: see the module's docstring)."""
    if len(x) == 0:
        first[e] = total
        a, b = band[r0, c0], band[r1, c1]
        if a >= 0 and b >= 0:
            total += abs(a - b)
        return total
    if band[r0, c0] < band[r1, c1]:  # (r0, c0) the node above every level crossing here
        r0, c0, r1, c1 = r1, c1, r0, c0
    za, zb = z[r0, c0], z[r1, c1]
    xa, ya, xb, yb = xs[c0], ys[r0], xs[c1], ys[r1]
    k0 = band[r1, c1]  # the edge's lowest level
    for i in range(first[e], first[e + 1]):
        k = k0 + i - first[e]
        f = (zb - levels[k]) / (zb - za)  # contourpy's arithmetic: the same bits
        x[i] = xa * f + xb * (1.0 - f)
        y[i] = ya * f + yb * (1.0 - f)
        level[i] = k
    return total


@njit(cache=True, nogil=True)
def _edges(z: np.ndarray, band: np.ndarray, levels: np.ndarray, diag: np.ndarray,
           first: np.ndarray, x: np.ndarray, y: np.ndarray, level: np.ndarray,
           xs: np.ndarray, ys: np.ndarray) -> int:
    """:func:`_edge` on every edge in id order (:func:`_edge_id`); returns the crossings'
    total."""
    rows, cols = z.shape
    total, e = 0, 0
    for r in range(rows):
        for c in range(cols - 1):
            total = _edge(z, band, levels, e, r, c, r, c + 1, first, x, y, level, total, xs, ys)
            e += 1
    for r in range(rows - 1):
        for c in range(cols):
            total = _edge(z, band, levels, e, r, c, r + 1, c, first, x, y, level, total, xs, ys)
            e += 1
    for r in range(rows - 1):
        for c in range(cols - 1):
            m = diag[r * (cols - 1) + c]
            if 0 <= m < 4:  # the diagonal between the corners next to the missing one
                a, b = (m + 1) % 4, (m + 3) % 4
                total = _edge(z, band, levels, e, r + _DR[a], c + _DC[a], r + _DR[b],
                              c + _DC[b], first, x, y, level, total, xs, ys)
            elif len(x) == 0:
                first[e] = total
            e += 1
    if len(x) == 0:
        first[e] = total
    return total


@njit(cache=True, nogil=True)
def _crossings(z: np.ndarray, band: np.ndarray, levels: np.ndarray, xs: np.ndarray,
               ys: np.ndarray):
    """Every crossing of a level with an edge (quad edges, and the diagonals of squares with
    one missing node): ``first[e]`` (crossing ids: ``first[e] + k - k0`` for level ``k``, k0
    the lower band of the edge's two nodes), each square's missing corner
    (:func:`_missing_corner`), and each crossing's x, y and level index."""
    rows, cols = z.shape
    diag = np.empty((rows - 1) * (cols - 1), dtype=np.int64)
    for r in range(rows - 1):
        for c in range(cols - 1):
            diag[r * (cols - 1) + c] = _missing_corner(band, r, c)
    n_e = rows * (cols - 1) + (rows - 1) * cols + len(diag)
    first = np.empty(n_e + 1, dtype=np.int64)
    none = np.empty(0)
    total = _edges(z, band, levels, diag, first, none, none, np.empty(0, dtype=np.int32), xs,
                   ys)
    x, y, level = np.empty(total), np.empty(total), np.empty(total, dtype=np.int32)
    if total:
        _edges(z, band, levels, diag, first, x, y, level, xs, ys)
    return first, diag, x, y, level


@njit(cache=True, nogil=True)
def _link(z: np.ndarray, band: np.ndarray, levels: np.ndarray, first: np.ndarray,
          diag: np.ndarray, n_crossings: int) -> np.ndarray:
    """``succ[i]``: the crossing the line goes to from crossing ``i`` (-1: none), each square's
    segments oriented with higher ground on the right."""
    rows, cols = z.shape
    n_hv = rows * (cols - 1) + (rows - 1) * cols
    succ = np.full(n_crossings, -1, dtype=np.int64)
    bc = np.empty(4, dtype=np.int64)  # the corners' bands, counter-clockwise
    edge = np.empty(4, dtype=np.int64)  # edge i of the polygon runs from corner i to i + 1
    for r in range(rows - 1):
        for c in range(cols - 1):
            m = diag[r * (cols - 1) + c]
            if m == 4:
                continue
            n_corners = 4 if m < 0 else 3
            start = 0 if m < 0 else m + 1  # a triangle: the three valid corners from m + 1
            lo, hi = 1 << 62, -1
            for j in range(n_corners):
                i = (start + j) % 4
                bc[j] = band[r + _DR[i], c + _DC[i]]
                lo, hi = min(lo, bc[j]), max(hi, bc[j])
            if lo == hi:
                continue
            for j in range(n_corners):
                edge[j] = _edge_id(r, c, (start + j) % 4, rows, cols)
            if m >= 0:
                edge[2] = n_hv + r * (cols - 1) + c
            for k in range(lo, hi):
                # a saddle: opposite corners on the same side; its middle (the mean of the
                # corners) says which pair the lines cut off
                saddle = n_corners == 4 and (bc[0] > k) == (bc[2] > k) and \
                    (bc[1] > k) == (bc[3] > k) and (bc[0] > k) != (bc[1] > k)
                step = 1
                if saddle and 0.25 * (z[r, c] + z[r, c + 1] + z[r + 1, c + 1]
                                      + z[r + 1, c]) > levels[k]:
                    step = -1  # middle above: the below corners are cut off
                for i in range(n_corners):
                    # an entering edge (below -> above going round) starts a segment; it ends
                    # on the next leaving edge (above -> below), or the previous one (step -1)
                    if bc[i] > k or not bc[(i + 1) % n_corners] > k:
                        continue
                    j = (i + step) % n_corners
                    while not (bc[j] > k and not bc[(j + 1) % n_corners] > k):
                        j = (j + step) % n_corners
                    a = first[edge[i]] + k - min(bc[i], bc[(i + 1) % n_corners])
                    succ[a] = first[edge[j]] + k - min(bc[j], bc[(j + 1) % n_corners])
    return succ


@njit(cache=True, nogil=True)
def _walk(succ: np.ndarray, x: np.ndarray, y: np.ndarray, level: np.ndarray):
    """Lines from the linked crossings: open ones from the crossings nothing leads into, then
    the rings (their first vertex repeated). Returns the points (n, 2), the line offsets and
    each line's level index."""
    n = len(succ)
    has_pred = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        if succ[i] >= 0:
            has_pred[succ[i]] = True
    seen = np.zeros(n, dtype=np.bool_)
    points = np.empty((n + n // 3 + 1, 2))
    offsets = np.zeros(n + 1, dtype=np.int64)
    line_level = np.empty(n, dtype=np.int32)
    n_pts = 0
    n_lines = 0
    for ring in (False, True):
        for start in range(n):
            if seen[start] or succ[start] < 0 or (has_pred[start] and not ring):
                continue
            i = start
            while True:
                seen[i] = True
                points[n_pts, 0], points[n_pts, 1] = x[i], y[i]
                n_pts += 1
                i = succ[i]
                if i < 0:
                    break
                if i == start:  # back at the start: close the ring
                    points[n_pts, 0], points[n_pts, 1] = x[i], y[i]
                    n_pts += 1
                    break
            line_level[n_lines] = level[start]
            n_lines += 1
            offsets[n_lines] = n_pts
    return points[:n_pts], offsets[:n_lines + 1], line_level[:n_lines]


@njit(cache=True, nogil=True)
def lines_core(z: np.ndarray, levels: np.ndarray, xs: np.ndarray, ys: np.ndarray):
    """:func:`grid_lines` of a C-contiguous float64 grid of at least 2 x 2 nodes and at least
    one level, its nodes at ``xs`` (one a column), ``ys`` (one a row) (the kernel
    :mod:`toolbox.aot` also compiles ahead of time)."""
    band = _bands(z, levels)
    first, diag, x, y, level = _crossings(z, band, levels, xs, ys)
    succ = _link(z, band, levels, first, diag, len(x))
    return _walk(succ, x, y, level)


def grid_lines(z: np.ndarray, levels: np.ndarray, xs: np.ndarray | None = None,
               ys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contour lines of grid ``z`` (NaN = no data) at ``levels`` (ascending), its nodes at
    x = ``xs[column]``, y = ``ys[row]`` (default: the column and row).

    Returns ``points (n, 2)``, ``offsets`` (line ``i`` is
    ``points[offsets[i]:offsets[i + 1]]``) and each line's index into ``levels``.
    """
    z = np.ascontiguousarray(z, dtype=np.float64)
    levels = np.ascontiguousarray(levels, dtype=np.float64)
    if z.shape[0] < 2 or z.shape[1] < 2 or not len(levels):
        return np.empty((0, 2)), np.zeros(1, dtype=np.int64), np.empty(0, dtype=np.int32)
    xs = np.arange(z.shape[1], dtype=np.float64) if xs is None else \
        np.ascontiguousarray(xs, dtype=np.float64)
    ys = np.arange(z.shape[0], dtype=np.float64) if ys is None else \
        np.ascontiguousarray(ys, dtype=np.float64)
    return lines_core(z, levels, xs, ys)
