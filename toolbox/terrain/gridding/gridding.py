"""Shared machinery of the DEM gridding algorithms: output grid, tiles, GeoTIFF writing (the
input data are read by :mod:`toolbox.terrain.gridding.inputs`).

Data flow (one run)::

    INPUT points + LINES vertices + BREAKLINES vertices   (CRS checked, NaN/inf refused)
      -> duplicate XY merged (DUPLICATES rule, reported)
      -> shifted to a local origin
      -> output grid (CELL_SIZE + EXTENT snapped, or TEMPLATE)       size guard before any array
      -> tiles of TILE_SIZE cells: cells to compute (convex hull, MASK), the points each tile
         needs (a halo from the global neighbour index) -> one picklable TileTask per tile
      -> tasks run on local threads or on a Dask cluster (toolbox.tiles.map_tiles)
      -> results written window by window, in tile order (same bytes either way)

Kernels (the method modules) see only local-coordinate numpy arrays.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.io.grid import GridSpec, max_cells_default
from toolbox.parameters import (
    Boolean,
    ExtentParameter,
    Integer,
    Number,
    Output,
    OutputFile,
    OutputRaster,
    RasterLayer,
    String,
    VectorLayer,
)
from toolbox.terrain.gridding.inputs import GriddingData
from toolbox.terrain.gridding.masks import convex_hull, hull_mask, polygon_mask
from toolbox.terrain.gridding.neighbours import PointBins

DEFAULT_NODATA = -9999.0
DEFAULT_TILE = 512
GDAL_CACHE_MB = 256


# -- parameters -----------------------------------------------------------------------------------
def grid_parameters() -> list:
    """The output grid and which cells get a value."""
    return [
        Number("CELL_SIZE", "cell size, CRS units (not with TEMPLATE)", optional=True,
               min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "output extent 'xmin,ymin,xmax,ymax', snapped outwards to the "
                        "cell size (default: the data's bounds)", optional=True),
        RasterLayer("TEMPLATE", "raster whose grid the output takes (origin, cell size, and its "
                    "extent unless EXTENT is given)", optional=True),
        Number("NODATA", "value of cells without a height", default=DEFAULT_NODATA),
        Number("MAX_DISTANCE", "cells whose nearest data point is farther than this stay nodata "
               "(CRS units; default: no limit)", optional=True, min_value=0, min_exclusive=True),
        VectorLayer("MASK", "polygons: cells whose centre is outside stay nodata",
                    geometry_types=["polygon"], optional=True),
        Boolean("EXTRAPOLATE", "also compute cells outside the data's convex hull (not for "
                "dem:tin_linear)", default=False),
        Integer("MAX_CELLS", "refuse outputs with more cells than this (default: "
                "TOOLBOX_MAX_CELLS or 1e9)", optional=True, min_value=1),
    ]


def execution_parameters() -> list:
    """Tiling, executor, outputs."""
    return [
        Integer("TILE_SIZE", "tile side in cells (a multiple of 16; also the GeoTIFF block)",
                default=DEFAULT_TILE, min_value=16, max_value=4096),
        String("SCHEDULER", "Dask scheduler address (tcp://host:8786) to run the tiles on a "
               "cluster; default: DASK_SCHEDULER_ADDRESS if set, else local threads ('local' "
               "forces local threads)", optional=True),
        Integer("WORKERS", "local threads (default: the CPUs available)", optional=True,
                min_value=1),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        OutputRaster("OUTPUT", "DEM GeoTIFF (Float32, tiled, DEFLATE)"),
        OutputFile("QUALITY", "JSON quality report: leave-one-out cross-validation of this "
                   "method on the input points (RMSE, mean and max error)", extensions=[".json"],
                   optional=True),
    ]


STATISTICS = Output("STATISTICS", "inputs, duplicates, grid, cells, fallbacks, timings", "dict")


# -- checks ---------------------------------------------------------------------------------------
def check_grid(alg: Algorithm, params: dict) -> None:
    """CELL_SIZE xor TEMPLATE, tile size, and the size guard when the extent is known now."""
    cell, template = params.get("CELL_SIZE"), params.get("TEMPLATE")
    if cell is None and template is None:
        raise alg.fail("CELL_SIZE", "is required (a cell size in CRS units), unless a TEMPLATE "
                       "raster gives the grid")
    if cell is not None and template is not None:
        raise alg.fail("CELL_SIZE", f"must not be given with TEMPLATE (the template's cells are "
                       f"used), got {cell:g}")
    if params.get("TILE_SIZE", DEFAULT_TILE) % 16:
        raise alg.fail("TILE_SIZE", f"must be a multiple of 16 (GeoTIFF blocks), got "
                       f"{params['TILE_SIZE']}")
    if template is not None or params.get("EXTENT") is not None:
        output_grid(params, None, None)  # size guard before reading any data


# -- output grid ----------------------------------------------------------------------------------
def output_grid(params: dict, data: GriddingData | None, crs: Any) -> GridSpec:
    """The output grid: TEMPLATE's (optionally cut to EXTENT on its lattice), or CELL_SIZE over
    EXTENT / the data bounds, snapped to multiples of the cell size. Raises ParameterError over
    MAX_CELLS before anything is allocated."""
    from affine import Affine

    limit = params.get("MAX_CELLS") or max_cells_default()
    extent = params.get("EXTENT")
    template = params.get("TEMPLATE")
    if template is not None:
        t = template.transform
        if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
            raise ParameterError("TEMPLATE", f"must be a north-up raster without rotation, "
                                 f"{template} has transform {tuple(t)[:6]}")
        if extent is None:
            width, height = template.width, template.height
            transform = t
        else:
            cx, cy = t.a, -t.e
            xmin = t.c + math.floor((extent.xmin - t.c) / cx + 1e-9) * cx
            xmax = t.c + math.ceil((extent.xmax - t.c) / cx - 1e-9) * cx
            ymax = t.f - math.floor((t.f - extent.ymax) / cy + 1e-9) * cy
            ymin = t.f - math.ceil((t.f - extent.ymin) / cy - 1e-9) * cy
            width = max(1, int(round((xmax - xmin) / cx)))
            height = max(1, int(round((ymax - ymin) / cy)))
            transform = Affine(cx, 0.0, xmin, 0.0, -cy, ymax)
        if width * height > limit:
            raise ParameterError("TEMPLATE", f"gives a {width} x {height} grid "
                                 f"({width * height:,} cells), over the limit of {limit:,} "
                                 "cells (MAX_CELLS or TOOLBOX_MAX_CELLS)")
        return GridSpec(transform, width, height, crs)
    bounds = extent.bounds if extent is not None else (None if data is None else data.bounds)
    if bounds is None:
        raise ParameterError("EXTENT", "is needed to size the grid before reading the data")
    return GridSpec.from_bounds(bounds, params["CELL_SIZE"], crs, snap=True, max_cells=limit)


# -- tiles ----------------------------------------------------------------------------------------
@dataclass
class TileTask:
    """Everything one tile needs; picklable (numpy arrays, a module-level function).

    ``xs`` / ``ys`` are the local x of the column centres and y of the row centres; ``mask``
    (h, w) marks the cells to compute; ``xyz`` (m, 3) the local points the tile needs;
    ``extra`` method data (e.g. triangles); ``options`` the method's keyword arguments.
    """

    index: int
    function: Callable | None
    xs: np.ndarray
    ys: np.ndarray
    mask: np.ndarray | None
    xyz: np.ndarray | None
    options: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.ys), len(self.xs))


@dataclass
class TileResult:
    """Float32 heights (NaN = nodata) and the method's counters (e.g. polynomial orders)."""

    values: np.ndarray
    counts: np.ndarray | None = None


