"""dem:slope - steepest slope of a DEM in degrees or percent (Horn's method, as gdaldem)."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Enum, Integer, Number, Output, OutputRaster, RasterLayer
from toolbox.registry import register


@register
class Slope(Algorithm):
    """Steepest slope of every DEM cell, as ``gdaldem slope`` (Horn 1981).

    The gradient comes from Horn's 3x3 weights, ``dz/dx = ((c+2f+i) - (a+2d+g)) / (8·cell_x)``
    and ``dz/dy = ((a+2b+c) - (g+2h+i)) / (8·cell_y)``; slope is ``atan(|grad z|)`` in degrees or
    ``100·|grad z|`` in percent. Output: Float32 GeoTIFF, nodata -9999. Beyond the raster edges
    the surface is extrapolated linearly (exact on planes); cells next to nodata
    are nodata. Tiled with a one-cell halo, so any size works in bounded memory.
    """

    id = "dem:slope"
    display_name = "Slope"
    group = "DEM terrain"
    short_help = "Slope of a DEM in degrees or percent (Horn's 3x3 method), Float32 GeoTIFF."
    parameters = [
        RasterLayer("INPUT", "DEM (band 1; elevations in the CRS's horizontal unit)"),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        Enum("UNITS", "slope units", options=["degrees", "percent"], default="degrees"),
        Number("Z_FACTOR", "vertical exaggeration (and unit conversion)", default=1.0,
               min_value=0, min_exclusive=True),
        Integer("TILE_SIZE", "tile side in cells", default=512, min_value=16),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        OutputRaster("OUTPUT", "slope GeoTIFF"),
    ]
    outputs = [Output("STATISTICS", "cell counts", "dict")]

    def check(self, params):
        from toolbox.terrain.shading import check_dem_params

        check_dem_params(params)

    def process(self, params, feedback: Feedback):
        from functools import partial

        from toolbox.terrain.shading import shade_raster, slope

        kernel = partial(slope, z_factor=params["Z_FACTOR"], units=params["UNITS"])
        stats = shade_raster(params["INPUT"], params["BAND"], params["OUTPUT"], kernel,
                             "float32", -9999.0, feedback, params["TILE_SIZE"],
                             params["OVERVIEWS"], params["COG"])
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
