"""Round 17 (seamspeed): the shortcuts of mosaic:seamlines give what the long way gives.

The reads of an ortho known to be all valid against GDAL's mask read of the same window."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine
from rasterio.windows import Window

from toolbox.mosaic.sources import open_source, read_valid, read_window, valid_footprint


def _ortho(path, nodata_corner: bool):
    data = np.arange(3 * 30 * 40, dtype="uint8").reshape(3, 30, 40) | 1  # no 0: all valid
    if nodata_corner:
        data[:, :5, :7] = 0
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=3, dtype="uint8",
                       nodata=0, crs="EPSG:3003", transform=Affine(1, 0, 1000, 0, -1, 2000)) as d:
        d.write(data)


@pytest.mark.parametrize("nodata_corner", [False, True])
def test_reads_of_an_all_valid_ortho_equal_the_mask_reads(tmp_path, nodata_corner):
    path = tmp_path / "o.tif"
    _ortho(path, nodata_corner)
    src = open_source(path, 0)
    valid_footprint(src)
    assert src.all_valid is not nodata_corner
    plain = open_source(path, 0)  # never traced: reads GDAL's mask
    assert not plain.all_valid
    grid = Affine(1, 0, 990, 0, -1, 2005)  # aligned, 10 cells west, 5 north of the ortho
    for window in (Window(10, 5, 40, 30), Window(12, 7, 20, 10), Window(0, 0, 60, 45),
                   Window(40, 30, 20, 10), Window(100, 100, 5, 5)):
        data, valid = read_window(src, grid, None, window)
        data0, valid0 = read_window(plain, grid, None, window)
        assert data.dtype == data0.dtype == np.float32
        assert np.array_equal(data, data0) and np.array_equal(valid, valid0)
        assert np.array_equal(read_valid(src, grid, None, window), valid0)
    with rasterio.open(path) as ds:  # the truth: GDAL's mask of the ortho
        assert np.array_equal(read_window(src, grid, None, Window(10, 5, 40, 30))[1],
                              ds.dataset_mask() > 0)


@pytest.mark.parametrize("radius", [0.5, 1.0, 2.5, 7.0, 30.0])
@pytest.mark.parametrize("workers", [1, 2])
def test_within_radius_of_a_few_columns_equals_scipy_edt(radius, workers):
    """Only the columns holding a True cell are transformed (a seam's structured differences
    are a few facades): the rest of the grid is still measured, against scipy's exact EDT."""
    from scipy import ndimage

    from toolbox.mosaic.kernels import within_radius

    rng = np.random.default_rng(int(radius * 10))
    mask = np.zeros((120, 150), bool)
    for c in (0, 3, 4, 77, 149):  # both edges, neighbours, one alone
        mask[:, c] = rng.random(120) < 0.1
    mask[5, 60] = True
    expected = ndimage.distance_transform_edt(~mask) <= radius
    assert np.array_equal(within_radius(mask, radius, workers=workers), expected)
    assert not within_radius(np.zeros((30, 40), bool), radius, workers=workers).any()


@pytest.mark.parametrize("small_groups", [False, True])
def test_structured_near_equals_scipy(small_groups):
    """Every group large enough (the mask is the strong cells themselves) or not: cells within
    the radius of a large group of strong cells, measured by scipy."""
    from scipy import ndimage

    from toolbox.mosaic.seams import structured_near

    g = np.zeros((60, 80))
    g[10:14, 20:30] = 1.0  # 40 cells
    g[40:42, 50:60] = 1.0  # 20 cells
    if small_groups:
        g[55, 5] = g[30, 75] = 1.0  # single cells: noise, not structure
    big = np.zeros(g.shape, bool)
    big[10:14, 20:30] = big[40:42, 50:60] = True
    expected = ndimage.distance_transform_edt(~big) <= 6.0
    assert np.array_equal(structured_near(g, 0.5, 6.0), expected)


def test_nearest_passable():
    from toolbox.mosaic.seams import _nearest_passable

    cost = np.ones((20, 30))
    cost[:, :10] = -1.0
    assert _nearest_passable(cost, (5, 15)) == (5, 15)
    assert _nearest_passable(cost, (5, 3)) == (5, 10)
    assert _nearest_passable(cost, (-4, 99)) == (0, 29)
    assert _nearest_passable(np.full((4, 4), -1.0), (1, 1)) is None


def test_open_block_threads_decode_the_same_footprints(tmp_path):
    """GDAL's decoding threads while the block is open (mosaic:seamlines' footprints): the same
    sources and footprints; the setting ends with the block."""
    from rasterio.env import getenv, hasenv

    from toolbox.mosaic.block import close_block, open_block

    paths = [tmp_path / "a.tif", tmp_path / "b.tif"]
    _ortho(paths[0], False)
    _ortho(paths[1], True)
    before = dict(getenv()) if hasenv() else None  # an earlier test may leave an Env open
    plain, _ = open_block(paths)
    close_block(plain)
    threaded, _ = open_block(paths, threads=2)
    try:
        assert getenv()["GDAL_NUM_THREADS"] == "2"
        assert [s.footprint.wkb for s in threaded] == [s.footprint.wkb for s in plain]
        assert [s.all_valid for s in threaded] == [True, False]
    finally:
        close_block(threaded)
    assert (dict(getenv()) if hasenv() else None) == before


def test_in_order_gives_numpys_percentiles():
    from toolbox.mosaic.seams import _in_order

    rng = np.random.default_rng(5)
    samples = [rng.integers(0, 256, n).astype("float32") for n in (1, 2, 7, 1000, 240_001)]
    samples += [rng.integers(0, 65536, 5000).astype("float32"),
                rng.uniform(0, 255, 999).astype("float32"),  # fractions: left as they are
                np.array([-1.0, 3.0, 7.0], "float32"), np.array([1.0, np.nan], "float32"),
                np.array([], "float32")]
    for sample in samples:
        ordered = _in_order(sample)
        if not sample.size:
            continue
        expected = np.percentile(sample, [1, 99])
        got = np.percentile(ordered, [1, 99])
        assert got.dtype == expected.dtype
        assert got.tobytes() == expected.tobytes() or np.isnan(expected).any()


@pytest.mark.parametrize("factor", [1, 3, 4])
def test_overview_is_the_block_mean_of_the_passable_cells(factor):
    from toolbox.mosaic.route import overview

    rng = np.random.default_rng(factor)
    cost = rng.uniform(0.1, 3.0, (23, 17))
    cost[rng.random(cost.shape) < 0.3] = -1.0
    cost[:factor, :factor] = -1.0  # one block wholly impassable
    got = overview(cost, factor)
    rows, cols = -(-23 // factor), -(-17 // factor)
    assert got.shape == (rows, cols)
    for r in range(rows):
        for c in range(cols):
            block = cost[r * factor:(r + 1) * factor, c * factor:(c + 1) * factor]
            passable = block[block >= 0]
            assert got[r, c] == (pytest.approx(passable.mean()) if passable.size else -1.0)
