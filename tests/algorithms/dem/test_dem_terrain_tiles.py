"""dem:slope, dem:aspect, dem:hillshade on the raster engine: a run cut into many small tiles
(edges and a nodata hole crossing tile borders) writes exactly the same cells as a one-tile
run; COG output passes the COG layout check."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.raster.writer import cog_problems, write_raster


@pytest.fixture(scope="module")
def rough_dem(tmp_path_factory):
    rows, cols = 53, 70  # not a multiple of the 16-cell tiles
    y, x = np.mgrid[0:rows, 0:cols].astype("float64")
    z = 200 + 15 * np.sin(x / 7.0) * np.cos(y / 5.0) + 0.3 * x + 0.02 * (x - 30) * (y - 20)
    z[20:27, 14:19] = -9999.0  # a hole across the tile border at column 16
    path = tmp_path_factory.mktemp("rough") / "rough.tif"
    write_raster(path, z.astype("float32"), Affine(2.0, 0, 1_688_000, 0, -3.0, 4_799_500),
                 "EPSG:3003", nodata=-9999.0)
    return path


def _run(algorithm, dem, out, **params):
    toolbox.run(algorithm, {"INPUT": dem, "OUTPUT": out} | params)
    with rasterio.open(out) as ds:
        return ds.read(1), ds.nodata


@pytest.mark.parametrize("algorithm,params", [
    ("dem:slope", {"UNITS": "percent", "Z_FACTOR": 2.0}),
    ("dem:aspect", {}),
    ("dem:hillshade", {"AZIMUTH": 200.0, "ALTITUDE": 30.0}),
])
def test_tiled_run_equals_one_tile_run(rough_dem, tmp_path, algorithm, params):
    tiled, nodata = _run(algorithm, rough_dem, tmp_path / "tiled.tif", TILE_SIZE=16, **params)
    whole, _ = _run(algorithm, rough_dem, tmp_path / "whole.tif", TILE_SIZE=4096, **params)
    np.testing.assert_array_equal(tiled, whole)
    missing = tiled == nodata
    assert missing[20:27, 14:19].all()  # the hole and its neighbours are nodata
    assert missing[19, 13] and missing[27, 19]
    assert not missing[0].any() and not missing[:, -1].any()  # edges extrapolated, not nodata


def test_cog_output(rough_dem, tmp_path):
    out = tmp_path / "slope_cog.tif"
    plain, _ = _run("dem:slope", rough_dem, tmp_path / "plain.tif")
    cog, _ = _run("dem:slope", rough_dem, out, COG=True)
    np.testing.assert_array_equal(cog, plain)
    assert cog_problems(out) == []
