"""dem:hillshade - shaded relief of a DEM (Horn's slope, Lambertian illumination)."""

from __future__ import annotations

from toolbox.parameters import Number
from toolbox.registry import register
from toolbox.ui.shading import ShadingAlgorithm, shading_parameters


@register
class Hillshade(ShadingAlgorithm):
    """Shaded relief of a DEM, as ``gdaldem hillshade``.

    Slope and aspect come from Horn's 3x3 weights; a distant sun lights the surface by
    Lambert's cosine law: ``shade = cos(zenith)·cos(slope) + sin(zenith)·sin(slope)·cos(azimuth -
    aspect)``. Output: Byte GeoTIFF, 1 (dark) to 255 (lit), 0 = nodata. Beyond the raster edges the
    surface is extrapolated linearly (exact on planes); cells next to nodata are
    nodata. The DEM is read and written in tiles with a one-cell halo, so any size works in
    bounded memory (the shared raster engine). Formerly ``raster:hillshade`` (that id still works).
    """

    id = "dem:hillshade"
    display_name = "Hillshade"
    short_help = "Shaded relief (Horn slope, sun azimuth/altitude) of a DEM, as a Byte GeoTIFF."
    parameters = shading_parameters(
        "DEM (band 1; elevations in the CRS's horizontal unit)", "hillshade GeoTIFF", [
            Number("AZIMUTH", "sun azimuth, degrees clockwise from north", default=315.0,
                   min_value=0, max_value=360),
            Number("ALTITUDE", "sun altitude above the horizon, degrees", default=45.0,
                   min_value=0, max_value=90),
            Number("Z_FACTOR", "vertical exaggeration (and unit conversion)", default=1.0,
                   min_value=0, min_exclusive=True)])

    kernel_name = "hillshade_bytes"
    dtype, nodata = "uint8", 0

    def kernel_options(self, params):
        return {"azimuth": params["AZIMUTH"], "altitude": params["ALTITUDE"],
                "z_factor": params["Z_FACTOR"]}
