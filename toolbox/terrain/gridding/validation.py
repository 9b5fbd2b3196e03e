"""Leave-one-out cross-validation of the gridding methods on the data points.

Each data point in turn is left out, its height predicted from the others with the method and
options of the DEM, and the error ``predicted - observed`` recorded. RMSE, mean (bias) and
maximum absolute error per method let a surveyor choose the method with evidence.

Rules (the same as the gridding): with EXTRAPOLATE off, a point that is a vertex of the convex
hull lies outside the hull of the others and is not predicted; MAX_DISTANCE and MIN_NEIGHBOURS
apply as in the grid. For ``tin_linear`` the triangulation without the point is used: the points
are split into independent sets (no two joined by a TIN edge, by greedy colouring), each set is
removed at once and the others re-triangulated, which gives every point exactly the TIN of the
others (removing a vertex changes only its own star). Breakline vertices stay in (they are
constraints) and are not predicted.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from toolbox.feedback import Feedback
from toolbox.terrain.gridding.masks import hull_vertex_indices
from toolbox.terrain.gridding.methods import Method
from toolbox.terrain.gridding.neighbours import PointBins


def error_summary(predicted: np.ndarray, observed: np.ndarray) -> dict[str, Any]:
    """RMSE, mean error, max absolute error... of ``predicted - observed`` where predicted."""
    ok = np.isfinite(predicted)
    err = predicted[ok] - observed[ok]
    n = int(ok.sum())
    summary: dict[str, Any] = {"points": int(len(observed)), "predicted": n,
                               "not_predicted": int(len(observed) - n)}
    if n == 0:
        return summary | {"rmse": None, "mean_error": None, "max_abs_error": None,
                          "mean_abs_error": None, "std_error": None}
    worst = int(np.argmax(np.abs(err)))
    return summary | {"rmse": float(np.sqrt(np.mean(err ** 2))), "mean_error": float(err.mean()),
                      "max_abs_error": float(np.abs(err).max()),
                      "mean_abs_error": float(np.abs(err).mean()),
                      "std_error": float(err.std()),
                      "worst_point_index": int(np.flatnonzero(ok)[worst])}


def add_worst_point(summary: dict[str, Any], xyz: np.ndarray, predicted: np.ndarray) -> None:
    """Add the map coordinates of the point with the largest |error| to a summary."""
    index = summary.get("worst_point_index")
    if index is not None:
        summary["worst_point"] = {"x": float(xyz[index, 0]), "y": float(xyz[index, 1]),
                                  "z": float(xyz[index, 2]), "predicted": float(predicted[index])}


def loo_predict(method: Method, local_xyz: np.ndarray, options: dict[str, Any],
                extrapolate: bool = False, segments: np.ndarray | None = None,
                feedback: Feedback | None = None, workers: int | None = None
                ) -> tuple[np.ndarray, dict[str, Any]]:
    """Leave-one-out prediction at every point of ``local_xyz`` ((n, 3), local origin).

    Returns ``(predicted (n,), details)``; NaN where the point is not predicted. ``details``
    holds method counters (orders used by the polynomial methods).
    """
    feedback = feedback or Feedback()
    n = len(local_xyz)
    details: dict[str, Any] = {}
    used = None
    if method.name == "tin_linear":
        predicted = tin_loo(local_xyz, segments, feedback)
        max_distance = options.get("max_distance", math.inf)
        if math.isfinite(max_distance) and n > 1:  # as in the grid: nearest other point
            bins = PointBins.build(local_xyz[:, :2])
            d2, _ = bins.query(local_xyz[:, 0], local_xyz[:, 1], 1, skip=np.arange(n))
            predicted[d2[:, 0] > max_distance ** 2] = np.nan
    else:
        predicted, used = _knn_loo(method, local_xyz, options, feedback, workers)
    if not extrapolate and n >= 3:
        outside = hull_vertex_indices(local_xyz[:, :2])
        predicted[outside] = np.nan
        details["hull_vertices_not_predicted"] = int(len(outside))
    if used is not None:
        from toolbox.terrain.gridding.polynomial import ORDER_NAMES

        used[np.isnan(predicted)] = -1
        details["orders_used"] = {ORDER_NAMES[o]: int(np.sum(used == o)) for o in range(4)}
    return predicted, details


def _knn_loo(method: Method, local_xyz: np.ndarray, options: dict[str, Any],
             feedback: Feedback, workers: int | None) -> tuple[np.ndarray, np.ndarray | None]:
    from toolbox.tiles import Executor, default_workers, map_tiles

    n = len(local_xyz)
    bins = PointBins.build(local_xyz[:, :2])
    z = local_xyz[:, 2]
    chunk = max(1000, math.ceil(n / 64))
    starts = list(range(0, n, chunk))

    def run(start: int):
        targets = np.arange(start, min(start + chunk, n))
        return method.loo(bins, z, targets, options)

    predicted = np.full(n, np.nan)
    used = None
    executor = Executor("local", workers or default_workers())
    for start, (pred, order) in zip(starts, map_tiles(run, starts, executor=executor,
                                                      feedback=feedback, total=len(starts)),
                                    strict=True):
        predicted[start:start + len(pred)] = pred
        if order is not None:
            if used is None:
                used = np.full(n, -1, dtype=np.int64)
            used[start:start + len(order)] = order
    return predicted, used


@njit(cache=True)
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


def tin_loo(local_xyz: np.ndarray, segments: np.ndarray | None,
            feedback: Feedback | None = None) -> np.ndarray:
    """Leave-one-out TIN-linear predictions (see the module notes). NaN: not predicted."""
    from scipy.sparse import coo_matrix

    from toolbox.terrain.gridding.tin_linear import constrained_tin
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
    colours = int(colour.max()) + 1 if (colour >= 0).any() else 0
    for c in range(colours):
        if feedback is not None:
            feedback.check_canceled()
            feedback.set_progress(100.0 * c / max(colours, 1))
        out = np.flatnonzero(colour == c)
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
        predicted[out] = interpolate_tin(nodes, tri, local_xyz[out, 0], local_xyz[out, 1])
    return predicted