def compute_tile(task: TileTask) -> TileResult:
    """Run one tile (on a local thread or a Dask worker)."""
    if task.function is None or task.mask is None or not task.mask.any():
        return TileResult(np.full(task.shape, np.nan, dtype="float32"))
    values, counts = task.function(task)
    return TileResult(values.astype("float32"), counts)


class NeighbourPlanner:
    """Chooses the points a tile needs for k-nearest-neighbour methods.

    For a tile whose computed cells span the box B, every cell's k nearest points lie within
    ``halo`` of B, where ``halo = max d_k(s) + spacing·√2/2`` over sample centres s laid every
    ``spacing`` over B (``d_k`` is 1-Lipschitz); with a search radius, ``halo <= radius``.
    """

    def __init__(self, local_xyz: np.ndarray, k: int, radius: float | None,
                 bins: PointBins | None = None):
        self.xyz = local_xyz
        self.bins = bins if bins is not None else PointBins.build(local_xyz[:, :2])
        self.k = max(0, int(k))  # 0: every point within the radius
        self.radius = math.inf if radius is None else float(radius)

    def halo(self, x0: float, y0: float, x1: float, y1: float, cell: float) -> float:
        if self.k == 0 or self.k >= len(self.xyz):
            return self.radius
        steps = 8
        sx = np.linspace(x0, x1, steps + 1)
        sy = np.linspace(y0, y1, steps + 1)
        gx, gy = np.meshgrid(sx, sy)
        d2, _ = self.bins.query(gx.ravel(), gy.ravel(), self.k)
        reach = float(np.sqrt(d2[:, -1].max()))
        spacing = math.hypot((x1 - x0) / steps, (y1 - y0) / steps)
        halo = reach + 0.5 * spacing + 1e-6 * max(cell, 1.0)
        return min(halo, self.radius)

    def payload(self, x0: float, y0: float, x1: float, y1: float, cell: float) -> np.ndarray:
        h = self.halo(x0, y0, x1, y1, cell)
        if not math.isfinite(h):
            return self.xyz
        return self.xyz[self.bins.in_rect(x0 - h, y0 - h, x1 + h, y1 + h)]


