"""One photo orthorectified into a GeoTIFF (:func:`orthorectify`): the options, the auxiliary
rasters, the engine's warp of :class:`~toolbox.ortho.windows.OrthoWindows` and the report."""

from __future__ import annotations

import math
import warnings
from contextlib import ExitStack
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.ortho.codes import DEFAULT_BLOCK, DEFAULT_TOLERANCE_PX
from toolbox.ortho.dem import DemSampler
from toolbox.ortho.metrics import expected_accuracy, ground_sample_distance
from toolbox.ortho.plan import orientation_transformer, photo_surface
from toolbox.ortho.windows import OrthoWindows


@dataclass
class OrthoOptions:
    """How :func:`orthorectify` works (see ``ortho:photo``'s help)."""

    resampling: str = "bilinear"
    outside: str = "alpha"
    nodata: float | None = None
    block: int = DEFAULT_BLOCK
    tolerance_px: float = DEFAULT_TOLERANCE_PX
    dem_factor: int = 1
    band: int = 1
    occlusion: bool = False
    chunk: int | None = None  # output window side; None: 1024, 512 on the NumPy path
    overviews: bool = True
    cog: bool = False
    compiled: bool | None = None  # numba's kernels for a camera model; None: if loaded


def use_compiled() -> bool:
    """Whether a camera model's ortho maps with numba's kernels: only when
    they are loaded in this process already. NumPy's map (:mod:`toolbox.ortho.grid_numpy`)
    spares numba's start-up (0.8 s CPU, 120 MB) and measured as fast on the 4 x 27 M cells of
    the NGI 1 m bench (12.6-12.9 CPU s either way), with 150 MB less peak memory."""
    import sys

    return "toolbox.cameras.kernels" in sys.modules


