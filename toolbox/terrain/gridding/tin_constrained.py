"""TIN-linear kernels: the constrained TIN of the data points, and its leave-one-out
predictions (each point predicted from the TIN of the others).

Leave-one-out: the points are split into independent sets (no two joined by a TIN edge, by
greedy colouring), each set is removed at once and the others re-triangulated, which gives
every point exactly the TIN of the others (removing a vertex changes only its own star).
Breakline vertices stay in (they are constraints) and are not predicted. A prediction is the
plane of its triangle computed from the triangle's lowest vertex (smallest x, then y) in the
caller's coordinates: the same bits whatever the triangulation's vertex numbering (the streamed
QUALITY of :mod:`toolbox.terrain.gridding.stream_quality` finds the same triangle in a bucket).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.cache import njit_on_first_call
from toolbox.feedback import Feedback


def constrained_tin(xyz: np.ndarray, segments: np.ndarray | None
                    ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Delaunay TIN of ``xyz`` ((n, 3)), constrained by breakline ``segments`` ((s, 2) indices).

    Uses the TIN kernels of tin:delaunay (CDT by default, or Triangle). Where breaklines
    cross without a shared vertex, they are split at the crossing; the new node takes the height
    interpolated linearly along each crossing segment (their mean where they disagree; the
    largest disagreement is reported).

    Returns
    -------
    nodes : (V, 3) float64
        ``xyz`` followed by the crossing nodes.
    triangles : (T, 3) int32
    info : dict
        ``crossings`` (count) and ``crossing_z_disagreement`` (m).
    """
    from toolbox.terrain.tin.kernels import (
        CrossingSegmentsError,
        crossing_heights,
        triangulate,
        triangulate_pslg,
    )

    seg = segments if segments is not None and len(segments) else None
    try:
        return xyz, triangulate(xyz[:, :2], seg), {"crossings": 0}
    except CrossingSegmentsError:
        if seg is None:
            raise
    tri = triangulate_pslg(xyz[:, :2], seg, neighbors=False)
    heights, spread = crossing_heights(tri, xyz, seg)
    nodes = np.vstack([xyz, np.column_stack([tri.vertices[tri.n_input:], heights])])
    return nodes, tri.triangles, {
        "crossings": tri.steiner_count, "crossing_z_disagreement": float(spread.max())}


@njit_on_first_call(cache=True)
def _greedy_colours(n, indptr, indices, protected):
    """Colour the vertices so that no two neighbours share a colour (greedy, vertex order);
    protected vertices get -1."""
    colour = np.full(n, -1, dtype=np.int64)
    seen = np.full(64, -1, dtype=np.int64)
    for v in range(n):
        if protected[v]:
            continue
        for p in range(indptr[v], indptr[v + 1]):
            c = colour[indices[p]]
            if c >= 0:
                if c >= len(seen):
                    bigger = np.full(2 * c + 2, -1, dtype=np.int64)
                    bigger[:len(seen)] = seen
                    seen = bigger
                seen[c] = v
        c = 0
        while c < len(seen) and seen[c] == v:
            c += 1
        colour[v] = c
    return colour


def lowest_first(xy: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """``triangles`` rotated (orientation kept) to start at their vertex of smallest x, then
    smallest y."""
    tri = np.asarray(triangles)
    if not len(tri):
        return tri
    xs, ys = xy[tri, 0], xy[tri, 1]
    ys = np.where(xs == xs.min(axis=1)[:, None], ys, np.inf)
    first = np.argmin(ys, axis=1)
    return tri[np.arange(len(tri))[:, None], (first[:, None] + np.arange(3)) % 3]


def tin_loo(local_xyz: np.ndarray, segments: np.ndarray | None,
            feedback: Feedback | None = None, targets: np.ndarray | None = None) -> np.ndarray:
    """Leave-one-out TIN-linear predictions (see the module notes). NaN: not predicted.
    ``targets``: the indices of the points to predict (default all; the others NaN)."""
    from scipy.sparse import coo_matrix

    from toolbox.terrain.tin.kernels import interpolate_tin

    n = len(local_xyz)
    seg = np.zeros((0, 2), dtype=np.int64) if segments is None else np.asarray(segments)
    _, triangles, _ = constrained_tin(local_xyz, seg)
    edges = np.vstack([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    edges = edges[(edges < n).all(axis=1)]  # between input points (not crossing nodes)
    adjacency = coo_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]],
                                                      np.r_[edges[:, 1], edges[:, 0]])),
                           shape=(n, n)).tocsr()
    protected = np.zeros(n, dtype=np.bool_)
    if len(seg):
        protected[seg.ravel()] = True
    colour = _greedy_colours(n, adjacency.indptr.astype(np.int64),
                             adjacency.indices.astype(np.int64), protected)
    predicted = np.full(n, np.nan)
    wanted = np.ones(n, dtype=bool)
    if targets is not None:
        wanted[:] = False
        wanted[targets] = True
    colours = int(colour.max()) + 1 if (colour >= 0).any() else 0
    for c in range(colours):
        if feedback is not None:
            feedback.check_canceled()
            feedback.set_progress(100.0 * c / max(colours, 1))
        out = np.flatnonzero((colour == c) & wanted)
        if not len(out):
            continue
        keep = np.flatnonzero(colour != c)
        if len(keep) < 3:
            continue
        lookup = np.full(n, -1, dtype=np.int64)
        lookup[keep] = np.arange(len(keep))
        sub_seg = lookup[seg] if len(seg) else None
        try:
            nodes, tri, _ = constrained_tin(local_xyz[keep], sub_seg)
        except ValueError:  # the others are collinear: nothing to predict from
            continue
        predicted[out] = interpolate_tin(nodes, lowest_first(nodes, tri), local_xyz[out, 0],
                                         local_xyz[out, 1], origin=(0.0, 0.0))
    return predicted
