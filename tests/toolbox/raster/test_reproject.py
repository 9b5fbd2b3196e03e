"""The one reprojection (toolbox.raster.reproject) against GDAL's gdalwarp on the same grid: a
DEM in Monte Mario / Italy 1 (EPSG:3003) with a nodata hole read onto a UTM 32N (EPSG:32632)
grid, and an RGBA ortho whose alpha band says where it has data."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio
from affine import Affine
from pyproj import CRS, Transformer

from toolbox.raster.reproject import default_grid, mask_onto, read_onto

pytestmark = pytest.mark.skipif(shutil.which("gdalwarp") is None, reason="needs gdalwarp")

UTM = CRS.from_epsg(32632)


@pytest.fixture
def dem(tmp_path):
    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:200, 0:250]
    z = (200 + 30 * np.sin(xx / 37.0) + 20 * np.cos(yy / 23.0)
         + rng.normal(0, 0.5, xx.shape)).astype("float32")
    z[80:95, 100:140] = -9999  # a hole
    path = tmp_path / "dem3003.tif"
    with rasterio.open(path, "w", driver="GTiff", width=250, height=200, count=1,
                       dtype="float32", crs="EPSG:3003", nodata=-9999,
                       transform=Affine(10, 0, 1680000, 0, -10, 4800000)) as dst:
        dst.write(z, 1)
    return path


def utm_grid(x, y, cell, width, height):
    """A UTM grid whose top-left corner is EPSG:3003's (x, y), rounded to metres."""
    e, n = Transformer.from_crs(3003, 32632, always_xy=True).transform(x, y)
    return Affine(cell, 0, round(e), 0, -cell, round(n)), width, height


def gdalwarp(tmp_path, source, transform, width, height, resampling, *extra):
    out = tmp_path / f"gdalwarp_{resampling}.tif"
    xmin, ymax = transform.c, transform.f
    xmax, ymin = xmin + width * transform.a, ymax + height * transform.e
    subprocess.run(["gdalwarp", "-q", "-overwrite", "-t_srs", "EPSG:32632", "-te", str(xmin),
                    str(ymin), str(xmax), str(ymax), "-ts", str(width), str(height), "-r",
                    resampling, "-et", "0.01", *extra, str(source), str(out)], check=True)
    return out


@pytest.mark.parametrize("resampling", ["nearest", "bilinear", "cubic"])
def test_dem_onto_another_crs_is_gdalwarp(tmp_path, dem, resampling):
    t, w, h = utm_grid(1680300, 4799700, 7.0, 260, 180)
    with rasterio.open(dem) as src:
        ours = read_onto(src, t, w, h, UTM, indexes=1, resampling=resampling)[0]
    with rasterio.open(gdalwarp(tmp_path, dem, t, w, h, resampling, "-dstnodata", "nan")) as ref:
        theirs = ref.read(1)
    assert ours.dtype == np.float32
    # same cells without data (the hole, and beyond the DEM's east edge)
    np.testing.assert_array_equal(np.isnan(ours), np.isnan(theirs))
    assert np.isnan(ours).sum() > 300
    np.testing.assert_allclose(ours, theirs, atol=1e-3, equal_nan=True)


def test_alpha_mask_onto_another_crs_is_gdalwarp(tmp_path):
    rng = np.random.default_rng(2)
    rgba = rng.integers(0, 255, (4, 120, 150), dtype=np.uint8)
    rgba[3] = 255
    rgba[3, :, :20] = 0
    rgba[3, 70:, 90:] = 0
    path = tmp_path / "ortho.tif"
    with rasterio.open(path, "w", driver="GTiff", width=150, height=120, count=4,
                       dtype="uint8", crs="EPSG:3003", photometric="RGB", alpha="YES",
                       transform=Affine(1, 0, 1680000, 0, -1, 4800000)) as dst:
        dst.write(rgba)
    t, w, h = utm_grid(1679990, 4800010, 0.8, 200, 170)  # beyond the ortho on every side
    with rasterio.open(path) as src:
        data = read_onto(src, t, w, h, UTM, resampling="nearest")
        valid = mask_onto(src, t, w, h, UTM)
    with rasterio.open(gdalwarp(tmp_path, path, t, w, h, "near")) as ref:
        theirs = ref.read()
    assert data.shape == (3, h, w)  # the alpha band is not data
    np.testing.assert_array_equal(valid, theirs[3] > 0)
    assert 0.3 < valid.mean() < 0.8
    np.testing.assert_array_equal(data[:, valid], theirs[:3, valid])


def test_default_grid_is_gdalwarps(tmp_path, dem):
    out = tmp_path / "default.tif"
    subprocess.run(["gdalwarp", "-q", "-t_srs", "EPSG:32632", str(dem), str(out)], check=True)
    with rasterio.open(dem) as src, rasterio.open(out) as ref:
        t, w, h = default_grid(src, UTM)
        assert (w, h) == (ref.width, ref.height)
        np.testing.assert_allclose(np.array(t)[:6], np.array(ref.transform)[:6], rtol=0,
                                   atol=1e-6)


def test_unknown_resampling_is_refused(dem):
    with rasterio.open(dem) as src, pytest.raises(ValueError, match="bicubicle"):
        read_onto(src, src.transform, 4, 4, resampling="bicubicle")
