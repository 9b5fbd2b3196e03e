"""orientation:monoplot - ground points from image points of one photo, on a DEM or a height."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.ortho.vertical import project_raster_crs
from toolbox.parameters import Boolean, Enum, Integer, Number
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.photogrammetry.collinearity import NO_INTERSECTION, OK
from toolbox.photogrammetry.collinearity import STATUS_NAMES as RAY_STATUS
from toolbox.photogrammetry.photo import off_image
from toolbox.photogrammetry.surface import dem_height_range, surface_for_photo
from toolbox.photogrammetry.tables import write_json
from toolbox.registry import register
from toolbox.ui.photogrammetry import (
    dem_parameters,
    measured_inputs,
    measured_photos,
    project_parameter,
    report_output,
    table_parameters,
)

OUTSIDE_IMAGE = max(RAY_STATUS) + 1  # a pixel off the photo's image: not a ray of the photo
STATUS_NAMES = {**RAY_STATUS, OUTSIDE_IMAGE: "outside_image"}


@register
class Monoplot(Algorithm):
    """Monoplotting: intersect the rays of image points with the terrain.

    INPUT lists image points (``photo``, optional ``point_id``, ``col_px``/``row_px`` or
    ``x_mm``/``y_mm``; see orientation:intersect). Each ray (collinearity, domain brief section 4,
    after the interior orientation, the principal point and radial distortion) is intersected with
    the DEM, bilinear between cell centres (the edge value held across the outer half cell):
    METHOD ``march`` walks down the ray from the DEM's top in half-cell steps and refines the
    first crossing (Illinois regula falsi) to TOLERANCE; it finds the first visible surface
    point and converges on steep terrain (a ray rising from a camera below the DEM's top, up a
    slope, is walked up from the camera). ``fixed_point`` is the
    classical iteration Z <- DEM(X(Z), Y(Z)), which fails where the terrain is steeper than the
    ray (reported as not_converged). Without a DEM the rays meet the plane Z = HEIGHT.

    OUTPUT layer ``points`` (PointZ): point_id, photo, status (ok, outside_dem, dem_nodata,
    not_converged, ray_not_descending, no_intersection; outside_image for a pixel off the photo's
    image, measured on another raster), iterations. Rays that do not meet the DEM are flagged
    rows without geometry, never silent NaNs; FAIL_ON_MISS=true makes them an error.
    """

    id = "orientation:monoplot"
    display_name = "Monoplotting (image to ground on a DEM)"
    group = "Orientation"
    short_help = "Ground points (PointZ) of image points of oriented photos, on a DEM or a height."
    parameters = [
        project_parameter(),
        *table_parameters("INPUT", "image points (CSV or GeoPackage table)"),
        Enum("COORDINATES", "measurement columns: auto, pixel (col_px/row_px), image (x_mm/y_mm)",
             options=("auto", "pixel", "image"), default="auto"),
        *dem_parameters(optional=True),
        Number("HEIGHT", "plane height when no DEM is given, CRS units", optional=True),
        Enum("METHOD", "ray/DEM intersection", options=("march", "fixed_point"), default="march"),
        Number("TOLERANCE", "accepted height misclosure |Z_ray - Z_dem|, CRS units", default=1e-6,
               min_value=0, min_exclusive=True),
        Integer("MAX_ITERATIONS", "refinement or fixed-point iterations", default=100,
                min_value=1),
        Boolean("FAIL_ON_MISS", "a ray that misses the terrain is an error", default=False),
        # duplicate-ok: declared layers and fields (a spec read by the docs and QGIS, not logic)
        OutputVector("OUTPUT", "GeoPackage with the layer points", layers=[
            Layer("points", "Point Z", [
                ("point_id", "string"), ("photo", "string"),
                ("status", "string", "ok, outside_dem, dem_nodata or no_intersection"),
                ("iterations", "integer", "iterations to converge")],
                "ground points of the image measurements (empty geometry when not found)")]),
        report_output("JSON summary"),
    ]
    outputs = [Output("STATISTICS", "points per status", "json")]

    def check(self, params: dict[str, Any]) -> None:
        if params["DEM"] is None and params["HEIGHT"] is None:
            raise self.fail("HEIGHT", "is required when no DEM is given, got nothing")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import geopandas as gpd
        import shapely

        from toolbox.io.vector_write import write_layers

        project, (ids, photo_ids, xy, kind), _ = measured_inputs(params, on_image=False)
        dem = params["DEM"]
        crs = project_raster_crs(project.crs, None if dem is None else dem.crs,
                                 bounds=None if dem is None else dem.bounds)
        measured_photos(project, photo_ids)
        xyz = np.full((len(ids), 3), np.nan)
        status = np.full(len(ids), OK, dtype=np.int8)
        iterations = np.zeros(len(ids), dtype=np.int32)
        if kind == "pixel":  # measured on another raster: no ray through this photo
            status[off_image(project.photos, photo_ids, xy)] = OUTSIDE_IMAGE
        z_range = None if dem is None else dem_height_range(dem, params["BAND"])
        groups = list(dict.fromkeys(photo_ids))
        for pid in feedback.iterate(groups, start=0, end=90):
            photo = project.photos[pid]
            rows = np.array([k for k, p in enumerate(photo_ids)
                             if p == pid and status[k] != OUTSIDE_IMAGE], dtype=int)
            if not len(rows):
                continue
            pts = xy[rows]
            if dem is None:
                xyz[rows] = photo.pixel_to_ground(pts, params["HEIGHT"], invalid="nan") \
                    if kind == "pixel" else photo.image_to_ground(pts, params["HEIGHT"],
                                                                  invalid="nan")
                status[rows] = np.where(np.isfinite(xyz[rows, 0]), OK, NO_INTERSECTION)
                continue
            surface = surface_for_photo(dem, photo, params["BAND"], z_range)
            options = {"method": params["METHOD"], "tolerance": params["TOLERANCE"],
                       "max_iterations": params["MAX_ITERATIONS"]}
            result = photo.monoplot_pixels(pts, surface, **options) if kind == "pixel" else \
                photo.monoplot_image(pts, surface, **options)
            xyz[rows], status[rows], iterations[rows] = result.xyz, result.status, \
                result.iterations
        values, counts = np.unique(status, return_counts=True)
        by_status = {STATUS_NAMES[int(v)]: int(n) for v, n in zip(values, counts, strict=True)}
        failed = int(np.count_nonzero(status != OK))
        if failed:
            message = f"{failed} of {len(ids)} rays did not meet the terrain: {by_status}"
            if params["FAIL_ON_MISS"]:
                first = int(np.flatnonzero(status != OK)[0])
                raise InputDataError(f"{message} (first: point {ids[first]!r} on photo "
                                     f"{photo_ids[first]!r}, {STATUS_NAMES[int(status[first])]})")
            feedback.push_warning(message)
        records = [{"point_id": i, "photo": p, "status": STATUS_NAMES[int(s)],
                    "iterations": int(it), "geometry": shapely.Point(v) if s == OK else None}
                   for i, p, s, it, v in zip(ids, photo_ids, status, iterations, xyz, strict=True)]
        write_layers(params["OUTPUT"],
                     {"points": gpd.GeoDataFrame(records, geometry="geometry", crs=crs)},
                     crs=crs, geometry_types={"points": "Point Z"})
        stats = {"points": len(ids), "status": by_status, "method": params["METHOD"]
                 if dem is not None else "plane"}
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {"algorithm": self.id, "statistics": stats})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}
