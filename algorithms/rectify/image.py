"""rectify:image - warp a photo onto the ground plane with a rectify:estimate transform.

Library code: :mod:`toolbox.transforms.rectification` (pixel -> ground matrix, footprint,
default cell size), the raster engine's grid rules, :func:`toolbox.raster.warp.warp_raster`
with a :class:`~toolbox.raster.homography.HomographyMap`, and
:class:`~toolbox.raster.writer.RasterWriter`.
"""

from __future__ import annotations

import json

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Enum, ExtentParameter, File, Number, RasterLayer, String
from toolbox.parameters.outputs import Output, OutputRaster
from toolbox.registry import register
from toolbox.transforms.rectification import MODES, OUTSIDE, RectificationModel, parse_pixel_to_image
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.grid import grid_request

RESAMPLING_METHODS = ("nearest", "bilinear", "cubic", "lanczos")  # toolbox.raster.resample's


@register
class RectifyImage(Algorithm):
    """Rectify a photo: warp it onto the ground plane (or a facade's plane) with a transform
    estimated by rectify:estimate.

    Indirect method: for every output cell centre the inverse transform gives the source
    position (pixel convention: origin at the top-left corner of the top-left pixel, rows down,
    pixel centres at +0.5), where the photo is resampled (nearest, bilinear, cubic or lanczos,
    by OpenCV). The output grid is north-up with square cells of CELL_SIZE (default: the ground
    size of a photo pixel at its centre), covering EXTENT as given (origin at its xmin/ymax;
    the east and south edges round up to whole cells), by default the photo's ground
    footprint with edges snapped to multiples of the cell. Outside the photo the output has
    alpha 0 (OUTSIDE=alpha, default) or NODATA. The work is streamed tile by tile on local
    threads (the source window each output tile needs, plus the interpolation margin), so
    memory stays bounded for any size of photo (e.g. a 16644 x 16644 scan); the output is a
    Cloud Optimized GeoTIFF (DEFLATE, with overviews) in the transform's CRS (none for a local
    object system); COG=false writes a tiled GeoTIFF with internal overviews instead.

    Any raster GDAL reads is accepted (TIFF, JPEG, PNG...; 1-4 or more bands, 8/16-bit or
    float); its own georeferencing, if any, is ignored. A transform in image mm needs the
    photo's interior orientation as PIXEL_TO_IMAGE (the Pixel->Fiducial matrix).

    MODE=gcps writes no resampled image: the photo is copied into a GeoTIFF with the control
    points embedded as GCPs, for warping later with GDAL (e.g. gdalwarp -order 1 or -tps),
    with the overviews and the COG layout OVERVIEWS and COG ask for, as MODE=warp.
    """

    id = "rectify:image"
    display_name = "Rectify image"
    group = "Rectification"
    short_help = "Warp a photo to a GeoTIFF with a rectify:estimate transform (or embed GCPs)."
    parameters = [
        RasterLayer("INPUT", "the photo (any GDAL raster: TIFF, JPEG, PNG...)", role="photo"),
        File("TRANSFORM", "transform written by rectify:estimate", extensions=[".json"]),
        String("PIXEL_TO_IMAGE", "pixel -> image mm matrix, 6 or 8 numbers row by row (only for "
               "a transform in image mm)", optional=True),
        Enum("MODE", "warp: resample onto a map grid; gcps: copy the photo with embedded GCPs",
             options=MODES, default="warp"),
        Number("CELL_SIZE", "output cell size, ground units (default: a photo pixel's ground "
               "size at the centre)", optional=True, min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "output extent (default: the photo's footprint)",
                        optional=True),
        Enum("RESAMPLING", "interpolation", options=RESAMPLING_METHODS, default="bilinear"),
        Enum("OUTSIDE", "marking of cells outside the photo: an alpha band (Byte and "
             "UInt16 photos; others get nodata) or nodata",
             options=OUTSIDE, default="alpha"),
        Number("NODATA", "nodata value with OUTSIDE=nodata (default: the photo's, else 0, NaN "
               "for float)", optional=True),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF (false: a tiled GeoTIFF "
                "with internal overviews)", default=True),
        scheduler_parameter(),
        OutputRaster("OUTPUT", "rectified GeoTIFF (or GCP GeoTIFF with MODE=gcps)"),
    ]
    outputs = [Output("STATISTICS", "grid, footprint and warp counters", "json")]

    def check(self, params):
        info = params["INPUT"]
        if params["MODE"] == "gcps":
            for name in ("CELL_SIZE", "EXTENT", "NODATA"):
                if params[name] is not None:
                    raise self.fail(name, "does not apply with MODE=gcps (the photo is copied, "
                                    "not resampled)")
        if info.width < 1 or info.height < 1:
            raise self.fail("INPUT", f"{info} has no pixels")
        from toolbox.io.raster import has_valid_pixel

        if not has_valid_pixel(info.path):  # all nodata or all NaN: an empty, "valid" output
            raise self.fail("INPUT", f"{info} has no valid pixel (every pixel is nodata or NaN)")
        if params["PIXEL_TO_IMAGE"] is not None:
            parse_pixel_to_image(params["PIXEL_TO_IMAGE"])
        from toolbox.io.crs import check_input_crs
        from toolbox.transforms.rectification import load_transform

        model = load_transform(params["TRANSFORM"], "TRANSFORM")
        if model.crs is not None and params["MODE"] != "gcps":  # CELL_SIZE etc. are metres
            check_input_crs(self.id, "TRANSFORM", model.crs)

    def process(self, params, feedback: Feedback):
        from toolbox.io.crs import crs_label
        from toolbox.raster.homography import HomographyMap
        from toolbox.raster.nan_cells import NanCells
        from toolbox.raster.warp import warp_layout, warp_raster
        from toolbox.raster.writer import RasterWriter
        from toolbox.transforms.plane import apply_homography
        from toolbox.transforms.rectification import (
            default_cell_size,
            footprint,
            load_transform,
            photo_cells,
            pixel_to_ground_matrix,
        )

        info = params["INPUT"]
        model = load_transform(params["TRANSFORM"], "TRANSFORM")
        p2i = None if params["PIXEL_TO_IMAGE"] is None else \
            parse_pixel_to_image(params["PIXEL_TO_IMAGE"])
        if model.image_units == "pixels" and p2i is not None:
            raise ParameterError("PIXEL_TO_IMAGE", "does not apply: the transform maps pixels "
                                 "(image_units = pixels), not image mm")
        matrix = pixel_to_ground_matrix(model, p2i)
        self._points_on_photo(model, p2i, info)
        tags = {"RECTIFY_MODEL": model.model,
                "RECTIFY_PIXEL_TO_GROUND": json.dumps(matrix.tolist()),
                "RECTIFY_PIXEL_CONVENTION": "col,row from the top-left corner; centres at +0.5"}
        if params["MODE"] == "gcps":
            return self._gcps(params, model, p2i, tags, feedback)
        corners = None
        try:
            corners = footprint(matrix, info.width, info.height)
        except InputDataError:
            if params["EXTENT"] is None:
                raise
            feedback.push_warning("the ground plane's vanishing line crosses the photo; only "
                                  "the part in front of the camera is rectified")
        bounds = None if corners is None else (
            float(corners[:, 0].min()), float(corners[:, 1].min()),
            float(corners[:, 0].max()), float(corners[:, 1].max()))
        grid = grid_request(params).grid(
            bounds, model.crs,
            default_cell_size=lambda: default_cell_size(matrix, info.width, info.height))
        cell = grid.cell_size[0]
        centre, _ = apply_homography(matrix, np.array([[info.width / 2.0, info.height / 2.0]]),
                                     return_w=True)
        coordinate_map = HomographyMap(np.linalg.inv(matrix), grid.transform,
                                       front=(float(centre[0, 0]), float(centre[0, 1])))
        try:
            layout = warp_layout(info, params["OUTSIDE"], params["NODATA"])
        except ParameterError:
            raise
        except ValueError as exc:
            raise ParameterError("NODATA" if params["NODATA"] is not None else "INPUT",
                                 str(exc)) from None
        writer = RasterWriter(params["OUTPUT"], grid, layout.count, layout.dtype, layout.nodata,
                              alpha=layout.alpha, cog=params["COG"],
                              overviews=params["OVERVIEWS"], tags=tags)
        nan_cells = NanCells(writer, layout.alpha, lambda window: photo_cells(
            matrix, grid.transform, window, info.width, info.height))  # NaN pixels: no data
        with feedback.timed("warp"), writer:
            stats = warp_raster(info, grid, coordinate_map, nan_cells, layout=layout,
                                resampling=params["RESAMPLING"], tile_size=2048,
                                executor=executor_of(params),
                                feedback=feedback, end=95 if params["OVERVIEWS"] else 100)
        if nan_cells.count:
            feedback.push_warning(f"INPUT: {nan_cells.count} output cells fall on NaN pixels of "
                                  f"{info} and are no data ({'alpha 0' if layout.alpha else 'nodata'})")
        if params["NODATA"] is None and info.nodata is None and layout.nodata is not None:
            clashes = _samples_equal(info, layout.data_bands, layout.nodata)
            if clashes:  # the nodata value was a guess: valid pixels moved off it
                feedback.push_warning(f"INPUT: {clashes} photo sample(s) hold "
                                      f"{layout.nodata:g}, the nodata value chosen for "
                                      "OUTSIDE=nodata, so the cells warped from them are "
                                      "moved one step off it to stay valid (as gdalwarp "
                                      "does); give NODATA a value the photo does not hold, "
                                      "or OUTSIDE=alpha")
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": {
            "model": model.model, "crs": crs_label(model.crs), "cell_size": cell,
            "width": grid.width, "height": grid.height, "bounds": list(grid.bounds),
            "footprint": None if corners is None else corners.tolist(),
            "resampling": params["RESAMPLING"], "outside": params["OUTSIDE"],
            "pixel_to_ground": matrix.tolist(), "nan_cells": nan_cells.count,
            **stats.as_dict()}}

    @staticmethod
    def _points_on_photo(model: RectificationModel, p2i, info) -> None:
        """The transform's control and check points were measured on the photo: one off
        INPUT's pixels (more than a pixel past its edge) says INPUT is another raster than the
        one measured (a preview, a crop, a turned copy) and the transform would warp it in
        silence onto the wrong ground."""
        from toolbox.transforms.plane import apply_homography

        points = [p for p in model.control_points() if p.get("image") is not None]
        if not points or (model.image_units == "mm" and p2i is None):
            return
        image = np.array([p["image"] for p in points], dtype="float64").reshape(-1, 2)
        if model.image_units == "mm":
            image = apply_homography(np.linalg.inv(p2i), image)
        off = ~((image >= -1.0) & (image <= np.array([info.width, info.height]) + 1.0)).all(axis=1)
        if off.any():
            k = int(np.flatnonzero(off)[0])
            raise ParameterError(
                "INPUT", f"{info} is {info.width} x {info.height} px but control point "
                f"{points[k].get('id')!r} of TRANSFORM '{model.path}' was measured at "
                f"({image[k, 0]:g}, {image[k, 1]:g}) px ({int(off.sum())} of {len(points)} "
                "points off the photo): the transform was estimated on another raster (a "
                "scaled, cropped or turned copy?)")

    @staticmethod
    def _gcps(params, model: RectificationModel, p2i, tags, feedback: Feedback):
        from toolbox.io.crs import crs_label
        from toolbox.transforms.plane import apply_homography
        from toolbox.transforms.rectification import write_gcp_geotiff

        used = model.control_points()
        if not used:
            raise InputDataError(f"TRANSFORM '{model.path}' lists no control points to embed")
        image = np.array([p["image"] for p in used], dtype="float64")
        if model.image_units == "mm":
            if p2i is None:
                raise ParameterError("PIXEL_TO_IMAGE", "is required to convert the control "
                                     "points' image mm to pixels for the GCPs")
            image = apply_homography(np.linalg.inv(p2i), image)
        gcps = [(p["id"], float(c), float(r), float(p["ground"][0]), float(p["ground"][1]),
                 float(p.get("z") or 0.0)) for p, (c, r) in zip(used, image, strict=True)]
        write_gcp_geotiff(params["INPUT"].path, params["OUTPUT"], gcps, model.crs, feedback, tags,
                          overviews=params["OVERVIEWS"], cog=params["COG"])
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": {
            "model": model.model, "crs": crs_label(model.crs), "gcps": len(gcps),
            "gcp_ids": [g[0] for g in gcps]}}


def _samples_equal(info, bands: list[int], value: float) -> int:
    """How many samples of ``bands`` of the photo ``info`` (a paletted one: its colours, as
    the warp reads it) equal ``value``, read block by block; 0 for NaN."""
    import math
    import warnings

    import rasterio

    from toolbox.raster.warp import photo_path

    if math.isnan(value):
        return 0
    count = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(photo_path(info.path)) as src:
            for _, window in src.block_windows(1):
                count += int(np.count_nonzero(src.read(bands, window=window) == value))
    return count
