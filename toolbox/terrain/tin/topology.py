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


def edge_table(triangles: np.ndarray, neighbors: np.ndarray) -> EdgeTable:
    """Unique edges with their left and right triangles, from triangles and neighbours.

    Each edge is listed once, directed as in the triangle with the lower index (which is then on
    its left, triangles being counter-clockwise). Order: by that triangle, then by corner.
    Indices are int32 when they fit (a 10 M-point TIN's table takes 0.7 GB instead of 1.4 GB),
    and no ``(T, 3)`` temporaries are built besides ``triangle_edges``.
    """
    tri = np.asarray(triangles)
    nb = np.asarray(neighbors)
    t_count = len(tri)
    index = np.int32 if 3 * t_count < np.iinfo(np.int32).max \
        and (t_count == 0 or int(tri.max()) < np.iinfo(np.int32).max) else np.int64
    keep = (nb < 0) | (np.arange(t_count, dtype=index)[:, None] < nb)
    t_idx, corner = (a.astype(index) for a in np.nonzero(keep))
    del keep
    n_edges = len(t_idx)
    tri_edges = np.full((t_count, 3), -1, dtype=index)
    tri_edges[t_idx, corner] = np.arange(n_edges, dtype=index)
    right = nb[t_idx, corner].astype(index)
    shared = np.flatnonzero(right >= 0).astype(index)
    other = right[shared]
    # corner of the neighbour that faces back to this triangle
    back = np.argmax(nb[other] == t_idx[shared, None], axis=1)
    tri_edges[other, back] = shared
    del other, back, shared
    nodes = np.empty((n_edges, 2), dtype=index)  # half-edge j runs corner j+1 -> corner j+2
    nodes[:, 0] = tri[t_idx, (corner + 1) % 3]
    nodes[:, 1] = tri[t_idx, (corner + 2) % 3]
    return EdgeTable(nodes, t_idx, right, tri_edges)


@dataclass
class TriangleMeasures:
    """Per-triangle measures; angles in degrees, areas in squared map units."""

    area_2d: np.ndarray  # planimetric area
    area_3d: np.ndarray  # area of the triangle in space
    slope_deg: np.ndarray
    slope_pct: np.ndarray  # 100 * tan(slope)
    aspect_deg: np.ndarray  # direction the slope faces, clockwise from north; -1 where flat


def plane_normals(xyz: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """``(a, b, c)`` of thesis eq. [43] for each triangle, ``(T, 3)``.

    They are the cross product of the edge vectors P2 - P1 and P3 - P1 (the same numbers as the
    eq. [43] sums, computed from coordinate differences so large coordinates keep their
    digits); ``c`` is twice the signed planimetric area, > 0 for counter-clockwise triangles.
    The plane is ``z = z1 - (a/c)(x - x1) - (b/c)(y - y1)`` (eq. [44]).
    """
    xyz = np.asarray(xyz, dtype="float64")
    tri = np.asarray(triangles, dtype=np.int64)
    p1 = xyz[tri[:, 0]]
    u = xyz[tri[:, 1]] - p1
    w = xyz[tri[:, 2]] - p1
    return np.cross(u, w)


def triangle_measures(xyz: np.ndarray, triangles: np.ndarray) -> TriangleMeasures:
    """Planimetric and 3D area, slope (degrees, percent) and aspect of each triangle."""
    n = plane_normals(xyz, triangles)
    a, b, c = n[:, 0], n[:, 1], n[:, 2]
    horizontal = np.hypot(a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.degrees(np.arctan2(horizontal, np.abs(c)))
        tan = horizontal / np.abs(c)
    # downslope direction is -grad z = (a/c, b/c); azimuth = atan2(east, north)
    sign = np.where(c < 0, -1.0, 1.0)
    aspect = np.degrees(np.arctan2(a * sign, b * sign)) % 360.0
    aspect = np.where(horizontal == 0, -1.0, aspect)
    return TriangleMeasures(np.abs(c) / 2.0, np.linalg.norm(n, axis=1) / 2.0, slope,
                            np.where(np.isfinite(tan), 100.0 * tan, np.inf), aspect)


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
