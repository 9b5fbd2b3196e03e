"""dem:slope, dem:aspect, dem:hillshade against gdaldem on the demo's real (jacksboro-derived)
DEM, computed in tiles smaller than the raster; exact values on a plane; the raster:hillshade
alias."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.demo.samples.terrain import CRS, terrain
from toolbox.raster.writer import write_raster
from toolbox.registry import get

GDALDEM = shutil.which("gdaldem")
needs_gdaldem = pytest.mark.skipif(
    GDALDEM is None, reason="gdaldem not found: install gdal-bin (apt-get install gdal-bin) to "
    "compare dem:slope/aspect/hillshade with GDAL")
TILE = 96  # the 344 x 403 DEM is cut into 20 tiles


@pytest.fixture(scope="module")
def real_dem(tmp_path_factory):
    z, transform = terrain()
    path = tmp_path_factory.mktemp("terrain") / "siena_dem.tif"
    write_raster(path, z, transform, CRS, nodata=-9999.0)
    assert z.shape[0] > 3 * TILE and z.shape[1] > 3 * TILE
    return path


def gdaldem(tmp_path, mode, dem, *args):
    out = tmp_path / f"gdal_{mode}.tif"
    subprocess.run([GDALDEM, mode, str(dem), str(out), "-q", *args], check=True)
    with rasterio.open(out) as ds:
        return ds.read(1, masked=True)


def ours(tmp_path, algorithm, dem, **params):
    out = tmp_path / f"{algorithm.replace(':', '_')}.tif"
    toolbox.run(algorithm, {"INPUT": dem, "OUTPUT": out, "TILE_SIZE": TILE} | params)
    with rasterio.open(out) as ds:
        assert ds.crs.to_epsg() == 3003
        return ds.read(1), ds.nodata


def interior(a):
    return a[1:-1, 1:-1]


@needs_gdaldem
@pytest.mark.parametrize("units,flag,tol", [("degrees", [], 1e-3), ("percent", ["-p"], 1e-3)])
def test_slope_equals_gdaldem(real_dem, tmp_path, units, flag, tol):
    mine, nodata = ours(tmp_path, "dem:slope", real_dem, UNITS=units)
    ref = gdaldem(tmp_path, "slope", real_dem, *flag)
    assert nodata == -9999.0
    # gdaldem leaves the border cells nodata (no -compute_edges); everything inside must agree
    assert not interior(ref.mask).any()
    diff = np.abs(interior(mine) - interior(ref.data))
    assert diff.max() < tol, f"max |slope - gdaldem| = {diff.max()} {units}"
    assert interior(mine).max() > (5 if units == "degrees" else 8)  # a real, sloping terrain


@needs_gdaldem
def test_aspect_equals_gdaldem(real_dem, tmp_path):
    mine, _ = ours(tmp_path, "dem:aspect", real_dem)
    ref = gdaldem(tmp_path, "aspect", real_dem)
    slope_deg, _ = ours(tmp_path, "dem:slope", real_dem)
    m, r = interior(mine), interior(ref.filled(-9999.0))
    # the same flat cells, but for rounding: gdaldem works in float32, so a gradient of a few
    # 1e-5 may be zero for one and not the other
    differ = (m == -9999.0) != (r == -9999.0)
    assert (m == -9999.0).sum() > 100 and (interior(slope_deg)[differ] < 1e-3).all()
    # aspect of near-flat cells is ill-conditioned under gdaldem's float32 rounding
    steep = interior(slope_deg) > 1.0
    d = np.abs((m - r + 180.0) % 360.0 - 180.0)[steep]
    assert steep.sum() > 0.5 * steep.size
    assert d.max() < 0.05 and np.percentile(d, 99) < 0.005, (d.max(), np.percentile(d, 99))


@needs_gdaldem
@pytest.mark.parametrize("azimuth,altitude", [(315, 45), (120, 30)])
def test_hillshade_equals_gdaldem(real_dem, tmp_path, azimuth, altitude):
    mine, nodata = ours(tmp_path, "dem:hillshade", real_dem, AZIMUTH=azimuth,
                        ALTITUDE=altitude)
    ref = gdaldem(tmp_path, "hillshade", real_dem, "-az", str(azimuth), "-alt", str(altitude))
    diff = np.abs(interior(mine).astype(int) - interior(ref.data).astype(int))
    assert nodata == 0 and diff.max() <= 1, diff.max()  # one grey level (rounding)
    assert np.unique(interior(mine)).size > 100


def test_slope_and_aspect_of_a_plane_are_exact(plane_dem, tmp_path):
    path, sx, sy = plane_dem  # dz/dx = 0.2 east, dz/dy = -0.1 north: downhill faces west-north
    out = tmp_path / "slope.tif"
    toolbox.run("dem:slope", {"INPUT": path, "OUTPUT": out, "TILE_SIZE": 16})
    pct = tmp_path / "slope_pct.tif"
    toolbox.run("dem:slope", {"INPUT": path, "OUTPUT": pct, "UNITS": "percent"})
    asp = tmp_path / "aspect.tif"
    toolbox.run("dem:aspect", {"INPUT": path, "OUTPUT": asp, "TILE_SIZE": 16})
    rise = np.hypot(sx, sy)
    with rasterio.open(out) as a, rasterio.open(pct) as b, rasterio.open(asp) as c:
        np.testing.assert_allclose(a.read(1), np.degrees(np.arctan(rise)), atol=1e-3)  # float32 DEM
        np.testing.assert_allclose(b.read(1), 100 * rise, atol=5e-3)
        # downhill direction (-0.2, +0.1): azimuth atan2(east=-0.2, north=0.1)
        np.testing.assert_allclose(c.read(1), np.degrees(np.arctan2(-sx, -sy)) % 360, atol=5e-3)


def test_aspect_of_a_north_facing_slope_is_zero_not_minus_zero(tmp_path):
    """A slope facing due north has aspect 0 as gdaldem writes it; it was -0.0 (the sign of
    arctan2(-0.0, y)), a value that prints as "-0" in a GeoTIFF's statistics and identify."""
    from affine import Affine

    z = 100.0 + 0.5 * np.arange(20)[:, None] + np.zeros((20, 20))  # rising to the south
    path = tmp_path / "north.tif"
    write_raster(path, z.astype("float32"), Affine(1.0, 0, 1688000.0, 0, -1.0, 4800000.0), CRS,
                 nodata=-9999)
    out = tmp_path / "aspect.tif"
    toolbox.run("dem:aspect", {"INPUT": path, "OUTPUT": out})
    with rasterio.open(out) as src:
        values = src.read(1, masked=True).compressed()
    assert len(values) and np.all(values == 0) and not np.signbit(values).any()


