"""The algorithm class shared by every DEM gridding method (read, grid by tiles, report)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any, ClassVar

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Integer, Number
from toolbox.terrain.gridding.gridding import (
    GridRun,
    TileTask,
    check_grid,
    grid_statistics,
    neighbour_tasks,
    prepare_run,
    write_quality,
    write_tiles,
)
from toolbox.terrain.gridding.inputs import GriddingData, check_sources, read_sources, require_points
from toolbox.terrain.gridding.methods import METHODS, Method


def neighbour_parameters(default: int, minimum: int, radius_help: str) -> list:
    """NEIGHBOURS, RADIUS and MIN_NEIGHBOURS of the k-nearest-neighbour methods."""
    return [
        Integer("NEIGHBOURS", f"k nearest data points per cell (at least {minimum})",
                default=default, min_value=minimum, max_value=256),
        Number("RADIUS", radius_help, optional=True, min_value=0, min_exclusive=True),
        Integer("MIN_NEIGHBOURS", "cells with fewer neighbours found (within RADIUS) stay "
                "nodata", default=1, min_value=1),
    ]


class GriddingAlgorithm(Algorithm):
    """Base of ``dem:<method>``: subclasses set ``method`` and the method's parameters."""

    group = "DEM gridding"
    method: ClassVar[str] = ""

    @property
    def spec_method(self) -> Method:
        return METHODS[self.method]

    # -- checks --------------------------------------------------------------------------------
    def check(self, params: dict[str, Any]) -> None:
        check_sources(self, params)
        self.check_method(params)
        check_grid(self, params)

    def check_method(self, params: dict[str, Any]) -> None:
        k, min_k = params.get("NEIGHBOURS"), params.get("MIN_NEIGHBOURS")
        if k is not None and min_k is not None and min_k > k:
            raise self.fail("MIN_NEIGHBOURS", f"must be <= NEIGHBOURS ({k}), got {min_k}")

    # -- work ----------------------------------------------------------------------------------
    def tasks(self, run: GridRun, options: dict[str, Any],
              feedback: Feedback) -> Iterator[TileTask]:
        method = self.spec_method
        k, radius = method.halo_neighbours(options)
        return neighbour_tasks(run, method.tile_function, options, k, radius)

    def summarise_counts(self, counts: np.ndarray | None) -> dict[str, Any]:
        return {}

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        method = self.spec_method
        data = read_sources(params, feedback)
        require_points(data, method.min_points, self.id)
        run = prepare_run(params, data, feedback, use_hull=method.name != "tin_linear")
        options = method.options(params)
        stats = grid_statistics(run, params)
        feedback.set_progress(5)
        written = write_tiles(run, self.tasks(run, options, feedback), params, feedback,
                              start=5, end=90 if params.get("QUALITY") else 98)
        counts = written.pop("counts")
        stats["method"] = {"name": method.name, "options": _jsonable_options(options)}
        stats["cells"] = written
        stats["method"].update(self.summarise_counts(counts))
        result: dict[str, Any] = {"OUTPUT": params["OUTPUT"]}
        if params.get("QUALITY") is not None:
            with feedback.timed("cross_validation"):
                report = quality_report(method, data, options, params, feedback.step(90, 99))
            write_quality(params["QUALITY"], report)
            stats["cross_validation"] = report["methods"][method.name]
            result["QUALITY"] = params["QUALITY"]
        result["STATISTICS"] = stats
        return result


def _jsonable_options(options: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in options.items()}


def quality_report(method: Method, data: GriddingData, options: dict[str, Any],
                   params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
    """Leave-one-out report of one method (the shape ``dem:cross_validate`` writes)."""
    from toolbox.io.crs import crs_label
    from toolbox.terrain.gridding.validation import add_worst_point, error_summary, loo_predict

    local = data.local
    predicted, details = loo_predict(method, local, options, bool(params.get("EXTRAPOLATE")),
                                     data.segments, feedback, params.get("WORKERS"))
    summary = error_summary(predicted, local[:, 2]) | details
    add_worst_point(summary, data.xyz, predicted)
    summary["options"] = _jsonable_options(options)
    return {"what": "leave-one-out cross-validation: error = predicted - observed height",
            "crs": crs_label(data.crs), "points": len(local),
            "duplicates": data.duplicates.as_dict(), "methods": {method.name: summary}}
