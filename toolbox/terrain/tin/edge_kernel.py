"""A TIN's edge table and its triangles' areas, each in one compiled pass over the triangles
(numba; also compiled ahead of time, :mod:`toolbox.aot`): the twins of
:func:`toolbox.terrain.tin.topology.edge_table` and :func:`~toolbox.terrain.tin.topology.triangle_areas`
for int32 triangles and neighbours (a triangulation's own arrays).

The numpy version makes about ten whole-array temporaries (half-edge indices, masks, the
neighbours' rows): 0.15 s of CPU for a 1 M-point TIN's 3 M edges once its memory is warm, and
0.55-0.85 s in a fresh process, where most of it is first touching about 200 MB (measured here
in process, successive calls). This kernel touches its four outputs only. The numpy version is
the fallback where no compiled module is built, and the oracle (tests: the same arrays).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def edge_arrays(triangles, neighbors):
    """``(nodes, left, right, triangle_edges)`` of :class:`~toolbox.terrain.tin.topology.EdgeTable`
    for int32 ``(T, 3)`` ``triangles`` and ``neighbors`` (every neighbour ``< T``; negative:
    none). An edge is listed once, from its triangle of lower index (a neighbour of higher
    index or none), in the order of that triangle then its corner; the neighbour's own corner
    gets the edge's id at the first of its corners that faces back (corner 0 if none)."""
    t_count = triangles.shape[0]
    n_edges = 0
    for t in range(t_count):
        for j in range(3):
            other = neighbors[t, j]
            if other < 0 or other > t:
                n_edges += 1
    nodes = np.empty((n_edges, 2), np.int32)
    left = np.empty(n_edges, np.int32)
    right = np.empty(n_edges, np.int32)
    triangle_edges = np.full((t_count, 3), -1, np.int32)
    e = 0
    for t in range(t_count):
        for j in range(3):
            other = neighbors[t, j]
            if other < 0 or other > t:
                nodes[e, 0] = triangles[t, (j + 1) % 3]
                nodes[e, 1] = triangles[t, (j + 2) % 3]
                left[e] = t
                right[e] = other
                triangle_edges[t, j] = e
                e += 1
    # after every listed edge, as the numpy version assigns them (a malformed neighbour table
    # then gives the same arrays too)
    for e in range(n_edges):
        other = right[e]
        if other >= 0:
            t = left[e]
            back = 0
            if neighbors[other, 0] != t:
                if neighbors[other, 1] == t:
                    back = 1
                elif neighbors[other, 2] == t:
                    back = 2
            triangle_edges[other, back] = e
    return nodes, left, right, triangle_edges


@numba.njit(cache=True, nogil=True)
def triangle_areas(xyz, triangles):
    """Planimetric and 3D area of each triangle (``(T,)`` float64 each) of int32 ``triangles``
    on ``(N, 3)`` float64 ``xyz``: :func:`toolbox.terrain.tin.topology.triangle_areas`' very
    operations (the same bits) without its ``(T, 3, 3)`` gather and temporaries."""
    t_count = triangles.shape[0]
    flat = np.empty(t_count)
    space = np.empty(t_count)
    for t in range(t_count):
        i, j, k = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        ux, uy, uz = xyz[j, 0] - xyz[i, 0], xyz[j, 1] - xyz[i, 1], xyz[j, 2] - xyz[i, 2]
        vx, vy, vz = xyz[k, 0] - xyz[i, 0], xyz[k, 1] - xyz[i, 1], xyz[k, 2] - xyz[i, 2]
        a = uy * vz - uz * vy
        b = uz * vx - ux * vz
        c = ux * vy - uy * vx
        flat[t] = abs(c) / 2.0
        space[t] = np.sqrt(a * a + b * b + c * c) / 2.0
    return flat, space