@pytest.mark.parametrize("dtype", ["float64", "int16"])
def test_dems_of_other_types_are_read_without_loss(tmp_path, dtype):
    # float32 DEMs (and 8/16-bit ones, which float32 holds exactly) are read as float32; a
    # float64 DEM stays float64: a plane 5,000 km up keeps its slope (float32 would step 0.5 m)
    from affine import Affine

    rows, cols, cell = 40, 50, 2.0
    step_x, step_y = (0.4, 0.2) if dtype == "float64" else (2, 1)  # per cell, east and south
    base = 5e6 if dtype == "float64" else 1000
    z = base + step_x * np.arange(cols)[None, :] + step_y * np.arange(rows)[:, None]
    path = tmp_path / f"plane_{dtype}.tif"
    write_raster(path, z.astype(dtype), Affine(cell, 0, 1688000.0, 0, -cell, 4800000.0), CRS,
                 nodata=-9999)
    out = tmp_path / "slope.tif"
    toolbox.run("dem:slope", {"INPUT": path, "OUTPUT": out, "TILE_SIZE": 16})
    with rasterio.open(out) as ds:
        got = ds.read(1)
    expected = np.degrees(np.arctan(np.hypot(step_x / cell, step_y / cell)))
    np.testing.assert_allclose(got, expected, atol=1e-3)


