"""One ``dem:match`` run: select the pairs, and for each: epipolar images (scratch GeoTIFFs),
StereoSGBM disparities, triangulated points, per-cell medians; then fusion of all pairs into
the DSM, COUNT and SPREAD rasters (:mod:`toolbox.stereo.fusion`) and the optional LAZ."""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.raster.grid_request import GridRequest
from toolbox.stereo.matching import MatchOptions

POINT_ROWS = 256  # disparity rows triangulated at a time (the points of one block in memory)
# a priori sigma of a matched disparity, in pixels of the epipolar images: the pair's reported
# sigma_z_m is the normal case's for this parallax sigma (on the NGI frames, 0.153 mm epipolar
# pixels, it gives 3.5 m where the DSM scatters by about 4.7 m around the published DEM; the
# film-measurement default of 5 um it took before gave 0.22 m)
MATCH_SIGMA_PX = 0.5


@dataclass
class MatchRequest:
    """One dense-matching DSM run (heights and lengths in CRS units, angles in degrees).

    ``project``: orientation project YAML; ``photos``: ids to use (None: every oriented one);
    ``min_height``..``max_height``: the surface's height range (sets the disparity search);
    pair rules ``min_overlap`` (fraction of the smaller footprint), ``min_base_ratio``,
    ``max_base_ratio``, ``max_angle``; ``pixel_size_mm``: the epipolar images' pixel (None:
    from the grid); ``output``/``count``/``spread``: the three GeoTIFFs; ``points``: optional
    LAS/LAZ of the matched points."""

    project: Path
    min_height: float
    max_height: float
    output: Path
    count: Path
    spread: Path
    photos: list[str] | None = None
    min_overlap: float = 0.3
    min_base_ratio: float = 0.1
    max_base_ratio: float = 2.0
    max_angle: float = 30.0
    pixel_size_mm: float | None = None
    options: MatchOptions = field(default_factory=MatchOptions)
    grid: GridRequest = field(default_factory=GridRequest)
    nodata: float = -9999.0
    points: Path | None = None
    executor: Any = None  # where pairs are matched (toolbox.executor.Executor); None: threads


