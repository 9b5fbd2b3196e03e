"""raster:hillshade - shaded relief of a DEM (Horn's slope, Lambertian illumination)."""

from __future__ import annotations

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.raster import build_overviews, geotiff_profile, iter_windows
from toolbox.parameters import Boolean, Integer, Number, OutputRaster, RasterLayer
from toolbox.registry import register
from toolbox.terrain.shading import (  # noqa: F401
    hillshade,
)


@register
class Hillshade(Algorithm):
    """Shaded relief of a DEM.

    Slope is computed with Horn's 3x3 weights and illuminated by a distant sun
    (Lambert's cosine law): ``shade = cos(zenith)·cos(slope) + sin(zenith)·sin(slope)·cos(azimuth -
    aspect)``. Output: Byte GeoTIFF, 1 (dark) to 255 (lit), 0 = nodata; beyond the raster
    edges the surface is extrapolated linearly (as ``gdaldem -compute_edges``); cells next to
    nodata are nodata. The DEM is
    read and written in tiles with a one-cell halo, so any size works in bounded memory.
    """

    id = "raster:hillshade"
    display_name = "Hillshade"
    group = "Raster"
    short_help = "Shaded relief (Horn slope, sun azimuth/altitude) of a DEM, as a Byte GeoTIFF."
    parameters = [
        RasterLayer("INPUT", "DEM (band 1; elevations in the CRS's vertical unit)"),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        Number("AZIMUTH", "sun azimuth, degrees clockwise from north", default=315.0,
               min_value=0, max_value=360),
        Number("ALTITUDE", "sun altitude above the horizon, degrees", default=45.0,
               min_value=0, max_value=90),
        Number("Z_FACTOR", "vertical exaggeration (and unit conversion)", default=1.0,
               min_value=0, min_exclusive=True),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        OutputRaster("OUTPUT", "hillshade GeoTIFF"),
    ]

    def check(self, params):
        if params["BAND"] > params["INPUT"].count:
            raise self.fail("BAND", f"must be <= {params['INPUT'].count} (bands of "
                            f"{params['INPUT']}), got {params['BAND']}")

    def process(self, params, feedback: Feedback):
        import rasterio

        info = params["INPUT"]
        if not info.georeferenced:
            raise InputDataError(f"INPUT {info} has no georeferencing: cell size unknown")
        cell_x, cell_y = info.res
        tiles = list(iter_windows(info.width, info.height, 512, halo=1))
        profile = geotiff_profile(info.width, info.height, 1, "uint8", info.crs, info.transform,
                                  nodata=0)
        with rasterio.Env(COMPRESS_OVERVIEW="DEFLATE"), rasterio.open(info.path) as src, \
                rasterio.open(params["OUTPUT"], "w", **profile) as dst:
            for tile in feedback.iterate(tiles, start=0, end=95):
                z = src.read(params["BAND"], window=tile.padded, masked=True)
                z = z.astype("float64").filled(np.nan)
                z = _pad_to_halo(z, tile)
                shade = hillshade(z, cell_x, cell_y, params["AZIMUTH"], params["ALTITUDE"],
                                  params["Z_FACTOR"])
                out = np.where(np.isnan(shade), 0, 1 + np.round(shade * 254)).astype("uint8")
                dst.write(out, 1, window=tile.core)
            if params["OVERVIEWS"]:
                build_overviews(dst)
        return {"OUTPUT": params["OUTPUT"]}


def _pad_to_halo(z: np.ndarray, tile) -> np.ndarray:
    """Give ``z`` a full one-cell halo, replicating edge cells where the raster ends."""
    core, padded = tile.core, tile.padded
    top = 1 - (core.row_off - padded.row_off)
    left = 1 - (core.col_off - padded.col_off)
    bottom = 1 - ((padded.row_off + padded.height) - (core.row_off + core.height))
    right = 1 - ((padded.col_off + padded.width) - (core.col_off + core.width))
    if min(z.shape) < 2:
        return np.pad(z, ((top, bottom), (left, right)), mode="edge")
    # linear extrapolation (2·edge - inner): exact on planes, like gdaldem -compute_edges
    return np.pad(z, ((top, bottom), (left, right)), mode="reflect", reflect_type="odd")
