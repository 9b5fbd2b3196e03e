"""Leave-one-out cross-validation of the gridding methods on the data points.

Each data point in turn is left out, its height predicted from the others with the method and
options of the DEM, and the error ``predicted - observed`` recorded. RMSE, mean (bias) and
maximum absolute error per method let a surveyor choose the method with evidence.

Rules (the same as the gridding): with EXTRAPOLATE off, a point that is a vertex of the convex
hull lies outside the hull of the others and is not predicted; MAX_DISTANCE and MIN_NEIGHBOURS
apply as in the grid. Each method predicts in its own way (``Method.loo``); ``tin_linear`` uses
the TIN of the other points (see :func:`toolbox.terrain.gridding.tin_constrained.tin_loo`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.feedback import Feedback
from toolbox.terrain.gridding.masks import hull_vertex_indices


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
                      # the sample standard deviation (n - 1, ASPRS Positional Accuracy
                      # Standards, Annex D), undefined for a single error
                      "std_error": float(err.std(ddof=1)) if n > 1 else None,
                      "worst_point_index": int(np.flatnonzero(ok)[worst])}


def add_worst_point(summary: dict[str, Any], xyz: np.ndarray, predicted: np.ndarray) -> None:
    """Add the map coordinates of the point with the largest |error| to a summary."""
    index = summary.get("worst_point_index")
    if index is not None:
        summary["worst_point"] = {"x": float(xyz[index, 0]), "y": float(xyz[index, 1]),
                                  "z": float(xyz[index, 2]), "predicted": float(predicted[index])}


def loo_predict(method: Any, local_xyz: np.ndarray, options: dict[str, Any],
                extrapolate: bool = False, segments: np.ndarray | None = None,
                feedback: Feedback | None = None, workers: int | None = None
                ) -> tuple[np.ndarray, dict[str, Any]]:
    """Leave-one-out prediction at every point of ``local_xyz`` ((n, 3), local origin) with a
    :class:`~toolbox.terrain.gridding.methods.base.Method`.

    Returns ``(predicted (n,), details)``; NaN where the point is not predicted. ``details``
    holds method counters (orders used by the polynomial methods).
    """
    feedback = feedback or Feedback()
    n = len(local_xyz)
    details: dict[str, Any] = {}
    predicted, used = method.loo(local_xyz, options, segments, feedback, workers)
    if not extrapolate and n >= 3:
        outside = hull_vertex_indices(local_xyz[:, :2])
        predicted[outside] = np.nan
        details["hull_vertices_not_predicted"] = int(len(outside))
    if used is not None:
        from toolbox.terrain.gridding.request import ORDER_NAMES

        used[np.isnan(predicted)] = -1
        details["orders_used"] = {ORDER_NAMES[o]: int(np.sum(used == o)) for o in range(4)}
    return predicted, details