@dataclass
class GridRun:
    """One gridding run: data, grid, cell selection and the executor."""

    data: GriddingData
    grid: GridSpec
    tile: int
    hull: np.ndarray | None  # local convex hull ring, None = no hull limit
    mask_geometry: Any  # shapely (multi)polygon in map coordinates, or None
    nodata: float

    def windows(self):
        from toolbox.io.raster import iter_windows

        return list(iter_windows(self.grid.width, self.grid.height, self.tile))

    def centres(self, window) -> tuple[np.ndarray, np.ndarray]:
        t = self.grid.transform
        ox, oy = self.data.origin
        xs = (t.c - ox) + (np.arange(window.col_off, window.col_off + window.width) + 0.5) * t.a
        ys = (t.f - oy) + (np.arange(window.row_off, window.row_off + window.height) + 0.5) * t.e
        return xs, ys

    def cell_mask(self, window, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        mask = np.ones((len(ys), len(xs)), dtype=bool)
        if self.hull is not None:
            tol = 1e-9 * max(self.grid.cell_size)
            mask &= hull_mask(self.hull, xs, ys, tol)
        if self.mask_geometry is not None and mask.any():
            from affine import Affine

            t = self.grid.transform
            window_transform = Affine(t.a, 0.0, t.c + window.col_off * t.a, 0.0, t.e,
                                      t.f + window.row_off * t.e)
            mask &= polygon_mask(self.mask_geometry, window_transform, mask.shape)
        return mask


def prepare_run(params: dict, data: GriddingData, feedback: Feedback,
                use_hull: bool = True) -> GridRun:
    """Grid, hull and mask of a run (after :func:`read_sources`)."""
    grid = output_grid(params, data, data.crs)
    hull = None
    if use_hull and not params.get("EXTRAPOLATE", False):
        from toolbox.terrain.points import check_not_collinear

        try:
            check_not_collinear(data.local[:, :2], "data points (after merging duplicate XY)")
        except ValueError as exc:
            hint = " (set EXTRAPOLATE to compute cells beyond their hull)" \
                if "collinear" in str(exc) else ""
            raise InputDataError(f"{exc}{hint}") from None
        hull = convex_hull(data.local[:, :2])
        if hull is None:
            raise InputDataError(f"the {len(data.xyz)} data points are collinear: their convex "
                                 "hull has no area and every cell would be nodata (set "
                                 "EXTRAPOLATE to compute cells beyond the hull)")
    mask_geometry = None
    if params.get("MASK") is not None:
        from shapely import union_all

        from toolbox.io.vector import read_vector

        frame = read_vector(params["MASK"], name="MASK")
        mask_geometry = union_all(frame.geometry.values)
    return GridRun(data, grid, int(params.get("TILE_SIZE") or DEFAULT_TILE), hull, mask_geometry,
                   float(params.get("NODATA", DEFAULT_NODATA)))


def neighbour_tasks(run: GridRun, function: Callable, options: dict, k: int,
                    radius: float | None) -> Iterator[TileTask]:
    """One TileTask per tile for a k-nearest-neighbour method (lazy: tiles are planned as the
    executor asks for them)."""
    planner = NeighbourPlanner(run.data.local, k, radius, run.data.bins)
    cell = max(run.grid.cell_size)
    for index, tw in enumerate(run.windows()):
        xs, ys = run.centres(tw.core)
        mask = run.cell_mask(tw.core, xs, ys)
        if not mask.any():
            yield TileTask(index, None, xs, ys, None, None)
            continue
        rows = np.flatnonzero(mask.any(axis=1))
        cols = np.flatnonzero(mask.any(axis=0))
        x0, x1 = sorted((xs[cols[0]], xs[cols[-1]]))
        y0, y1 = sorted((ys[rows[0]], ys[rows[-1]]))
        xyz = planner.payload(x0, y0, x1, y1, cell)
        yield TileTask(index, function, xs, ys, mask, np.ascontiguousarray(xyz), dict(options))


def write_tiles(run: GridRun, tasks: Iterator[TileTask], params: dict, feedback: Feedback,
                start: float = 5.0, end: float = 95.0) -> dict:
    """Compute the tasks (locally or on Dask) and write the GeoTIFF in tile order.

    Returns statistics: cells with a value, nodata cells, summed method counters, executor.
    """
    import rasterio

    from toolbox.io.raster import build_overviews, geotiff_profile
    from toolbox.tiles import map_tiles, resolve_executor

    executor = resolve_executor(params.get("SCHEDULER"), params.get("WORKERS"))
    grid = run.grid
    windows = run.windows()
    profile = geotiff_profile(grid.width, grid.height, 1, "float32", grid.crs, grid.transform,
                              nodata=run.nodata, block=run.tile)
    valid = 0
    counts = None
    empty_tiles = 0
    feedback.push_info(f"{grid.width} x {grid.height} cells in {len(windows)} tiles on "
                       f"{executor.describe()}")
    # a bounded GDAL block cache keeps the writer's memory small for any output size
    with rasterio.Env(COMPRESS_OVERVIEW="DEFLATE", PREDICTOR_OVERVIEW=3,
                      GDAL_CACHEMAX=GDAL_CACHE_MB), \
            rasterio.open(params["OUTPUT"], "w", **profile) as dst:
        with feedback.timed("tiles"):
            results = map_tiles(compute_tile, tasks, executor=executor, feedback=feedback,
                                total=len(windows), start=start, end=end)
            for tw, result in zip(windows, results, strict=True):
                values = result.values
                ok = ~np.isnan(values)
                n_ok = int(ok.sum())
                valid += n_ok
                empty_tiles += n_ok == 0
                if result.counts is not None:
                    counts = result.counts.copy() if counts is None else counts + result.counts
                out = np.where(ok, values, np.float32(run.nodata)).astype("float32")
                dst.write(out, 1, window=tw.core)
        if params.get("OVERVIEWS", True):
            with feedback.timed("overviews"):
                build_overviews(dst)
    total = grid.width * grid.height
    return {"cells": total, "cells_with_value": valid, "cells_nodata": total - valid,
            "tiles": len(windows), "tiles_without_value": empty_tiles,
            "executor": executor.describe(), "counts": counts}


def grid_statistics(run: GridRun, params: dict) -> dict:
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
            "mask": params.get("MASK") is not None,
            "max_distance": params.get("MAX_DISTANCE")}


def write_quality(path, report: dict) -> None:
    """Write a JSON quality report."""
    import json

    from toolbox.report import to_jsonable

    path.write_text(json.dumps(to_jsonable(report), indent=2) + "\n")