def orthorectify(photo: Any, image: Any, dem: Any, grid: Any, output: Any,
                 options: OrthoOptions | None = None, surface: Any = None,
                 reference_height: float | None = None, mask_output: Any = None,
                 incidence_output: Any = None, map_scale: float | None = None,
                 feedback: Any = None, executor: Any = None) -> dict[str, Any]:
    """Orthorectify one photo onto ``grid`` and write ``output`` (GeoTIFF, or COG).

    Parameters
    ----------
    photo : Photo
        Oriented, with a pixel transform; its image size must equal the raster's.
    image : RasterInfo
        The photo raster (any GDAL format, 1-4 bands, 8/16 bit).
    dem : RasterInfo
        Terrain (or surface) heights, any CRS.
    grid : GridSpec
        Output grid (the orientation's CRS, or another: see :class:`OrthoWindows`).
    surface : DemSurface, optional
        The DEM around the photo (needed for the visibility test; read when missing).
    reference_height : float, optional
        Plane of the relief-displacement figure (default: the DEM's mean under the grid).
    mask_output, incidence_output : path, optional
        Occlusion mask (uint8: 1 hidden, 0 seen, 255 no height) and incidence angle (float32,
        degrees) on the same grid.
    executor : toolbox.executor.Executor, optional
        Where the output windows run (default: the raster engine's, which honours
        ``DASK_SCHEDULER_ADDRESS``); a block's task passes local threads.

    Returns
    -------
    dict : the per-photo report (JSON-ready).
    """
    from pathlib import Path

    from toolbox.feedback import Feedback
    from toolbox.io.crs import crs_label
    from toolbox.photogrammetry.photo import fit_image_size
    from toolbox.raster.resample import single_threaded_opencv
    from toolbox.raster.warp import warp_to_geotiff
    from toolbox.raster.writer import RasterWriter

    options = options or OrthoOptions()
    feedback = feedback or Feedback()
    photo = fit_image_size(photo, image.width, image.height, getattr(image, "path", image))
    compiled = use_compiled() if options.compiled is None else options.compiled
    sampler = DemSampler(dem, grid.crs, options.band, options.dem_factor)
    sampler.compiled = compiled
    # NumPy's map chunks its temporaries: smaller windows bound the memory (two photos x two
    # windows in flight: 4 x 24 MB at 1024; measured 40-50 MB less peak at 512, same CPU time)
    if options.chunk is None:
        options = replace(options, chunk=512 if photo.is_model and not compiled else 1024)
    sampler.preload(grid.bounds)
    to_orientation = orientation_transformer(photo, grid.crs)
    datums = transformations(photo, dem, grid, sampler, feedback)
    if to_orientation is not None and (options.occlusion or incidence_output is not None):
        raise InputDataError("the visibility test and the incidence angles need the ortho in "
                             "the orientation's CRS")
    # the film camera's compiled, planned map; a camera model's own project() otherwise
    cmap = None
    if not photo.is_model:
        from toolbox.ortho.sensor import CollinearityMap

        cmap = CollinearityMap(photo, options.block, options.tolerance_px, image.width,
                               image.height)
    if options.occlusion and surface is None:
        surface = photo_surface(dem, photo, grid.crs, options.band)
    if reference_height is None:
        step = max(1, int(math.ceil(max(grid.width, grid.height) / 256)))
        xs, ys = grid.cell_centers(None)
        with warnings.catch_warnings():  # no height at all is reported just below
            warnings.simplefilter("ignore", RuntimeWarning)
            reference_height = float(np.nanmean(sampler.heights(xs[::step], ys[::step])))
        if not math.isfinite(reference_height):
            raise InputDataError(f"DEM {dem} has no height under the output grid of photo "
                                 f"{photo.id!r}")
    if mask_output is not None and not options.occlusion:
        raise InputDataError("an occlusion mask needs the visibility test (OCCLUSION)")
    output = Path(output)
    # the mask and the angles: tiled, compressed GeoTIFFs with the ortho's overviews (the mask's
    # classes by nearest); a failed run removes them (the writers' exit with the error)
    with ExitStack() as aux:
        mask_writer = incidence_writer = None
        if mask_output is not None:
            mask_writer = aux.enter_context(RasterWriter(
                mask_output, grid, 1, "uint8", 255, overviews=options.overviews,
                overview_resampling="nearest", tags={"ORTHO_PHOTO": photo.id},
                band_descriptions=["occlusion (1 hidden, 0 seen, 255 no height)"]))
        if incidence_output is not None:
            incidence_writer = aux.enter_context(RasterWriter(
                incidence_output, grid, 1, "float32", float("nan"),
                overviews=options.overviews, tags={"ORTHO_PHOTO": photo.id},
                band_descriptions=["incidence angle (ray to surface normal, degrees)"],
                band_units=["degree"]))
        windows = OrthoWindows(photo, grid, sampler, cmap, reference_height,
                               surface if options.occlusion else None, mask_writer,
                               incidence_writer, to_orientation, options.resampling,
                               compiled)
        eo = photo.require_exterior()
        tags = {"ORTHO_PHOTO": photo.id, "ORTHO_MAP_TOLERANCE_PX": str(options.tolerance_px),
                "ORTHO_RESAMPLING": options.resampling, "NADIR_X": repr(eo.x0),
                "NADIR_Y": repr(eo.y0), "PROJECTION_CENTRE_Z": repr(eo.z0)}
        # the engine runs the windows on one thread per core, each its map then its remap
        with feedback.timed("orthorectify"), single_threaded_opencv():
            warp = warp_to_geotiff(image.path, windows, grid, output, options.resampling,
                                   options.outside, options.nodata, chunk=options.chunk,
                                   overviews=options.overviews, cog=options.cog,
                                   feedback=feedback, tags=tags, executor=executor)
    windows.release()
    totals = windows.totals()
    photo_gsd = ground_sample_distance(photo, reference_height)
    cells = max(totals.cells, 1)
    report = {
        "photo": photo.id, "image": str(image.path),
        "crs": crs_label(grid.crs), "cell_size": grid.cell_size[0],
        "photo_gsd_m": photo_gsd, "reference_height": reference_height,
        "width": grid.width, "height": grid.height, "bounds": list(grid.bounds),
        "cells": totals.cells,
        "outside_dem_fraction": totals.outside_dem / cells,
        "outside_photo_fraction": totals.outside_photo / cells,
        "hidden_fraction": totals.hidden / cells if options.occlusion else None,
        "max_relief_displacement_m": totals.max_relief_m,
        "max_relief_displacement_px": totals.max_relief_m / photo_gsd,
        "map_tolerance_px": options.tolerance_px,
        "map_blocks": {"projective_exact": totals.blocks.get(0, 0),
                       "distortion_interpolated": totals.blocks.get(1, 0),
                       "distortion_exact": totals.blocks.get(2, 0)},
        "resampling": options.resampling, "dem_factor": options.dem_factor,
        "expected_accuracy": expected_accuracy(map_scale),
        "warp": warp.as_dict(),
    }
    if datums:
        report["transformations"] = datums
    if totals.outside_dem:
        feedback.push_warning(f"photo {photo.id}: {totals.outside_dem} of {totals.cells} cells "
                              f"({100 * totals.outside_dem / cells:.1f} %) have no DEM height "
                              "and are left empty")
    return report


def transformations(photo: Any, dem: Any, grid: Any, sampler: Any, feedback: Any) -> list:
    """The datum transformations an ortho in another CRS than its orientation or DEM makes
    (:func:`toolbox.io.crs.note_transformation`: which, its accuracy; warned when it is coarser
    than the ortho's cell (the DEM's cell for the DEM), of unknown accuracy, or a better one
    lacks its grid)."""
    from toolbox.io.crs import note_transformation

    cell = float(min(abs(grid.cell_size[0]), abs(grid.cell_size[1])))
    found = [note_transformation(feedback, grid.crs, photo.require_exterior().crs, grid.bounds,
                                 cell, "the ortho's cells (to the orientation's CRS)")]
    if sampler.transformer is not None:
        dem_cell = float(min(abs(dem.transform.a), abs(dem.transform.e)))
        found.append(note_transformation(feedback, grid.crs, dem.crs, grid.bounds, dem_cell,
                                         "the DEM's positions (to the ortho's CRS)"))
    return [f for f in found if f is not None]
