"""Numba kernels on CDT's arrays (also compiled ahead of time, :mod:`toolbox.aot`): whether a
Delaunay triangulation is the only one of its points (:func:`cocircular_edges`), and CDT's
triangles and neighbours without its super-triangle in our numbering (:func:`cdt_tables`: one
pass instead of numpy's masks, gathers and lookups, 0.15 s of a 1 M-point build).

A triangulation whose every edge between two triangles has its four points off one circle is
the unique (constrained) Delaunay triangulation of its points: any other differs only inside a
face of four or more cocircular points, and every triangulation of such a face has an edge
between two triangles with its four points on the circle. The in-circle determinant is computed
in floating point; a magnitude within Shewchuk's error bound of it (``iccerrboundA``, "Adaptive
Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates", 1997), times 8 for
safety, counts as cocircular, so the count errs only towards too many.
"""

from __future__ import annotations

import numba
import numpy as np

#: Shewchuk's ``iccerrboundA`` times 8
INCIRCLE_BOUND = 8.0 * (10.0 + 96.0 * 2.0 ** -53) * 2.0 ** -53


@numba.njit(cache=True, nogil=True)
def cocircular_edges(xy, triangles):
    """Number of edges shared by two triangles whose four points may lie on one circle.

    ``xy``: ``(V, 2)`` float64 vertex coordinates; ``triangles``: ``(T, 6)`` uint32 rows of
    three vertex indices, then three neighbours (neighbour ``i`` across the edge from corner
    ``i`` to corner ``i + 1``; a value ``>= T`` means none): CDT's ``triangles_array`` viewed as
    ``uint32``. Each shared edge is counted once."""
    count = 0
    n = triangles.shape[0]
    for t in range(n):
        for i in range(3):
            other = numba.int64(triangles[t, 3 + i])
            if other >= n or other <= t:
                continue
            a = numba.int64(triangles[t, i])
            b = numba.int64(triangles[t, (i + 1) % 3])
            c = numba.int64(triangles[t, (i + 2) % 3])
            d = (numba.int64(triangles[other, 0]) + numba.int64(triangles[other, 1])
                 + numba.int64(triangles[other, 2]) - a - b)
            dx, dy = xy[d, 0], xy[d, 1]
            adx, ady = xy[a, 0] - dx, xy[a, 1] - dy
            bdx, bdy = xy[b, 0] - dx, xy[b, 1] - dy
            cdx, cdy = xy[c, 0] - dx, xy[c, 1] - dy
            alift = adx * adx + ady * ady
            blift = bdx * bdx + bdy * bdy
            clift = cdx * cdx + cdy * cdy
            bc, cb = bdx * cdy, cdx * bdy
            ca, ac = cdx * ady, adx * cdy
            ab, ba = adx * bdy, bdx * ady
            det = alift * (bc - cb) + blift * (ca - ac) + clift * (ab - ba)
            permanent = ((abs(bc) + abs(cb)) * alift + (abs(ca) + abs(ac)) * blift
                         + (abs(ab) + abs(ba)) * clift)
            if abs(det) <= INCIRCLE_BOUND * permanent:
                count += 1
    return count


@numba.njit(cache=True, nogil=True)
def cdt_tables(triangles, renumber, first):
    """The triangles and neighbours of :func:`toolbox.terrain.tin.kernels._drop_super_triangle`
    and :func:`~toolbox.terrain.tin.kernels._kept_neighbours` in two passes over CDT's
    ``(T, 6)`` uint32 rows (three vertices, three neighbours, the layout of
    :func:`cocircular_edges`): rows touching a vertex below ``first`` (the super-triangle's) are
    dropped, vertex ``v`` becomes ``renumber[v]`` (or ``v - first`` when ``renumber`` is empty),
    and the neighbour across the edge facing corner ``j`` is CDT's neighbour ``(j + 1) % 3``
    renumbered to the kept rows (-1 for none, a dropped row or an index ``>= T``). Both int32."""
    t_all = triangles.shape[0]
    new_index = np.full(t_all + 1, -1, np.int32)
    count = 0
    for t in range(t_all):
        if min(triangles[t, 0], triangles[t, 1], triangles[t, 2]) >= first:
            new_index[t] = count
            count += 1
    out = np.empty((count, 3), np.int32)
    neighbors = np.empty((count, 3), np.int32)
    for t in range(t_all):
        k = new_index[t]
        if k < 0:
            continue
        for j in range(3):
            v = numba.int64(triangles[t, j])
            out[k, j] = renumber[v] if renumber.shape[0] else v - first
            other = min(numba.int64(triangles[t, 3 + (j + 1) % 3]), t_all)
            neighbors[k, j] = new_index[other]
    return out, neighbors
