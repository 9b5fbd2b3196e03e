"""One ``dem:ground`` run: read points (or DSM cells), SMRF ground filter
(:mod:`toolbox.terrain.ground`), grid the ground points by a dem:* method, write the
non-ground mask on the DTM's grid and optionally the classified points."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.terrain.gridding.request import GriddingRequest
from toolbox.terrain.ground import GroundFilter, smrf

MASK_NODATA = 255
HEIGHTS_NODATA = -9999.0


@dataclass(frozen=True)
class GroundRequest:
    """One ``dem:ground`` run.

    ``gridding``: the points (``sources.points``; unused with ``dsm``), the DTM's grid (none
    asked: the DSM's grid, or ``filter.cell`` over the points' bounds), the gridding options
    and the DTM ``output``; ``method``: tin_linear, idw or nearest; ``dsm``: a raster
    (:class:`toolbox.io.raster.RasterInfo`) read instead of points, whose cells set
    ``filter.cell``; ``nonground``: the mask GeoTIFF; ``ground_points``: LAS/LAZ of the
    classified points (optional); ``heights``: GeoTIFF of the height above the DTM (optional).
    """

    gridding: GriddingRequest
    filter: GroundFilter
    nonground: Path
    method: str = "tin_linear"
    dsm: Any = None
    ground_points: Path | None = None
    heights: Path | None = None


def read_dsm_points(info: Any) -> tuple[np.ndarray, float]:
    """(N, 3) cell centres and heights of the valid cells of a DSM (band 1); the cell size."""
    import rasterio

    t = info.transform
    if t.b != 0 or t.d != 0 or not np.isclose(abs(t.a), abs(t.e)):
        raise InputDataError(f"DSM {info.path.name} must be north-up with square cells, got "
                             f"cell {abs(t.a):g} x {abs(t.e):g}")
    from toolbox.io.raster import read_filled

    with rasterio.open(info.path) as ds:  # any band type: integer DSMs too
        z = read_filled(ds, 1)
    rows, cols = np.nonzero(np.isfinite(z))
    if len(rows) < 3:
        raise InputDataError(f"DSM {info.path.name} has fewer than 3 valid cells")
    x = t.c + (cols + 0.5) * t.a
    y = t.f + (rows + 0.5) * t.e
    return np.column_stack([x, y, z[rows, cols]]), abs(t.a)


def nonground_mask(xyz: np.ndarray, ground: np.ndarray, transform: Any, width: int,
                   height: int) -> np.ndarray:
    """UInt8 (height, width): 1 where a cell holds a non-ground point, 0 only ground, 255 none."""
    cols = np.floor((xyz[:, 0] - transform.c) / transform.a).astype(np.int64)  # north-up
    rows = np.floor((xyz[:, 1] - transform.f) / transform.e).astype(np.int64)
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    flat = rows[inside] * width + cols[inside]
    seen = np.bincount(flat, minlength=width * height) > 0
    objects = np.bincount(flat, weights=(~ground[inside]).astype(np.float64),
                          minlength=width * height) > 0
    mask = np.full(width * height, MASK_NODATA, dtype=np.uint8)
    mask[seen] = 0
    mask[objects] = 1
    return mask.reshape(height, width)


def heights_above(xyz: np.ndarray, dtm: np.ndarray, transform: Any) -> np.ndarray:
    """(rows, cols) float32: the highest point of each cell of a north-up grid minus the DTM
    there; NaN where no point fell or the DTM has no value."""
    rows_n, cols_n = dtm.shape
    cols = np.floor((xyz[:, 0] - transform.c) / transform.a).astype(np.int64)
    rows = np.floor((xyz[:, 1] - transform.f) / transform.e).astype(np.int64)
    inside = (cols >= 0) & (cols < cols_n) & (rows >= 0) & (rows < rows_n)
    top = np.full(rows_n * cols_n, -np.inf)
    np.maximum.at(top, rows[inside] * cols_n + cols[inside], xyz[inside, 2])
    top[~np.isfinite(top)] = np.nan
    return (top.reshape(rows_n, cols_n) - dtm).astype(np.float32)


def run_ground(request: GroundRequest, feedback: Feedback) -> dict[str, Any]:
    """Filter, grid, write the DTM, the mask, the heights above it (and the classified points);
    returns STATISTICS."""
    import rasterio

    from toolbox.io.crs import common_crs, crs_label
    from toolbox.raster.writer import RasterWriter
    from toolbox.terrain.gridding.inputs import check_heights_fit, merge_points
    from toolbox.terrain.gridding.methods import METHODS
    from toolbox.terrain.gridding.run import grid_dem, other_crs
    from toolbox.terrain.points import local_origin, read_mass_points

    gridding, sources = request.gridding, request.gridding.sources
    grid = gridding.grid
    cloud = None
    with feedback.timed("read"):
        if request.dsm is not None:
            info = request.dsm
            crs = common_crs({"DSM": info.crs, **other_crs(gridding)}, sources.crs)
            xyz, cell = read_dsm_points(info)
            if grid.cell_size is None and grid.template is None:
                grid = replace(grid, template=info)
        else:
            crs = common_crs({"INPUT": sources.points.crs, **other_crs(gridding)}, sources.crs)
            xyz, cloud = read_mass_points(sources.points, sources.z_field, sources.classes,
                                          sources.returns, sources.crs)
            cell = float(request.filter.cell)
            if grid.cell_size is None and grid.template is None:
                grid = replace(grid, cell_size=cell)
    check_heights_fit(xyz[:, 2], "DSM" if request.dsm is not None else "INPUT")
    gridding = replace(gridding, grid=grid)
    flt = replace(request.filter, cell=cell)
    origin = local_origin(xyz)
    local = xyz.copy()
    local[:, :2] -= origin
    span = np.ptp(local[:, :2], axis=0) / cell
    radii = flt.max_window / cell  # the openings' largest radius, cells: the grid's padding
    if radii > span.max() + 2:
        raise ParameterError("MAX_WINDOW", f"{flt.max_window:g} is {radii:,.0f} filter cells "
                             f"of {cell:g}, wider than the data ({span[0]:,.0f} x "
                             f"{span[1]:,.0f} cells): objects cannot be wider than the area; "
                             "use a MAX_WINDOW of about half the widest building or tree group")
    limit = int(grid.max_cells or 1e9)
    cells = (span[0] + 2 + 2 * radii) * (span[1] + 2 + 2 * radii)
    if cells > limit:
        raise InputDataError(f"the filter grid would have {cells:,.0f} cells with its border "
                             f"(over MAX_CELLS {limit:,}): use a larger FILTER_CELL")
    feedback.set_progress(5, "ground filter")
    with feedback.timed("filter"):
        try:
            result = smrf(local, flt)
        except ValueError as exc:
            raise InputDataError(f"ground filter: {exc}") from None
    ground = result.ground
    n_ground = int(ground.sum())
    if n_ground < 3:
        raise InputDataError(f"only {n_ground} of {len(xyz)} points are ground: raise "
                             "ELEVATION_THRESHOLD or SLOPE")
    feedback.push_info(f"{n_ground} of {len(xyz)} points are ground")
    feedback.set_progress(30, "gridding the ground points")
    counts = {"points": len(xyz), "ground_points": n_ground}
    if cloud is not None:
        counts["point_cloud"] = cloud
    data = merge_points(xyz[ground], np.zeros((0, 2), dtype=np.int64), crs, counts, "mean", 0.0,
                        feedback)
    stats = grid_dem(METHODS[request.method], gridding, feedback.step(30, 90), data)
    with rasterio.open(gridding.output) as ds:
        transform, width, height = ds.transform, ds.width, ds.height
        grid = _grid_spec(transform, width, height, crs)
    mask = nonground_mask(xyz, ground, transform, width, height)
    with RasterWriter(request.nonground, grid, 1, "uint8", MASK_NODATA,
                      band_descriptions=["non-ground (1 a non-ground point in the cell, "
                                         "0 only ground points, 255 no point)"],
                      tile=int(gridding.execution.tile_size),
                      overviews=gridding.execution.overviews) as writer:
        from rasterio.windows import Window

        writer.write(Window(0, 0, width, height), mask)
    if request.heights is not None:
        from toolbox.io.raster import read_filled

        with rasterio.open(gridding.output) as ds:
            dtm = read_filled(ds, 1)
        heights = heights_above(xyz, dtm, transform)
        with RasterWriter(request.heights, grid, 1, "float32", HEIGHTS_NODATA,
                          band_descriptions=["height above the ground (DTM)"],
                          tile=int(gridding.execution.tile_size),
                          overviews=gridding.execution.overviews) as writer:
            from rasterio.windows import Window

            writer.write(Window(0, 0, width, height),
                         np.where(np.isfinite(heights), heights, HEIGHTS_NODATA))
    if request.ground_points is not None:
        from toolbox.io.pointcloud import (
            PointCloudRef,
            cloud_filter,
            write_classified_copy,
            write_point_cloud,
        )

        codes = np.where(ground, 2, 1)
        if isinstance(sources.points, PointCloudRef):  # every dimension kept, and the true Z
            kept = cloud_filter(sources.points, sources.classes, sources.returns, sources.crs)
            write_classified_copy(sources.points, kept, request.ground_points, codes, crs)
        else:
            write_point_cloud(request.ground_points, xyz, crs, classification=codes)
    occupied = np.isfinite(result.surface.z)
    stats["ground_filter"] = {
        "method": "SMRF (Pingel et al. 2013), square windows", "filter_cell": cell,
        "slope": flt.slope, "max_window": flt.max_window, "radii_cells": len(flt.radii),
        "elevation_threshold": flt.elevation_threshold,
        "elevation_scalar": flt.elevation_scalar, "points": len(xyz), "ground": n_ground,
        "nonground": len(xyz) - n_ground,
        # of the filter cells holding points (the empty ones, flagged so that the provisional
        # DTM is filled from ground cells, are no objects: a survey's gaps read as buildings)
        "object_cells_fraction": float(result.objects[occupied].mean()) if occupied.any()
        else 0.0, "empty_cells_fraction": float(1.0 - occupied.mean()),
        "crs": crs_label(crs),
        "mask_cells_nonground": int((mask == 1).sum())}
    return stats


def _grid_spec(transform: Any, width: int, height: int, crs: Any):
    from toolbox.io.grid import GridSpec

    return GridSpec(transform, width, height, crs)
