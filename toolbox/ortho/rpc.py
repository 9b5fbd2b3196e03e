"""Ortho of a satellite image through its RPC camera (:func:`rpc_orthorectify`).

Per output window: the DEM's heights at the cell centres (:class:`~toolbox.ortho.dem.DemSampler`:
bilinear between DEM cell centres, the edge value held across the outer half cell, a DEM in
another CRS through a checked pyproj lattice), the
cells (grid CRS -> WGS84 lon/lat with pyproj) projected by the RPCs (exact at every cell:
:meth:`toolbox.cameras.rpc.RpcCamera.project`), the image resampled there by the warp engine
(:func:`toolbox.raster.warp.warp_to_geotiff`). The default grid covers the image's outline
projected on the DEM's lowest and highest heights; the default cell is the image's ground
sample distance at its centre (2 significant digits).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.ortho.metrics import TileStatistics, nice_cell_size
from toolbox.ortho.windows import leaf_window_totals
from toolbox.raster.maps import WindowResults

OUTLINE_STEP_PX = 16  # image pixels between the projected points of the outline


def rpc_extent(camera: Any, low: float, high: float) -> tuple[float, float, float, float]:
    """Bounds (camera CRS) of the image outline projected on the heights ``low`` and ``high``."""
    w, h = camera.image_size
    n = int(min(1024, max(8, math.ceil(max(w, h) / OUTLINE_STEP_PX)))) + 1
    t = np.linspace(0.0, 1.0, n)
    outline = np.vstack([np.column_stack([t * w, np.zeros(n)]),
                         np.column_stack([np.full(n, w), t * h]),
                         np.column_stack([t * w, np.full(n, h)]),
                         np.column_stack([np.zeros(n), t * h])])
    ground = np.vstack([camera.pixel_to_ground(outline, z) for z in (low, high)])
    ok = np.isfinite(ground).all(axis=1)
    if ok.sum() < 4:
        raise InputDataError("the RPC image's outline does not meet the DEM's heights "
                             f"({low:.1f} .. {high:.1f}): wrong DEM or RPCs")
    g = ground[ok]
    return float(g[:, 0].min()), float(g[:, 1].min()), float(g[:, 0].max()), float(g[:, 1].max())


def rpc_gsd(camera: Any, height: float) -> float:
    """Ground distance of one image pixel at the image centre and ``height`` (mean of the
    column and row steps; camera CRS units)."""
    w, h = camera.image_size
    px = np.array([[w / 2, h / 2], [w / 2 + 1, h / 2], [w / 2, h / 2 + 1]])
    g = camera.pixel_to_ground(px, height)
    gsd = 0.5 * (np.hypot(*(g[1, :2] - g[0, :2])) + np.hypot(*(g[2, :2] - g[0, :2])))
    if not math.isfinite(gsd) or gsd <= 0:
        raise InputDataError("the RPC camera has no ground sample distance at its image centre")
    return float(gsd)


class RpcOrthoMap(WindowResults):
    """The warp's coordinate map: output window -> image pixels through the RPC camera, with the
    counts of cells without a DEM height or outside the image (a
    :class:`~toolbox.raster.maps.WindowResults`: they come back from a Dask worker with each
    tile)."""

    def __init__(self, camera: Any, grid: Any, sampler: Any):
        self.camera, self.grid, self.sampler = camera, grid, sampler
        WindowResults.__init__(self)

    def __call__(self, tile: Any, aux: Any = None) -> tuple[np.ndarray, np.ndarray]:
        from toolbox.ortho.windows import project_cells

        window = getattr(tile, "window", tile)
        xs, ys = self.grid.cell_centers(window)
        z = self.sampler.heights(xs, ys)
        gx = np.broadcast_to(xs[None, :], z.shape)
        gy = np.broadcast_to(ys[:, None], z.shape)
        cols, rows, box = project_cells(self.camera, gx, gy, z)
        w, h = self.camera.image_size
        inside = (cols >= 0) & (cols <= w) & (rows >= 0) & (rows <= h)
        nan_z = np.isnan(z)
        stats = TileStatistics(cells=z.size, outside_dem=int(nan_z.sum()),
                               outside_photo=int((~inside & ~nan_z).sum()))
        self.record(window, stats)
        return cols, rows

    def totals(self) -> TileStatistics:
        """Sums over the windows, without the parents of windows the warp split in four."""
        return leaf_window_totals(self.window_results())


def rpc_plan(camera: Any, dem: Any, band: int = 1, cell: float | None = None,
             bounds: tuple[float, float, float, float] | None = None,
             origin: tuple[float, float] = (0.0, 0.0)) -> tuple[Any, float]:
    """The output grid (camera CRS) and the image's GSD at the DEM's mean height."""
    from toolbox.ortho.plan import lattice_grid
    from toolbox.photogrammetry.surface import dem_height_range

    if camera.crs is None:
        raise InputDataError("an RPC ortho needs a projected CRS for its grid")
    low, high = dem_height_range(dem, band)
    gsd = rpc_gsd(camera, 0.5 * (low + high))
    cell = nice_cell_size(gsd) if cell is None else float(cell)
    extent = rpc_extent(camera, low, high) if bounds is None else bounds
    return lattice_grid(extent, cell, camera.crs, origin), gsd


def rpc_orthorectify(camera: Any, image: Any, dem: Any, grid: Any, output: Any,
                     options: Any = None, feedback: Any = None,
                     executor: Any = None) -> dict[str, Any]:
    """Orthorectify the RPC image ``image`` (RasterInfo) on ``dem`` onto ``grid`` (the camera's
    CRS) into the GeoTIFF ``output``; ``options`` an :class:`~toolbox.ortho.run.OrthoOptions`
    (resampling, outside, nodata, band, dem_factor, chunk, overviews, cog). Returns the
    report."""
    from toolbox.feedback import Feedback
    from toolbox.io.crs import crs_label
    from toolbox.ortho.dem import DemSampler
    from toolbox.ortho.run import OrthoOptions
    from toolbox.raster.warp import warp_to_geotiff

    options = options or OrthoOptions()
    feedback = feedback or Feedback()
    if tuple(camera.image_size) != (image.width, image.height):
        raise InputDataError(f"the RPC camera is {camera.image_size[0]} x "
                             f"{camera.image_size[1]} px but the image {image} is "
                             f"{image.width} x {image.height}")
    sampler = DemSampler(dem, grid.crs, options.band, options.dem_factor)
    sampler.preload(grid.bounds)
    datums = _transformations(dem, grid, sampler, feedback)
    cmap = RpcOrthoMap(camera, grid, sampler)
    with feedback.timed("orthorectify"):
        warp = warp_to_geotiff(image.path, cmap, grid, output, options.resampling,
                               options.outside, options.nodata, chunk=options.chunk or 1024,
                               overviews=options.overviews, cog=options.cog,
                               feedback=feedback.step(0, 100),
                               tags={"ORTHO_CAMERA": "rpc",
                                     "ORTHO_RESAMPLING": options.resampling},
                               executor=executor)
    totals = cmap.totals()
    cells = max(totals.cells, 1)
    report = {"image": str(image.path), "camera": "rpc", "crs": crs_label(grid.crs),
              "cell_size": grid.cell_size[0], "width": grid.width, "height": grid.height,
              "bounds": list(grid.bounds), "cells": totals.cells,
              "outside_dem_fraction": totals.outside_dem / cells,
              "outside_photo_fraction": totals.outside_photo / cells,
              "resampling": options.resampling, "dem_factor": options.dem_factor,
              "warp": warp.as_dict()}
    if datums:
        report["transformations"] = datums
    if totals.outside_dem:
        feedback.push_warning(f"{totals.outside_dem} of {totals.cells} cells "
                              f"({100 * totals.outside_dem / cells:.1f} %) have no DEM height "
                              "and are left empty")
    return report


def has_rpc(path: Any) -> bool:
    """True when GDAL finds RPCs for the raster (GeoTIFF tags, .RPB, _RPC.TXT)."""
    import warnings

    import rasterio

    from toolbox.io.gdal_errors import handled_gdal_errors

    with handled_gdal_errors(rasterio.errors.RasterioIOError), warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path) as src:
            return src.rpcs is not None
    return False


def rpc_crs(crs: Any, dem: Any) -> Any:
    """The RPC ortho's CRS: ``crs``, else the DEM's horizontal CRS when projected."""
    from toolbox.errors import ParameterError
    from toolbox.ortho.vertical import horizontal_part

    if crs is not None:
        if not horizontal_part(crs).is_projected:
            raise ParameterError("CRS", f"must be a projected CRS for an RPC ortho, got "
                                 f"{crs.name!r}")
        return horizontal_part(crs)
    if dem.crs is not None and horizontal_part(dem.crs).is_projected:
        return horizontal_part(dem.crs)
    raise InputDataError("an RPC ortho needs CRS (the DEM's CRS is not projected)")


def gcp_pairs(image_id: str, measurements: tuple, control: tuple, single: bool = True
              ) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Ids, ground (n, 3) and pixels (n, 2) of the control points measured on ``image_id``
    (rows whose ``photo`` is the image's file name or stem; with ``single``, every row when the
    table names a single photo: one image's GCPs). ``measurements``:
    :func:`~toolbox.photogrammetry.tables.image_measurements`
    in pixels; ``control``: :func:`~toolbox.photogrammetry.tables.ground_points`."""
    ids, photos, xy, kind = measurements
    if kind != "pixel":
        raise InputDataError("MEASUREMENTS: an RPC image's GCPs are measured in pixels "
                             "(col_px, row_px), not image mm")
    names = {image_id, image_id.rsplit(".", 1)[0]}
    rows = [k for k, p in enumerate(photos) if p in names]
    if not rows and single and len(set(photos)) == 1:
        rows = list(range(len(photos)))
    known = dict(zip(control[0], control[1], strict=True))
    pairs = [(ids[k], known[ids[k]], xy[k]) for k in rows
             if ids[k] in known and control[2][control[0].index(ids[k])] == "control"]
    if not pairs:
        raise InputDataError(f"MEASUREMENTS: no control point of CONTROL is measured on "
                             f"'{image_id}'")
    return ([p[0] for p in pairs], np.array([p[1] for p in pairs]),
            np.array([p[2] for p in pairs]))


def _transformations(dem: Any, grid: Any, sampler: Any, feedback: Any) -> list:
    """The datum transformations of an RPC ortho: its cells to the RPCs' WGS 84 longitude and
    latitude, the DEM's to the grid's CRS (:func:`toolbox.io.crs.note_transformation`; warned
    when coarser than the cell, of unknown accuracy or when a better one lacks its grid)."""
    from toolbox.io.crs import note_transformation

    cell = float(min(abs(grid.cell_size[0]), abs(grid.cell_size[1])))
    found = [note_transformation(feedback, grid.crs, "EPSG:4326", grid.bounds, cell,
                                 "the RPC ortho's cells (to the RPCs' WGS 84)")]
    if sampler.transformer is not None:
        dem_cell = float(min(abs(dem.transform.a), abs(dem.transform.e)))
        found.append(note_transformation(feedback, grid.crs, dem.crs, grid.bounds, dem_cell,
                                         "the DEM's positions (to the ortho's CRS)"))
    return [f for f in found if f is not None]
