"""One DEM gridding run, one way through::

    read points      inputs.read_sources      INPUT points + LINES / BREAKLINES vertices, CRS
                                              checked, duplicate XY merged, local origin
    prepare the grid grid.prepare_grid        the raster engine's grid rules (cell size, extent,
                                              template, size guard), convex hull, mask
    plan tiles       method.plan_tiles        per tile: the arrays it needs (its points, its
                                              triangles, its cell mask) and the kernel
    one kernel/tile  raster.engine            local threads or a Dask cluster, in tile order
    write            raster.writer            tiled 512, DEFLATE, overviews (COG on request)

Kernels (the method modules) see only local-coordinate numpy arrays.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from toolbox.feedback import Feedback
from toolbox.terrain.gridding.grid import GridRun, prepare_grid
from toolbox.terrain.gridding.inputs import GriddingData, read_sources, require_points
from toolbox.terrain.gridding.request import GriddingRequest


def grid_dem(method: Any, request: GriddingRequest, feedback: Feedback,
             data: GriddingData | None = None) -> dict[str, Any]:
    """Grid a DEM with ``method`` (a :class:`~toolbox.terrain.gridding.methods.base.Method`):
    writes ``request.output`` (and ``request.quality``) and returns the STATISTICS.

    ``data``: points already read and merged (e.g. the ground points of ``dem:ground``);
    default: read from ``request.sources``.
    """
    data = read_sources(request.sources, feedback, other_crs(request)) if data is None else data
    require_points(data, method.min_points, f"dem:{method.name}")
    run = prepare_grid(request, data, limit_to_hull=method.limits_to_hull)
    options = method.options(request.method)
    stats = grid_statistics(run, request)
    feedback.set_progress(5)
    tiles = method.plan_tiles(run, options, feedback)
    written = write_dem(run, tiles, request, feedback, start=5,
                        end=90 if request.quality is not None else 98)
    counts = written.pop("counts")
    stats["method"] = {"name": method.name, "options": jsonable_options(options),
                       **method.summarise(counts), **tiles.info}
    stats["cells"] = written
    if request.quality is not None:
        with feedback.timed("cross_validation"):
            report = quality_report(method, data, options, request, feedback.step(90, 99))
        write_quality(request.quality, report)
        stats["cross_validation"] = report["methods"][method.name]
    return stats


def other_crs(request: GriddingRequest) -> dict[str, Any]:
    """The CRS of the run's inputs besides the data (MASK, TEMPLATE), by name: they must be
    the data's; an EXTENT in another CRS is converted to it (:meth:`GridRequest.grid`)."""
    named = {"MASK": request.cells.mask, "TEMPLATE": request.grid.template}
    return {name: getattr(value, "crs", None) for name, value in named.items()
            if value is not None}


def write_dem(run: GridRun, tiles: Any, request: GriddingRequest, feedback: Feedback,
              start: float = 5.0, end: float = 95.0) -> dict:
    """Compute the tiles (locally or on Dask) and write the Float32 GeoTIFF in tile order.

    Returns statistics: cells with a value, nodata cells, summed method counters, executor.
    """
    from toolbox.executor import resolve_executor
    from toolbox.io.raster import nodata_clash_warning, nodata_clashes
    from toolbox.raster.engine import process_raster, tile_count
    from toolbox.raster.writer import RasterWriter

    execution = request.execution
    executor = resolve_executor(execution.scheduler, execution.workers)
    grid = run.grid
    n_tiles = tile_count(grid, run.tile)
    totals: dict[str, Any] = {"valid": 0, "empty_tiles": 0, "counts": None, "clashes": 0}

    def collect(tile, values, counts):
        n_ok = 0 if values is None else int(np.count_nonzero(~np.isnan(values)))
        clashes = nodata_clashes(values, run.nodata, "float32")
        totals["clashes"] += clashes
        n_ok -= clashes  # stored as NODATA: no value in the file
        totals["valid"] += n_ok
        totals["empty_tiles"] += n_ok == 0
        if counts is not None:
            totals["counts"] = counts.copy() if totals["counts"] is None \
                else totals["counts"] + counts

    feedback.push_info(f"{grid.width} x {grid.height} cells in {n_tiles} tiles on "
                       f"{executor.describe()}")
    writer = RasterWriter(request.output, grid, 1, "float32", run.nodata, tile=run.tile,
                          cog=bool(execution.cog), overviews=execution.overviews,
                          band_descriptions=["height (gridded from the points)"])
    with feedback.timed("tiles"), writer:
        process_raster(grid, None, tiles.kernel, writer, tile_size=run.tile, executor=executor,
                       feedback=feedback, plan=tiles.plan, collect=collect, start=start, end=end)
    if totals["clashes"]:
        feedback.push_warning(nodata_clash_warning(totals["clashes"], run.nodata))
    total = grid.width * grid.height
    return {"cells": total, "cells_with_value": totals["valid"],
            "cells_nodata": total - totals["valid"], "tiles": n_tiles,
            "tiles_without_value": totals["empty_tiles"], "executor": executor.describe(),
            "counts": totals["counts"]}


def grid_statistics(run: GridRun, request: GriddingRequest) -> dict:
    """The inputs, duplicates and grid part of STATISTICS."""
    from toolbox.io.crs import crs_label

    data, grid = run.data, run.grid
    return {"inputs": dict(data.counts), "points_used": len(data.xyz),
            "breakline_segments": len(data.segments),
            "duplicates": data.duplicates.as_dict(),
            "grid": {"width": grid.width, "height": grid.height,
                     "cell_size": list(grid.cell_size), "bounds": list(grid.bounds),
                     "crs": crs_label(grid.crs), "nodata": run.nodata,
                     "tile_size": run.tile},
            "limited_to_convex_hull": run.hull is not None,
            "mask": request.cells.mask is not None,
            "max_distance": request.method.max_distance}


def jsonable_options(options: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
            for k, v in options.items()}


def quality_report(method: Any, data: GriddingData, options: dict[str, Any],
                   request: GriddingRequest, feedback: Feedback) -> dict[str, Any]:
    """Leave-one-out report of one method (the shape ``dem:cross_validate`` writes)."""
    from toolbox.io.crs import crs_label
    from toolbox.terrain.gridding.validation import add_worst_point, error_summary, loo_predict

    local = data.local
    predicted, details = loo_predict(method, local, options, request.cells.extrapolate,
                                     data.segments, feedback, request.execution.workers)
    summary = error_summary(predicted, local[:, 2]) | details
    add_worst_point(summary, data.xyz, predicted)
    summary["options"] = jsonable_options(options)
    return {"what": "leave-one-out cross-validation: error = predicted - observed height",
            "crs": crs_label(data.crs), "points": len(local),
            "duplicates": data.duplicates.as_dict(), "methods": {method.name: summary}}


def write_quality(path, report: dict) -> None:
    """Write a JSON quality report."""
    import json

    from toolbox.report import to_jsonable

    path.write_text(json.dumps(to_jsonable(report), indent=2) + "\n")
