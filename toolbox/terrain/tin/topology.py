"""TIN topology and per-triangle measures (numpy kernels).

The stored structure of a TIN (thesis par. 2.5.1; ../shared/docs/domain.md par. 14) is nodes,
edges, triangles and their relations: each triangle's nodes, edges and neighbours; each edge's
nodes and the triangles on its left and right. Conventions: triangles are counter-clockwise;
corner ``j`` of triangle ``t`` faces the edge ``triangles[t, j+1] -> triangles[t, j+2]``
(indices mod 3); ``-1`` means "none" (no neighbour across a hull edge).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np


def _half_edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end vertex of the three half-edges of each triangle, ``(T, 3)`` each; half-edge
    ``j`` is the edge opposite corner ``j``, in counter-clockwise direction."""
    tri = np.asarray(triangles, dtype=np.int64)
    return tri[:, [1, 2, 0]], tri[:, [2, 0, 1]]


def neighbors_from_triangles(triangles: np.ndarray) -> np.ndarray:
    """Neighbour across the edge opposite each corner, ``(T, 3)`` int64, -1 on the border.

    For triangulations read back from a file (Triangle returns neighbours itself). An edge
    shared by more than two triangles (not a valid TIN) raises ``ValueError``.
    """
    tri = np.asarray(triangles, dtype=np.int64)
    t_count = len(tri)
    start, end = _half_edges(tri)
    n = int(tri.max()) + 1 if t_count else 0
    lo = np.minimum(start, end).ravel()
    hi = np.maximum(start, end).ravel()
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    same = sorted_key[1:] == sorted_key[:-1]
    if np.any(same[1:] & same[:-1]):
        raise ValueError("an edge is shared by more than two triangles: not a valid TIN")
    out = np.full(3 * t_count, -1, dtype=np.int64)
    first, second = order[:-1][same], order[1:][same]
    out[first] = second // 3
    out[second] = first // 3
    return out.reshape(t_count, 3)


def hull_edges(triangles: np.ndarray, neighbors: np.ndarray | None = None) -> np.ndarray:
    """Border edges (with a triangle on one side only), ``(E, 2)`` vertex indices, oriented
    counter-clockwise around the TIN (the TIN on their left)."""
    nb = neighbors_from_triangles(triangles) if neighbors is None else np.asarray(neighbors)
    start, end = _half_edges(triangles)
    border = nb < 0
    return np.column_stack([start[border], end[border]])


@dataclass
class EdgeTable:
    """Each edge once: ``nodes`` (E, 2) from/to vertex indices, ``left``/``right`` (E,) triangle
    indices (``right`` -1 on the border), and ``triangle_edges`` (T, 3): the edge facing each
    triangle corner."""

    nodes: np.ndarray
    left: np.ndarray
    right: np.ndarray
    triangle_edges: np.ndarray


#: half-edge ``3 t + j`` (the edge facing corner ``j`` of triangle ``t``) -> the flat index of
#: corner ``(j + 1) % 3`` (the edge's start) and of corner ``(j + 2) % 3`` (its end)
_START = np.array([1, 1, -2], dtype=np.intp)
_END = np.array([2, -1, -1], dtype=np.intp)