@needs_gdaldem
def test_raster_hillshade_alias_equals_gdaldem(real_dem, tmp_path):
    """The alias runs dem:hillshade: its values on the real DEM are gdaldem's (not just a file)."""
    assert get("raster:hillshade") is get("dem:hillshade")
    mine, nodata = ours(tmp_path, "raster:hillshade", real_dem, AZIMUTH=300.0, ALTITUDE=40.0)
    ref = gdaldem(tmp_path, "hillshade", real_dem, "-az", "300", "-alt", "40")
    diff = np.abs(interior(mine).astype(int) - interior(ref.data).astype(int))
    assert nodata == 0 and diff.max() <= 1, diff.max()  # one grey level (rounding)
    assert np.unique(interior(mine)).size > 100


@pytest.mark.parametrize("algorithm", ["dem:hillshade", "dem:slope", "dem:aspect"])
def test_band_beyond_the_dem_is_refused_before_any_output(plane_dem, tmp_path, algorithm):
    out = tmp_path / "out.tif"
    with pytest.raises(toolbox.ParameterError, match="BAND.*must be <= 1"):
        toolbox.run(algorithm, {"INPUT": plane_dem[0], "BAND": 2, "OUTPUT": out})
    assert not out.exists()


@pytest.mark.parametrize("flip", ["south_up", "east_to_west"])
@pytest.mark.parametrize("algorithm", ["dem:aspect", "dem:hillshade", "dem:slope"])
def test_a_dem_stored_the_other_way_gives_the_same_map(real_dem, tmp_path, algorithm, flip):
    """The same terrain stored south-up (rows south to north, a positive transform.e) or east
    to west: aspect and shading keep their map directions (gdaldem's would be mirrored), equal
    to the north-up run (itself equal to gdaldem's above) cell for cell on the same ground."""
    from affine import Affine

    with rasterio.open(real_dem) as ds:
        z, t, rows, cols = ds.read(1), ds.transform, ds.height, ds.width
    if flip == "south_up":
        flipped, transform = z[::-1], Affine(t.a, 0, t.c, 0, -t.e, t.f + t.e * rows)
    else:
        flipped, transform = z[:, ::-1], Affine(-t.a, 0, t.c + t.a * cols, 0, t.e, t.f)
    path = tmp_path / f"{flip}.tif"
    write_raster(path, flipped, transform, CRS, nodata=-9999.0)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    north_up, _ = ours(tmp_path / "a", algorithm, real_dem)
    other, _ = ours(tmp_path / "b", algorithm, path)
    back = other[::-1] if flip == "south_up" else other[:, ::-1]
    if algorithm == "dem:aspect":  # angles: the same within float32 rounding, across 0/360
        diff = np.abs((back.astype(float) - north_up + 180) % 360 - 180)
        assert np.nanmax(np.where(north_up == -9999, 0, diff)) < 1e-3
        assert np.array_equal(back == -9999, north_up == -9999)
    else:
        np.testing.assert_allclose(back, north_up, atol=1e-4)


@pytest.mark.parametrize("algorithm", ["dem:hillshade", "dem:slope", "dem:aspect"])
def test_a_rotated_dem_is_refused(tmp_path, algorithm):
    from affine import Affine

    path = tmp_path / "rotated.tif"
    write_raster(path, np.ones((20, 20), "float32"),
                 Affine(1.0, 0.2, 1688000.0, 0.1, -1.0, 4800000.0), CRS, nodata=-9999.0)
    out = tmp_path / "out.tif"
    with pytest.raises(toolbox.InputDataError, match="rotated geotransform"):
        toolbox.run(algorithm, {"INPUT": path, "OUTPUT": out})
    assert not out.exists()
