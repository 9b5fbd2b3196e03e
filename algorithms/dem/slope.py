"""dem:slope - steepest slope of a DEM in degrees or percent (Horn's method, as gdaldem)."""

from __future__ import annotations

from toolbox.parameters import Enum, Number
from toolbox.parameters.outputs import Output
from toolbox.registry import register
from toolbox.ui.shading import ShadingAlgorithm, shading_parameters


@register
class Slope(ShadingAlgorithm):
    """Steepest slope of every DEM cell, as ``gdaldem slope`` (Horn 1981).

    The gradient comes from Horn's 3x3 weights, ``dz/dx = ((c+2f+i) - (a+2d+g)) / (8·cell_x)``
    and ``dz/dy = ((a+2b+c) - (g+2h+i)) / (8·cell_y)``; slope is ``atan(|grad z|)`` in degrees or
    ``100·|grad z|`` in percent. Output: Float32 GeoTIFF, nodata -9999. Beyond the raster edges
    the surface is extrapolated linearly (exact on planes); cells next to nodata
    are nodata. Tiled with a one-cell halo, so any size works in bounded memory.
    """

    id = "dem:slope"
    display_name = "Slope"
    short_help = "Slope of a DEM in degrees or percent (Horn's 3x3 method), Float32 GeoTIFF."
    parameters = shading_parameters(
        "DEM (band 1; elevations in the CRS's horizontal unit)", "slope GeoTIFF", [
            Enum("UNITS", "slope units", options=["degrees", "percent"], default="degrees"),
            Number("Z_FACTOR", "vertical exaggeration (and unit conversion)", default=1.0,
                   min_value=0, min_exclusive=True)])
    outputs = [Output("STATISTICS", "cell counts", "dict")]

    kernel_name = "slope"

    def kernel_options(self, params):
        return {"z_factor": params["Z_FACTOR"], "units": params["UNITS"]}

    def band_meaning(self, params):
        if params["UNITS"] == "percent":
            return "slope (percent)", "percent"
        return "slope (degrees)", "degree"
