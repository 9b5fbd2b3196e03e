"""Small DEMs read whole once (toolbox.photogrammetry.surface.read_dem_cells): every window
sliced from memory equals GDAL's windowed read of the file (masked, nodata -> NaN), a DEM
rewritten in place is read again, a large one is read window by window."""

from __future__ import annotations

import os

import numpy as np
import pytest
import rasterio
from affine import Affine
from rasterio.windows import Window

from toolbox.photogrammetry import surface as surface_module
from toolbox.photogrammetry.surface import read_dem_cells


def write_dem(path, values, nodata=-9999.0):
    with rasterio.open(path, "w", driver="GTiff", width=values.shape[1], height=values.shape[0],
                       count=1, dtype="float32", nodata=nodata, crs="EPSG:32633",
                       transform=Affine(2, 0, 500000, 0, -2, 5000000), tiled=True,
                       blockxsize=64, blockysize=64, compress="deflate") as dst:
        dst.write(values.astype("float32"), 1)


def gdal_window(path, window):
    with rasterio.open(path) as src:
        return src.read(1, window=window, masked=True).astype("float64").filled(np.nan)


WINDOWS = [Window(0, 0, 150, 130), Window(17, 33, 40, 51), Window(149, 129, 1, 1),
           Window(60, 0, 90, 130)]


@pytest.fixture
def dem(tmp_path):
    rng = np.random.default_rng(11)
    values = rng.uniform(100, 900, (130, 150))
    values[40:60, 70:90] = -9999.0
    path = tmp_path / "dem.tif"
    write_dem(path, values)
    surface_module._WHOLE_DEM.clear()
    yield path, values
    surface_module._WHOLE_DEM.clear()


@pytest.mark.parametrize("small", [True, False])
def test_windows_equal_gdal_reads(dem, small, monkeypatch):
    path, _ = dem
    if not small:
        monkeypatch.setattr(surface_module, "SMALL_DEM_CELLS", 100)
    for window in WINDOWS:
        cells = read_dem_cells(path, 1, window, (130, 150))
        truth = gdal_window(path, window)
        assert cells.dtype == np.float64 and cells.shape == truth.shape
        np.testing.assert_array_equal(cells, truth)
    assert np.isnan(read_dem_cells(path, 1, Window(70, 40, 20, 20), (130, 150))).all()
    assert len(surface_module._WHOLE_DEM) == (1 if small else 0)
    cells = read_dem_cells(path, 1, WINDOWS[1], (130, 150))
    cells[:] = 0  # a new array: the copy in memory is not changed
    np.testing.assert_array_equal(read_dem_cells(path, 1, WINDOWS[1], (130, 150)),
                                  gdal_window(path, WINDOWS[1]))


def test_a_dem_rewritten_is_read_again(dem):
    path, values = dem
    first = read_dem_cells(path, 1, WINDOWS[0], (130, 150))
    write_dem(path, values + 1000.0)
    st = os.stat(path)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # a new modification time
    again = read_dem_cells(path, 1, WINDOWS[0], (130, 150))
    np.testing.assert_array_equal(again, gdal_window(path, WINDOWS[0]))
    assert np.nanmax(np.abs(again - first - 1000.0)) < 1e-3
