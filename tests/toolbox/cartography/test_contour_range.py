"""The contour levels' range read in tiles (from the file, or from the band in memory) is
numpy's nanmin/nanmax of the whole band: several tiles, partial edge tiles, nodata and an
all-nodata tile."""

from __future__ import annotations

import numpy as np
import rasterio
from affine import Affine

from toolbox.cartography.contour_io import grid_range, raster_range


def test_tiled_range_is_the_whole_bands(tmp_path):
    z = np.random.default_rng(4).normal(100.0, 30.0, (150, 230))
    z[:64, :64] = -9999.0  # a whole tile of nodata
    z[100:, 200:] = -9999.0
    path = tmp_path / "dem.tif"
    with rasterio.open(path, "w", driver="GTiff", width=230, height=150, count=1,
                       dtype="float64", nodata=-9999.0,
                       transform=Affine(1, 0, 1688000, 0, -1, 4799000)) as dst:
        dst.write(z, 1)
    valid = np.where(z == -9999.0, np.nan, z)
    expected = (np.nanmin(valid), np.nanmax(valid))
    with rasterio.open(path) as src:
        assert raster_range(src, 1, 64)[:2] == expected
    assert grid_range(valid) == expected