def read_epipolar(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Data bands (bands, rows, cols) and the valid mask (alpha > 0) of an epipolar image."""
    import rasterio

    with rasterio.open(path) as ds:
        data = ds.read(list(range(1, ds.count)))
        valid = ds.read(ds.count) > 0
    return data, valid


def matching_pixel(left: Any, cell_size: float, distance_m: float) -> float:
    """Default epipolar pixel (mm): the left image's, or coarser so that a DSM cell spans four
    pixels on the ground (GSD = pixel x distance / c): matching much finer than the grid only adds
    points to one median."""
    native = float(left.require_pixel_transform().pixel_size_mm)
    return max(native, 0.25 * cell_size * left.camera.c / distance_m)


def spread_nodata(nodata: float) -> float:
    """SPREAD's nodata: NODATA when it cannot be a spread (negative, or NaN), else -1 (a
    spread is never negative; NODATA 0 made every cell of spread 0, one pair's points all at
    one height, read as no value)."""
    return nodata if nodata < 0 or math.isnan(nodata) else -1.0


def disparity_fits(pairs: list, pixels: list[float], low: float, high: float,
                   max_disparities: int) -> tuple[list, list[str]]:
    """The pairs whose heights ``low``..``high`` span at most ``max_disparities`` disparities
    at their epipolar pixel, and a line for each of the others (pair, disparities needed,
    MAX_DISPARITIES)."""
    from toolbox.stereo.epipolar import epipolar_geometry
    from toolbox.stereo.matching import disparity_range

    kept, wide = [], []
    for pair, pixel in zip(pairs, pixels, strict=True):
        left, right = pair[0], pair[1]
        _, count = disparity_range(epipolar_geometry(left, right, pixel_mm=pixel), left, low,
                                   high)
        if count > max_disparities:
            wide.append(f"{left.id}-{right.id}: MIN_HEIGHT {low:g} .. MAX_HEIGHT {high:g} spans "
                        f"{count} disparities, more than MAX_DISPARITIES {max_disparities} "
                        "(narrow the height range to the terrain's, or coarsen PIXEL_SIZE_MM)")
        else:
            kept.append(pair)
    return kept, wide


def match_one_pair(left: Any, right: Any, images: tuple[Path, Path], low: float, high: float,
                   options: MatchOptions, pixel_mm: float, workdir: Path,
                   feedback: Feedback, pixel_photos: tuple[Any, Any] | None = None
                   ) -> tuple[Any, np.ndarray, np.ndarray, dict]:
    """Geometry, disparity (NaN invalid), the left image's colours (K, 3) uint8 per pixel
    (grey repeated for one band) and statistics of one pair. ``pixel_photos``: the photos
    whose cameras fetch the pixels (see :func:`toolbox.stereo.epipolar.resample_image`)."""
    from toolbox.stereo.epipolar import epipolar_geometry, resample_image
    from toolbox.stereo.matching import disparity_range, match_pair, to_uint8

    geometry = epipolar_geometry(left, right, pixel_mm=pixel_mm)
    d_min, count = disparity_range(geometry, left, low, high)
    name = f"{left.id}-{right.id}"
    if count > options.max_disparities:
        raise InputDataError(
            f"MIN_HEIGHT {low:g} .. MAX_HEIGHT {high:g} spans {count} disparities in pair "
            f"{name}, more than MAX_DISPARITIES {options.max_disparities}: narrow the height "
            "range to the terrain's (or coarsen PIXEL_SIZE_MM)")
    arrays = []
    for side, photo in enumerate((left, right)):
        path = workdir / f"{name}_{side}.tif"
        resample_image(geometry, photo, side, images[side], path, "bilinear",
                       feedback.step(20 * side, 20 * side + 20), overviews=False,
                       pixel_photo=None if pixel_photos is None else pixel_photos[side])
        data, valid = read_epipolar(path)
        arrays.append((to_uint8(data, valid), valid))
        if side == 0:
            colours = _colours(data, arrays[0][0])
        path.unlink()
    (lim, lval), (rim, rval) = arrays
    from toolbox.stereo.range_check import check_terrain_range, coarse_heights

    coarse = coarse_heights(geometry, left, (lim, rim), (lval, rval), low, high, options)
    check_terrain_range(coarse, low, high, name, feedback)
    disparity = match_pair(lim, rim, lval, rval, d_min, count, options, feedback.step(40, 100))
    matched = int(np.isfinite(disparity).sum())
    stats = {"pair": name, "min_disparity": d_min, "num_disparities": count,
             "image_size": [lim.shape[1], lim.shape[0]], "matched_pixels": matched,
             "matched_fraction_of_left": matched / max(1, int(lval.sum())),
             "coarse_inside_range": coarse.inside(low, high) if len(coarse.heights) else None}
    return geometry, disparity, colours, stats


@dataclass(frozen=True)
class PairJob:
    """One stereo pair to match on a thread or a Dask worker, picklable and small: the frame
    photos, the image paths (each worker reads its pair itself: the images must be at the same
    path there), the photos whose cameras fetch the pixels, and the DSM grid's transform and
    size; ``points``: the matched points come back too (a LAS/LAZ is written); ``feedback``
    (local runs, never pickled): progress and cancellation within the pair; ``sink`` (local
    runs): the points go straight to the LAS/LAZ writer instead of coming back."""

    left: Any
    right: Any
    images: tuple[Path, Path]
    pixel_photos: tuple[Any, Any]
    low: float
    high: float
    options: MatchOptions
    pixel_mm: float
    transform: Any
    width: int
    height: int
    points: bool = False
    feedback: Any = None  # local runs only: the pair's share of the run's progress
    sink: Any = None  # local runs only: the point writer, fed block by block (never held)


@dataclass
class PairDone:
    """What a pair gives back: its cells' statistics (:func:`cell_statistics`), statistics,
    messages (level, text) for the client to push, and (xyz, rgb) blocks of points if asked."""

    cells: tuple
    stats: dict
    messages: list
    points: list


def match_pair_job(job: PairJob) -> PairDone:
    """Match one pair (module level: a Dask worker imports it by name), in a scratch folder of
    its own, and reduce its points to per-cell statistics of the grid."""
    from toolbox.feedback import CollectingFeedback
    from toolbox.stereo.fusion import cell_index, cell_statistics
    from toolbox.stereo.matching import disparity_points

    feedback = job.feedback if job.feedback is not None else CollectingFeedback()
    with tempfile.TemporaryDirectory(prefix="dem_match_") as tmp:
        geometry, disparity, colours, stats = match_one_pair(
            job.left, job.right, job.images, job.low, job.high, job.options, job.pixel_mm,
            Path(tmp), feedback, job.pixel_photos)
    keys, heights, blocks, n_points = [], [], [], 0
    for r0 in range(0, disparity.shape[0], POINT_ROWS):  # points by row blocks
        xyz, flat = disparity_points(geometry, disparity[r0:r0 + POINT_ROWS], r0)
        keep = (xyz[:, 2] >= job.low) & (xyz[:, 2] <= job.high)
        xyz, flat = xyz[keep], flat[keep]
        cell, inside = cell_index(xyz, job.transform, job.width, job.height)
        keys.append(cell[inside])
        heights.append(xyz[inside, 2])
        n_points += len(xyz)
        if job.points:
            rgb = colours[flat + r0 * disparity.shape[1]]
            if job.sink is not None:
                job.sink.write(xyz, rgb=rgb)
            else:
                blocks.append((xyz, rgb))
    stats.update(points=n_points)
    messages = [] if job.feedback is not None else feedback.messages  # else pushed already
    return PairDone(cell_statistics(np.concatenate(keys), np.concatenate(heights)), stats,
                    messages, blocks)


def _colours(data: np.ndarray, grey: np.ndarray) -> np.ndarray:
    """(rows * cols, 3) uint8 colours: the three bands of an 8-bit RGB image, else the grey."""
    if data.shape[0] == 3 and data.dtype == np.uint8:
        return data.reshape(3, -1).T
    return np.repeat(grey.reshape(-1, 1), 3, axis=1)


def run_match(request: MatchRequest, feedback: Feedback) -> dict[str, Any]:
    """Match every suitable pair, fuse, write the rasters (and points); returns the
    statistics."""
    from toolbox.executor import map_tiles, resolve_executor
    from toolbox.io.crs import crs_label
    from toolbox.io.raster import nodata_clash_warning, nodata_clashes
    from toolbox.photogrammetry.tables import load_project_parameter
    from toolbox.stereo.epipolar import photo_image
    from toolbox.stereo.fusion import fuse
    from toolbox.stereo.pairs import PairRules, overlap_bounds, select_pairs

    project = load_project_parameter(request.project)
    if request.photos:
        photos = [project.photo(i) for i in request.photos]
        for photo in photos:
            photo.require_exterior()
    else:
        photos = project.oriented()
    from toolbox.stereo.frames import as_frame_photo

    originals = {photo.id: photo for photo in photos}  # model cameras fetch the pixels
    photos = [as_frame_photo(photo) for photo in photos]  # their distortion-free frames
    if len(photos) < 2:
        raise InputDataError(f"PROJECT has {len(photos)} oriented photo(s) (of those chosen): "
                             "dense matching needs at least one oriented pair")
    low, high = float(request.min_height), float(request.max_height)
    rules = PairRules((low + high) / 2.0, request.min_overlap, request.min_base_ratio,
                      request.max_base_ratio, request.max_angle)
    pairs, skipped = select_pairs(photos, rules)
    for line in skipped:
        feedback.push_info(f"pair skipped: {line}")
    if not pairs:
        raise InputDataError(f"no suitable stereo pair among {len(photos)} photos: "
                             f"{'; '.join(skipped[:3])}")
    crs = project.crs
    options = request.options

    def grid_and_pixels(pairs):
        bounds = np.array([overlap_bounds(a, b, rules.terrain_height) for a, b, _ in pairs])
        data_bounds = (bounds[:, 0].min(), bounds[:, 1].min(), bounds[:, 2].max(),
                       bounds[:, 3].max())
        grid = request.grid.grid(data_bounds, crs)
        return data_bounds, grid, [
            request.pixel_size_mm or matching_pixel(left, abs(grid.transform.a),
                                                    report.distance_m)
            for left, right, report in pairs]

    data_bounds, grid, pixels = grid_and_pixels(pairs)
    # a pair whose height range needs more disparities than MAX_DISPARITIES is skipped as the
    # other unusable pairs are (it stopped the whole run); refused when no pair is left
    kept, wide = disparity_fits(pairs, pixels, low, high, options.max_disparities)
    for line in wide:
        feedback.push_warning(f"pair skipped: {line}")
    skipped = skipped + wide
    if not kept:
        raise InputDataError(f"no stereo pair fits MAX_DISPARITIES {options.max_disparities}: "
                             f"{'; '.join(wide[:3])}")
    if len(kept) < len(pairs):
        pairs = kept
        data_bounds, grid, pixels = grid_and_pixels(pairs)
    cells, pair_stats = [], []
    writer = None
    if request.points is not None:
        from toolbox.io.pointcloud import PointCloudWriter

        centre = np.array([(data_bounds[0] + data_bounds[2]) / 2,
                           (data_bounds[1] + data_bounds[3]) / 2, low])
        writer = PointCloudWriter(request.points, centre, crs, rgb=True).__enter__()
    executor = request.executor or resolve_executor("local")
    local = executor.kind == "local"
    if local:  # in this thread, one pair at a time: its epipolar images are the run's memory
        executor = resolve_executor("local", 1)  # peak, and a signal stops it at once

    def jobs():  # lazily: a pair's images are looked for when it is submitted
        for k, ((left, right, _), pixel) in enumerate(zip(pairs, pixels, strict=True)):
            step = feedback.step(90 * k / len(pairs), 90 * (k + 1) / len(pairs))
            yield PairJob(left, right, (photo_image(left, None, "its image path in PROJECT"),
                                        photo_image(right, None, "its image path in PROJECT")),
                          (originals[left.id], originals[right.id]), low, high, options, pixel,
                          grid.transform, grid.width, grid.height, writer is not None,
                          step if local else None, writer if local else None)

    try:
        # on a cluster as many pairs at a time as the workers take
        for (_, _, report), pixel, done in zip(pairs, pixels, map_tiles(
                match_pair_job, jobs(), executor=executor,
                feedback=None if local else feedback, total=len(pairs), end=90), strict=True):
            for level, text in done.messages:
                (feedback.push_warning if level == "warning" else feedback.push_info)(text)
            if writer is not None:
                for xyz, rgb in done.points:
                    writer.write(xyz, rgb=rgb)
            cells.append(done.cells)
            stats = done.stats
            sigma_parallax_um = MATCH_SIGMA_PX * pixel * 1000.0  # sigma_z is linear in it
            stats.update(pixel_mm=pixel, base_ratio=report.base_ratio,
                         overlap=report.overlap, sigma_parallax_um=sigma_parallax_um,
                         sigma_z_m=report.sigma_z_m * sigma_parallax_um
                         / report.sigma_parallax_um)
            pair_stats.append(stats)
            if stats["matched_fraction_of_left"] < 0.2:
                feedback.push_warning(
                    f"pair {stats['pair']}: only {100 * stats['matched_fraction_of_left']:.0f}"
                    " % of the left image matched: is MIN_HEIGHT..MAX_HEIGHT the terrain's, "
                    "and is the pair textured?")
            feedback.push_info(f"pair {stats['pair']}: {stats['points']} points "
                               f"({100 * stats['matched_fraction_of_left']:.0f} % of the "
                               "left image matched)")
    finally:
        if writer is not None:
            writer.__exit__(None, None, None)
    dsm, count, spread = fuse(cells, grid.width, grid.height)
    nodata = float(request.nodata)
    clashes = nodata_clashes(dsm, nodata, "float32")
    if clashes:  # heights stored as NODATA: no value in the file
        feedback.push_warning(nodata_clash_warning(clashes, nodata))
    _write(request.output, grid, dsm, "float32", nodata)
    _write(request.count, grid, count, "uint16", 0)
    _write(request.spread, grid, spread, "float32", spread_nodata(nodata))
    feedback.set_progress(100)
    valid = int(np.isfinite(dsm).sum()) - clashes
    stats = {"pairs": pair_stats, "skipped": skipped, "crs": crs_label(crs),
             "grid": {"width": grid.width, "height": grid.height,
                      "cell_size": abs(grid.transform.a), "bounds": list(grid.bounds)},
             "cells_with_value": valid, "cells": grid.width * grid.height,
             "max_pairs_per_cell": int(count.max()) if count.size else 0,
             "executor": executor.describe()}
    if writer is not None:
        stats["points_written"] = writer.count
    return stats


def _write(path: Path, grid: Any, array: np.ndarray, dtype: str, nodata: float) -> None:
    from rasterio.windows import Window

    from toolbox.raster.writer import RasterWriter

    with RasterWriter(path, grid, 1, dtype, nodata) as writer:
        writer.write(Window(0, 0, grid.width, grid.height), array)