def edge_table(triangles: np.ndarray, neighbors: np.ndarray) -> EdgeTable:
    """Unique edges with their left and right triangles, from triangles and neighbours.

    Each edge is listed once, directed as in the triangle with the lower index (which is then on
    its left, triangles being counter-clockwise). Order: by that triangle, then by corner.
    Indices are int32 when they fit (a 10 M-point TIN's table takes 0.7 GB instead of 1.4 GB),
    and no ``(T, 3)`` integer temporaries are built besides ``triangle_edges``: the half-edges
    are flat indices ``3 t + j`` read with :func:`numpy.take` (0.18 s CPU for a million points'
    3 M edges; 0.39 s with ``(row, column)`` fancy indexing and an ``argmax`` along rows).
    A triangulation's own int32 arrays go through the compiled twin of these steps where it is
    built (:mod:`toolbox.terrain.tin.edge_kernel`: the same arrays, without the temporaries).
    """
    tri = np.asarray(triangles)
    nb = np.asarray(neighbors)
    compiled = _compiled_edge_arrays(tri, nb)
    if compiled is not None:
        return EdgeTable(*compiled(tri, nb))
    t_count = len(tri)
    index = np.int32 if 3 * t_count < np.iinfo(np.int32).max \
        and (t_count == 0 or int(tri.max()) < np.iinfo(np.int32).max) else np.int64
    flat_nb = np.ascontiguousarray(nb).reshape(-1)
    # an edge is listed from its triangle of lower index: the neighbour's is higher, or there is
    # none (a negative index, which as an unsigned number is higher than any triangle's)
    unsigned = flat_nb.view(np.dtype(f"u{flat_nb.dtype.itemsize}"))
    keep = unsigned.reshape(-1, 3) > np.arange(t_count, dtype=unsigned.dtype)[:, None]
    half = np.flatnonzero(keep)  # the listed half-edges, 3 t + j
    del keep, unsigned
    n_edges = len(half)
    t_idx = (half // 3).astype(index)
    corner = (half - 3 * t_idx).astype(np.int8)
    tri_edges = np.full((t_count, 3), -1, dtype=index)
    flat_edges = tri_edges.reshape(-1)
    flat_edges[half] = np.arange(n_edges, dtype=index)
    right = np.take(flat_nb, half).astype(index, copy=False)
    shared = np.flatnonzero(right >= 0)
    other = np.take(right, shared)
    mine = np.take(t_idx, shared)
    # the neighbour's half-edge that faces back: its first corner whose neighbour is this
    # triangle (corner 0 if none, as an argmax along the row said); its row read a column at a
    # time (no (S, 3) int64 temporary: 0.7 GB for a 10 M-point TIN)
    back = 3 * other.astype(np.intp)
    del other
    first = np.take(flat_nb, back) == mine
    second = np.take(flat_nb, back + 1) == mine
    third = np.take(flat_nb, back + 2) == mine
    del mine
    back += second & ~first
    back += 2 * (third & ~first & ~second)
    del first, second, third
    flat_edges[back] = shared
    del back, shared
    flat_tri = np.ascontiguousarray(tri).reshape(-1)
    nodes = np.empty((n_edges, 2), dtype=index)
    nodes[:, 0] = np.take(flat_tri, half + np.take(_START, corner))
    nodes[:, 1] = np.take(flat_tri, half + np.take(_END, corner))
    return EdgeTable(nodes, t_idx, right, tri_edges)


def _compiled_edge_arrays(tri: np.ndarray, nb: np.ndarray):
    """The compiled edge kernel when it is built and takes these arrays (C-contiguous int32
    ``(T, 3)``, ids within int32, every neighbour a triangle or negative), else None."""
    t_count = len(tri)
    if not (t_count and tri.dtype == nb.dtype == np.int32 and tri.shape == nb.shape == (t_count, 3)
            and tri.flags.c_contiguous and nb.flags.c_contiguous
            and 3 * t_count < np.iinfo(np.int32).max):
        return None
    from toolbox.aot import compiled_kernel

    compiled = compiled_kernel("edge_arrays")
    if compiled is None or int(nb.max()) >= t_count:  # (numpy's take raises for those)
        return None
    return compiled


@dataclass
class TriangleMeasures:
    """Per-triangle measures; angles in degrees, areas in squared map units."""

    area_2d: np.ndarray  # planimetric area
    area_3d: np.ndarray  # area of the triangle in space
    slope_deg: np.ndarray
    slope_pct: np.ndarray  # 100 * tan(slope)
    aspect_deg: np.ndarray  # direction the slope faces, clockwise from north; -1 where flat


def triangle_corners(xyz: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The triangles' vertices, ``(T, 3, 3)``: ``xyz[triangles]`` (by ``np.take``, a third of
    the time of fancy indexing on a million triangles)."""
    return np.take(np.asarray(xyz, dtype="float64"), np.asarray(triangles, dtype=np.int64),
                   axis=0)


def plane_normals(xyz: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """``(a, b, c)`` of thesis eq. [43] for each triangle, ``(T, 3)``.

    They are the cross product of the edge vectors P2 - P1 and P3 - P1 (the same numbers as the
    eq. [43] sums, computed from coordinate differences so large coordinates keep their
    digits); ``c`` is twice the signed planimetric area, > 0 for counter-clockwise triangles.
    The plane is ``z = z1 - (a/c)(x - x1) - (b/c)(y - y1)`` (eq. [44]).
    """
    return corner_normals(triangle_corners(xyz, triangles))


def corner_normals(corner_xyz: np.ndarray) -> np.ndarray:
    """:func:`plane_normals` of triangles given by their ``(T, 3, 3)`` :func:`triangle_corners`.
    Component by component, the very operations of ``np.cross`` (the same bits) in a third of
    its time: ``np.cross`` moves axes and multiplies through strided views."""
    p1 = corner_xyz[:, 0]
    u, v = corner_xyz[:, 1] - p1, corner_xyz[:, 2] - p1
    normals = np.empty_like(u)
    normals[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    normals[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    normals[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return normals


def triangle_areas(xyz: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planimetric and 3D area of each triangle (the first two :func:`triangle_measures`); in
    one compiled pass for int32 triangles where :mod:`toolbox.terrain.tin.edge_kernel` is built
    (the same bits: tests)."""
    xyz, triangles = np.asarray(xyz), np.asarray(triangles)
    if xyz.dtype == np.float64 and xyz.ndim == 2 and xyz.shape[1] == 3 \
            and triangles.dtype == np.int32 and triangles.ndim == 2 and triangles.shape[1] == 3 \
            and len(triangles) and int(triangles.min()) >= 0 and int(triangles.max()) < len(xyz):
        from toolbox.aot import compiled_kernel

        compiled = compiled_kernel("triangle_areas")
        if compiled is not None:
            return compiled(np.ascontiguousarray(xyz), np.ascontiguousarray(triangles))
    return _areas(plane_normals(xyz, triangles))


def _areas(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planimetric and 3D areas from :func:`plane_normals`: half ``|c|``, half the length (summed
    in ``np.linalg.norm``'s order: the same bits)."""
    a, b, c = normals[:, 0], normals[:, 1], normals[:, 2]
    return np.abs(c) / 2.0, np.sqrt(a * a + b * b + c * c) / 2.0


def triangle_measures(xyz: np.ndarray, triangles: np.ndarray) -> TriangleMeasures:
    """Planimetric and 3D area, slope (degrees, percent) and aspect of each triangle."""
    return corner_measures(triangle_corners(xyz, triangles))


def corner_measures(corner_xyz: np.ndarray) -> TriangleMeasures:
    """:func:`triangle_measures` of triangles given by their ``(T, 3, 3)`` :func:`triangle_corners`."""
    n = corner_normals(corner_xyz)
    a, b, c = n[:, 0], n[:, 1], n[:, 2]
    horizontal = np.hypot(a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.degrees(np.arctan2(horizontal, np.abs(c)))
        tan = horizontal / np.abs(c)
    # downslope direction is -grad z = (a/c, b/c); azimuth = atan2(east, north)
    sign = np.where(c < 0, -1.0, 1.0)
    aspect = np.degrees(np.arctan2(a * sign, b * sign)) % 360.0
    aspect = np.where(horizontal == 0, -1.0, aspect)
    return TriangleMeasures(*_areas(n), slope, np.where(np.isfinite(tan), 100.0 * tan, np.inf),
                            aspect)


def median_edge_length(xyz: np.ndarray, triangles: np.ndarray, neighbors: np.ndarray) -> float:
    """Median planimetric length of the TIN's edges (each edge once)."""
    nodes = edge_table(triangles, neighbors).nodes
    d = xyz[nodes[:, 1], :2] - xyz[nodes[:, 0], :2]
    return float(np.median(np.hypot(d[:, 0], d[:, 1])))


def erode_concave(xy: np.ndarray, triangles: np.ndarray, neighbors: np.ndarray,
                  max_edge: float) -> np.ndarray:
    """Chi-shape erosion: mask of triangles kept after removing, longest border edge first,
    border triangles whose border edge is longer than ``max_edge`` and whose third node is not
    on the border yet. ``neighbors`` is updated in place."""
    tri = triangles
    nb = neighbors
    alive = np.ones(len(tri), dtype=bool)
    on_border = np.zeros(len(xy), dtype=bool)
    t_b, j_b = np.nonzero(nb < 0)
    on_border[tri[t_b, (j_b + 1) % 3]] = True
    on_border[tri[t_b, (j_b + 2) % 3]] = True

    def length(t: int, j: int) -> float:
        a, b = xy[tri[t, (j + 1) % 3]], xy[tri[t, (j + 2) % 3]]
        return float(np.hypot(*(b - a)))

    heap = [(-length(t, j), int(t), int(j)) for t, j in zip(t_b, j_b, strict=True)]
    heap = [h for h in heap if -h[0] > max_edge]
    heapq.heapify(heap)
    while heap:
        _, t, j = heapq.heappop(heap)
        if not alive[t] or nb[t, j] >= 0:
            continue
        apex = tri[t, j]
        if on_border[apex]:
            continue
        alive[t] = False
        on_border[apex] = True
        for k in (1, 2):
            jj = (j + k) % 3
            other = nb[t, jj]
            if other < 0:
                continue
            back = int(np.flatnonzero(nb[other] == t)[0])
            nb[other, back] = -1
            nb[t, jj] = -1
            edge_len = length(other, back)
            if edge_len > max_edge:
                heapq.heappush(heap, (-edge_len, int(other), back))
    return alive
