"""rectify:image - warp a photo onto the ground plane with a rectify:estimate transform.

Kernels: :func:`pixel_to_ground_matrix` (compose with the interior orientation),
:func:`footprint` (ground outline of the photo), :func:`default_cell_size`; the streamed warp is
:func:`algorithms.rectify.warp.warp_to_geotiff` with a
:class:`~algorithms.rectify.warp.HomographyMap`.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from typing import Any

import numpy as np

from algorithms.rectify.estimate import RectificationModel, load_transform
from algorithms.rectify.warp import RESAMPLING_METHODS, HomographyMap, warp_to_geotiff
from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import (
    Boolean,
    Enum,
    ExtentParameter,
    File,
    Number,
    Output,
    OutputRaster,
    RasterLayer,
    String,
)
from toolbox.registry import register

MODES = ("warp", "gcps")
OUTSIDE = ("alpha", "nodata")


def parse_pixel_to_image(text: str, name: str = "PIXEL_TO_IMAGE") -> np.ndarray:
    """The Pixel->Fiducial matrix from 6 (affine) or 8 (homography) numbers, row by row:
    ``a b c d e f [g h]`` means ``x = (a·col + b·row + c)/(g·col + h·row + 1)``, ``y = (d·col +
    e·row + f)/(...)`` (the Z-Map interior-orientation reports' ``p2f`` elements)."""
    parts = [p for p in re.split(r"[,;\s]+", str(text).strip()) if p]
    try:
        numbers = [float(p) for p in parts]
    except ValueError:
        numbers = []
    if len(numbers) not in (6, 8) or not all(math.isfinite(v) for v in numbers):
        raise ParameterError(name, f"must be 6 or 8 numbers (a b c d e f [g h], the Pixel->"
                             f"Fiducial matrix row by row), got {text!r}")
    g, h = (numbers[6], numbers[7]) if len(numbers) == 8 else (0.0, 0.0)
    matrix = np.array([numbers[0:3], numbers[3:6], [g, h, 1.0]])
    if abs(np.linalg.det(matrix)) < 1e-300:
        raise ParameterError(name, f"{text!r} is not invertible")
    return matrix


def pixel_to_ground_matrix(model: RectificationModel,
                           pixel_to_image: np.ndarray | None) -> np.ndarray:
    """Homography from source pixel coordinates (col, row; centres at +0.5) to ground X, Y."""
    if model.image_units == "pixels":
        matrix = model.image_to_ground
    else:
        if pixel_to_image is None:
            raise ParameterError("PIXEL_TO_IMAGE", "is required: the transform maps image mm to "
                                 "the ground, so the pixel -> mm (interior orientation) matrix is "
                                 "needed to warp pixels")
        matrix = model.image_to_ground @ pixel_to_image
    return matrix / matrix[2, 2]


def _apply(matrix: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p = np.column_stack([points, np.ones(len(points))]) @ matrix.T
    return p[:, :2] / p[:, 2:], p[:, 2]


def footprint(pixel_to_ground: np.ndarray, width: int, height: int) -> np.ndarray:
    """Ground (X, Y) of the photo's four corners (top-left, top-right, bottom-right,
    bottom-left), (4, 2). Raises :class:`InputDataError` when the plane's vanishing line crosses
    the photo (an oblique view: the footprint is unbounded)."""
    corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype="float64")
    ground, w = _apply(pixel_to_ground, corners)
    if not (np.all(w > 0) or np.all(w < 0)):
        raise InputDataError("the ground plane's vanishing line crosses the photo (an oblique "
                             "view): its footprint is unbounded; give EXTENT")
    return ground


def default_cell_size(pixel_to_ground: np.ndarray, width: int, height: int) -> float:
    """Ground size of a source pixel at the photo centre, ``sqrt(|det J|)``, rounded to 3
    significant digits."""
    centre = np.array([width / 2.0, height / 2.0])
    step = 1.0
    pts = np.array([centre, centre + [step, 0], centre + [0, step]])
    g, _ = _apply(pixel_to_ground, pts)
    jac = np.column_stack([g[1] - g[0], g[2] - g[0]]) / step
    size = float(np.sqrt(abs(np.linalg.det(jac))))
    if not size > 0 or not math.isfinite(size):
        raise InputDataError("the transform gives a zero or undefined pixel size at the photo "
                             "centre")
    return float(f"{size:.3g}")


def write_gcp_geotiff(source: Any, output: Any, gcps: list[tuple[str, float, float, float,
                                                               float, float]],
                      crs: Any, feedback: Feedback, tags: dict[str, str] | None = None,
                      chunk: int = 2048) -> None:
    """Copy ``source`` into a tiled GeoTIFF with embedded GCPs, window by window.

    ``gcps``: (id, col, row, X, Y, Z) with col/row in the source pixel convention (pixel centres
    at +0.5, as GDAL's GCP pixel/line).
    """
    import rasterio
    from rasterio.control import GroundControlPoint
    from rasterio.enums import ColorInterp

    from toolbox.io.raster import geotiff_profile, iter_windows

    with rasterio.Env(GDAL_CACHEMAX=256), warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(source) as src:
            dtypes = set(src.dtypes)
            if len(dtypes) != 1:
                raise InputDataError(f"INPUT has bands of different types ({', '.join(dtypes)})")
            options: dict[str, str] = {"num_threads": "ALL_CPUS"}
            interp = list(src.colorinterp)
            has_alpha = src.count > 1 and interp[-1] == ColorInterp.alpha
            if src.count - has_alpha == 3 and np.dtype(src.dtypes[0]).kind in "iu":
                options["photometric"] = "RGB"
            if has_alpha:
                options["alpha"] = "YES"
            profile = geotiff_profile(src.width, src.height, src.count, src.dtypes[0], crs,
                                      None, src.nodata, **options)
            profile.pop("transform")
            points = [GroundControlPoint(row=r, col=c, x=x, y=y, z=z, id=str(i), info=str(i))
                      for i, c, r, x, y, z in gcps]
            with rasterio.open(output, "w", gcps=points, **profile) as dst:
                if tags:
                    dst.update_tags(**tags)
                windows = [t.core for t in iter_windows(src.width, src.height, chunk)]
                for window in feedback.iterate(windows):
                    dst.write(src.read(window=window), window=window)


@register
class RectifyImage(Algorithm):
    """Rectify a photo: warp it onto the ground plane (or a facade's plane) with a transform
    estimated by rectify:estimate.

    Indirect method: for every output cell centre the inverse transform gives the source
    position (pixel convention: origin at the top-left corner of the top-left pixel, rows down,
    pixel centres at +0.5), where the photo is resampled (nearest, bilinear, cubic or lanczos,
    by OpenCV). The output grid is north-up with square cells of CELL_SIZE (default: the ground
    size of a photo pixel at its centre), covering EXTENT (default: the photo's ground
    footprint), edges snapped to multiples of the cell. Outside the photo the output has
    alpha 0 (OUTSIDE=alpha, default) or NODATA. The work is streamed window by window (the
    source window each output window needs, plus the interpolation margin), so memory stays
    bounded for any size of photo (e.g. a 16644 x 16644 scan); the output is a tiled, DEFLATE
    GeoTIFF in the transform's CRS (none for a local object system), with overviews.

    Any raster GDAL reads is accepted (TIFF, JPEG, PNG...; 1-4 or more bands, 8/16-bit or
    float); its own georeferencing, if any, is ignored. A transform in image mm needs the
    photo's interior orientation as PIXEL_TO_IMAGE (the Pixel->Fiducial matrix).

    MODE=gcps writes no resampled image: the photo is copied into a GeoTIFF with the control
    points embedded as GCPs, for warping later with GDAL (e.g. gdalwarp -order 1 or -tps).
    """

    id = "rectify:image"
    display_name = "Rectify image"
    group = "Rectification"
    short_help = "Warp a photo to a GeoTIFF with a rectify:estimate transform (or embed GCPs)."
    parameters = [
        RasterLayer("INPUT", "the photo (any GDAL raster: TIFF, JPEG, PNG...)"),
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
        Enum("OUTSIDE", "marking of cells outside the photo: an alpha band or nodata",
             options=OUTSIDE, default="alpha"),
        Number("NODATA", "nodata value with OUTSIDE=nodata (default: the photo's, else 0, NaN "
               "for float)", optional=True),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        OutputRaster("OUTPUT", "rectified GeoTIFF (or GCP GeoTIFF with MODE=gcps)"),
    ]
    outputs = [Output("STATISTICS", "grid, footprint and warp counters", "dict")]

    def check(self, params):
        info = params["INPUT"]
        if params["MODE"] == "gcps":
            for name in ("CELL_SIZE", "EXTENT", "NODATA"):
                if params[name] is not None:
                    raise self.fail(name, "does not apply with MODE=gcps (the photo is copied, "
                                    "not resampled)")
        if info.width < 1 or info.height < 1:
            raise self.fail("INPUT", f"{info} has no pixels")
        if params["PIXEL_TO_IMAGE"] is not None:
            parse_pixel_to_image(params["PIXEL_TO_IMAGE"])

    def process(self, params, feedback: Feedback):
        from toolbox.io.crs import crs_label, same_crs
        from toolbox.io.grid import GridSpec

        info = params["INPUT"]
        model = load_transform(params["TRANSFORM"], "TRANSFORM")
        p2i = None if params["PIXEL_TO_IMAGE"] is None else \
            parse_pixel_to_image(params["PIXEL_TO_IMAGE"])
        if model.image_units == "pixels" and p2i is not None:
            raise ParameterError("PIXEL_TO_IMAGE", "does not apply: the transform maps pixels "
                                 "(image_units = pixels), not image mm")
        matrix = pixel_to_ground_matrix(model, p2i)
        tags = {"RECTIFY_MODEL": model.model,
                "RECTIFY_PIXEL_TO_GROUND": json.dumps(matrix.tolist()),
                "RECTIFY_PIXEL_CONVENTION": "col,row from the top-left corner; centres at +0.5"}
        if params["MODE"] == "gcps":
            return self._gcps(params, model, p2i, tags, feedback)
        extent = params["EXTENT"]
        if extent is not None and extent.crs is not None and not same_crs(extent.crs, model.crs):
            raise ParameterError("EXTENT", f"is in {crs_label(extent.crs)} but the transform is "
                                 f"in {crs_label(model.crs)}")
        corners = None
        try:
            corners = footprint(matrix, info.width, info.height)
        except InputDataError:
            if extent is None:
                raise
            feedback.push_warning("the ground plane's vanishing line crosses the photo; only "
                                  "the part in front of the camera is rectified")
        cell = params["CELL_SIZE"] or default_cell_size(matrix, info.width, info.height)
        bounds = extent.bounds if extent is not None else (
            float(corners[:, 0].min()), float(corners[:, 1].min()),
            float(corners[:, 0].max()), float(corners[:, 1].max()))
        grid = GridSpec.from_bounds(bounds, cell, model.crs, snap=True, name="CELL_SIZE")
        centre, _ = _apply(matrix, np.array([[info.width / 2.0, info.height / 2.0]]))
        coordinate_map = HomographyMap(np.linalg.inv(matrix), grid.transform,
                                       front=(float(centre[0, 0]), float(centre[0, 1])))
        with feedback.timed("warp"):
            stats = warp_to_geotiff(info.path, coordinate_map, grid, params["OUTPUT"],
                                    params["RESAMPLING"], params["OUTSIDE"], params["NODATA"],
                                    overviews=params["OVERVIEWS"], feedback=feedback, tags=tags)
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": {
            "model": model.model, "crs": crs_label(model.crs), "cell_size": cell,
            "width": grid.width, "height": grid.height, "bounds": list(grid.bounds),
            "footprint": None if corners is None else corners.tolist(),
            "resampling": params["RESAMPLING"], "outside": params["OUTSIDE"],
            "pixel_to_ground": matrix.tolist(), **stats.as_dict()}}

    @staticmethod
    def _gcps(params, model: RectificationModel, p2i, tags, feedback: Feedback):
        from toolbox.io.crs import crs_label

        used = model.control_points()
        if not used:
            raise InputDataError(f"TRANSFORM '{model.path}' lists no control points to embed")
        image = np.array([p["image"] for p in used], dtype="float64")
        if model.image_units == "mm":
            if p2i is None:
                raise ParameterError("PIXEL_TO_IMAGE", "is required to convert the control "
                                     "points' image mm to pixels for the GCPs")
            image, _ = _apply(np.linalg.inv(p2i), image)
        gcps = [(p["id"], float(c), float(r), float(p["ground"][0]), float(p["ground"][1]),
                 float(p.get("z") or 0.0)) for p, (c, r) in zip(used, image, strict=True)]
        write_gcp_geotiff(params["INPUT"].path, params["OUTPUT"], gcps, model.crs, feedback, tags)
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": {
            "model": model.model, "crs": crs_label(model.crs), "gcps": len(gcps),
            "gcp_ids": [g[0] for g in gcps]}}
