"""dem:hillshade - shaded relief of a DEM (Horn's slope, Lambertian illumination)."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Integer, Number, OutputRaster, RasterLayer
from toolbox.registry import register


@register
class Hillshade(Algorithm):
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
    group = "DEM terrain"
    short_help = "Shaded relief (Horn slope, sun azimuth/altitude) of a DEM, as a Byte GeoTIFF."
    parameters = [
        RasterLayer("INPUT", "DEM (band 1; elevations in the CRS's horizontal unit)"),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        Number("AZIMUTH", "sun azimuth, degrees clockwise from north", default=315.0,
               min_value=0, max_value=360),
        Number("ALTITUDE", "sun altitude above the horizon, degrees", default=45.0,
               min_value=0, max_value=90),
        Number("Z_FACTOR", "vertical exaggeration (and unit conversion)", default=1.0,
               min_value=0, min_exclusive=True),
        Integer("TILE_SIZE", "tile side in cells", default=512, min_value=16),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        OutputRaster("OUTPUT", "hillshade GeoTIFF"),
    ]

    def check(self, params):
        from toolbox.terrain.shading import check_dem_params

        check_dem_params(params)

    def process(self, params, feedback: Feedback):
        from functools import partial

        from toolbox.terrain.shading import hillshade_bytes, shade_raster

        kernel = partial(hillshade_bytes, azimuth=params["AZIMUTH"],
                         altitude=params["ALTITUDE"], z_factor=params["Z_FACTOR"])
        shade_raster(params["INPUT"], params["BAND"], params["OUTPUT"], kernel, "uint8", 0,
                     feedback, params["TILE_SIZE"], params["OVERVIEWS"], params["COG"])
        return {"OUTPUT": params["OUTPUT"]}

