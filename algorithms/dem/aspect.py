"""dem:aspect - direction a DEM's slope faces, degrees clockwise from north (as gdaldem)."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Integer, Output, OutputRaster, RasterLayer
from toolbox.registry import register


@register
class Aspect(Algorithm):
    """Aspect of every DEM cell, as ``gdaldem aspect`` (Horn 1981).

    The downhill direction of Horn's gradient ``(-dz/dx, -dz/dy)``, in degrees clockwise from
    north in [0, 360): 0 faces north, 90 east. Flat cells (zero gradient) have no aspect and are
    written as nodata -9999, as gdaldem does without ``-zero_for_flat``. Float32 GeoTIFF. Edges
    are extrapolated linearly, cells next to nodata are nodata; tiled with a one-cell halo.
    """

    id = "dem:aspect"
    display_name = "Aspect"
    group = "DEM terrain"
    short_help = "Aspect of a DEM, degrees clockwise from north (Horn's 3x3 method)."
    parameters = [
        RasterLayer("INPUT", "DEM (band 1)"),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        Integer("TILE_SIZE", "tile side in cells", default=512, min_value=16),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        OutputRaster("OUTPUT", "aspect GeoTIFF"),
    ]
    outputs = [Output("STATISTICS", "cell counts", "dict")]

    def check(self, params):
        from toolbox.terrain.shading import check_dem_params

        check_dem_params(params)

    def process(self, params, feedback: Feedback):
        from toolbox.terrain.shading import aspect, shade_raster

        stats = shade_raster(params["INPUT"], params["BAND"], params["OUTPUT"], aspect,
                             "float32", -9999.0, feedback, params["TILE_SIZE"],
                             params["OVERVIEWS"], params["COG"])
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
