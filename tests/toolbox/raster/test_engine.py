"""The tiled raster engine: grid rules, tiles and halos (a tiled result equals the one-tile
result), inputs on other grids and CRSs resampled, the writer's layout (tiled 512, DEFLATE with
a predictor, overviews, COG), and the warp mode with auxiliary arrays."""

from __future__ import annotations

from functools import partial
from types import SimpleNamespace

import numpy as np
import pytest
import rasterio
from affine import Affine
from scipy import ndimage

from toolbox.errors import ParameterError
from toolbox.executor import Executor
from toolbox.io.grid import GridSpec
from toolbox.io.raster import overview_levels
from toolbox.parameters import Extent
from toolbox.raster.engine import (
    RasterInput,
    Tile,
    iter_tiles,
    process_raster,
    read_window,
)
from toolbox.raster.grid_request import GridRequest
from toolbox.raster.homography import HomographyMap
from toolbox.raster.warp import warp_layout, warp_raster
from toolbox.raster.writer import RasterWriter, cog_problems

X0, Y0 = 1_688_000.0, 4_799_500.0
CRS = "EPSG:3003"
LOCAL = Executor("local", 2)


def write(path, array, transform, crs=CRS, nodata=None, **kw):
    import warnings

    data = array if array.ndim == 3 else array[None]
    with warnings.catch_warnings():  # a photo without georeferencing is what we mean
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        dst = rasterio.open(path, "w", driver="GTiff", width=data.shape[2],
                            height=data.shape[1], count=data.shape[0], dtype=data.dtype, crs=crs,
                            transform=transform, nodata=nodata, **kw)
    with dst:
        dst.write(data)
    return path


def read(path):
    with rasterio.open(path) as src:
        return src.read()


# -- grid rules ------------------------------------------------------------------------------------
def test_extent_is_honoured_as_given():
    # a QGIS extent at 4 m: the origin stays at xmin/ymax, the far edges round up to whole cells
    grid = GridRequest(cell_size=4.0, extent=Extent(X0 + 2, Y0 + 1, X0 + 41, Y0 + 30)).grid(None, CRS)
    assert (grid.transform.c, grid.transform.f) == (X0 + 2, Y0 + 30)
    assert (grid.width, grid.height) == (10, 8)  # 39 m -> 10 cells, 29 m -> 8 cells
    exact = GridRequest(cell_size=0.1, extent=Extent(0, 0, 0.3, 0.7)).grid(None, None)
    assert (exact.width, exact.height) == (3, 7)  # no extra cell from 0.3 / 0.1 = 2.9999...


def test_data_bounds_are_snapped_outwards_without_extent():
    grid = GridRequest(cell_size=5.0).grid((X0 + 3, Y0 + 7, X0 + 96, Y0 + 61), CRS)
    assert (grid.transform.c, grid.transform.f, grid.width, grid.height) == (X0, Y0 + 65, 20, 12)


def test_template_lattice_and_extent_cut(tmp_path):
    t = Affine(2.5, 0, X0 + 13.3, 0, -2.5, Y0 + 181.7)
    path = write(tmp_path / "t.tif", np.zeros((60, 90), "float32"), t)
    from toolbox.io.raster import open_raster_info

    info = open_raster_info(path)
    assert GridRequest(template=info).grid(None, None) == GridSpec(t, 90, 60, info.crs)
    cut = GridRequest(template=info, extent=Extent(X0 + 50, Y0 + 50, X0 + 100, Y0 + 90)).grid(
        None, None)
    col, row = (cut.transform.c - t.c) / 2.5, (t.f - cut.transform.f) / 2.5
    assert abs(col - round(col)) < 1e-9 and abs(row - round(row)) < 1e-9
    assert cut.transform.c <= X0 + 50 < cut.transform.c + 2.5
    with pytest.raises(ParameterError, match="CELL_SIZE must not be given with TEMPLATE"):
        GridRequest(template=info, cell_size=1.0).grid(None, None)


def test_max_cells_guard():
    with pytest.raises(ParameterError, match="CELL_SIZE 1 gives a 1000 x 1000 grid"):
        GridRequest(cell_size=1.0, max_cells=10_000).grid((0, 0, 1000, 1000), None)
    with pytest.raises(ParameterError, match="CELL_SIZE is required"):
        GridRequest().grid((0, 0, 1, 1), None)
    assert GridRequest().grid((0, 0, 10, 10), None, default_cell_size=lambda: 2.0).width == 5


# -- tiles and halos -------------------------------------------------------------------------------
def test_tiles_cover_the_grid_once_with_full_halos():
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 130), 170, 130)
    seen = np.zeros(grid.shape, int)
    for tile in iter_tiles(grid, 64, halo=3):
        w = tile.window
        seen[w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] += 1
        assert tile.haloed_shape == (w.height + 6, w.width + 6)
        xs, ys = tile.cell_centres()
        assert xs[3] == w.col_off + 0.5 and ys[3] == 130 - (w.row_off + 0.5)
        assert tile.transform.c == w.col_off - 3
    assert (seen == 1).all()


def mean3(tile, arrays):
    """3 x 3 mean of the haloed input, over the tile without halo (each cell sums its nine
    neighbours in the same order wherever the tile is, so the result cannot depend on tiling)."""
    z = arrays["dem"][0].astype("float64")
    h, w = tile.shape
    return sum(z[r:r + h, c:c + w] for r in range(3) for c in range(3)) / 9.0


@pytest.mark.parametrize("boundary, scipy_mode", [("edge", "nearest"), ("reflect", "mirror")])
def test_tiled_result_equals_one_tile_and_scipy(tmp_path, boundary, scipy_mode):
    rng = np.random.default_rng(3)
    z = rng.normal(0, 10, (150, 170)).astype("float32")
    t = Affine(2, 0, X0, 0, -2, Y0)
    src = write(tmp_path / "z.tif", z, t)
    grid = GridSpec(t, 170, 150, CRS)
    results = []
    for tile_size in (32, 1024):  # many tiles smaller than the raster, and one tile
        out = np.full(grid.shape, np.nan)

        def put(tile, array, out=out):
            w = tile.window
            out[w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] = array

        stats = process_raster(grid, {"dem": RasterInput(src, boundary=boundary)}, mean3, put,
                               tile_size=tile_size, halo=1, executor=LOCAL)
        assert stats["tiles"] == (30 if tile_size == 32 else 1)  # 6 x 5 tiles
        results.append(out)
    assert np.array_equal(results[0], results[1])
    reference = ndimage.uniform_filter(z.astype("float64"), 3, mode=scipy_mode)
    np.testing.assert_allclose(results[0], reference, rtol=0, atol=1e-9)


def test_written_tiles_equal_one_tile_and_blank_tiles(tmp_path):
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 700), 900, 700, None)

    def kernel(tile, arrays):
        xs, ys = tile.cell_centres(halo=False)
        return (xs[None, :] * 1000 + ys[:, None]).astype("float32")

    def plan(tile):  # skip the tiles whose west edge is past x = 600
        return None if tile.window.col_off >= 600 else {}

    paths = []
    for tile_size in (128, 1024):
        path = tmp_path / f"o{tile_size}.tif"
        with RasterWriter(path, grid, 1, "float32", nodata=-1.0) as w:
            process_raster(grid, None, kernel, w, tile_size=tile_size, executor=LOCAL, plan=plan)
        paths.append(path)
    a, b = read(paths[0])[0], read(paths[1])[0]
    assert np.array_equal(a[:, :640], b[:, :640])
    assert (a[:, 640:] == -1).all()  # tiles skipped by the plan are nodata
    assert a[699, 0] == 0.5 * 1000 + 0.5


# -- inputs on other grids --------------------------------------------------------------------------
def test_aligned_input_is_read_directly_with_nodata_and_outside_fill(tmp_path):
    z = np.arange(40 * 50, dtype="int16").reshape(40, 50)
    z[5, 10] = -1
    src = write(tmp_path / "a.tif", z, Affine(1, 0, X0, 0, -1, Y0), nodata=-1)
    grid = GridSpec(Affine(1, 0, X0 + 10, 0, -1, Y0 - 3), 30, 20, CRS)  # shifted 10 cols, 3 rows
    from rasterio.windows import Window

    out = read_window(src, grid, Window(0, 0, 45, 5), halo=2, dtype="float32")
    assert out.shape == (1, 9, 49)
    np.testing.assert_array_equal(out[0, 0, :42], z[1, 8:50])  # row -2 of the grid = row 1
    assert np.isnan(out[0, 0, 42:]).all()  # beyond the source: NaN for a float result
    assert np.isnan(out[0, 4, 2]) and np.isnan(out).sum() == 9 * 7 + 1  # + the nodata cell
    ints = read_window(src, grid, Window(35, 0, 10, 2))  # source cols 45..54
    assert ints.dtype == np.int16 and (ints[0, :, 5:] == -1).all()


@pytest.mark.parametrize("mask_kind", ["mask band", "alpha band"])
def test_aligned_input_honours_a_mask_band_or_alpha_as_the_warper_does(tmp_path, mask_kind):
    """A DEM whose holes are in an internal mask band (no nodata) or an alpha band: the aligned
    read fills them as the resampled (GDAL warper) read does (they were read as heights: a
    0 m hole in a hillshade or a volume)."""
    from rasterio.windows import Window

    dtype = "float32" if mask_kind == "mask band" else "uint16"  # GDAL: no float alpha
    z = (100 + np.arange(40 * 50).reshape(40, 50) % 37).astype(dtype)
    hole = np.zeros(z.shape, bool)
    hole[10:16, 20:30] = True
    path = tmp_path / "m.tif"
    profile = dict(driver="GTiff", width=50, height=40, crs=CRS, dtype=dtype,
                   transform=Affine(1, 0, X0, 0, -1, Y0))
    with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True):
        extra = {"count": 1} if mask_kind == "mask band" else {"count": 2, "alpha": "YES"}
        with rasterio.open(path, "w", **profile, **extra) as dst:
            dst.write(np.where(hole, 0, z), 1)
            if mask_kind == "mask band":
                dst.write_mask(np.where(hole, 0, 255).astype("uint8"))
            else:  # 0 transparent
                dst.write(np.where(hole, 0, 65535).astype(dtype), 2)
    with rasterio.open(path) as src:
        assert src.mask_flag_enums[0] != [rasterio.enums.MaskFlags.all_valid]
    grid = GridSpec(Affine(1, 0, X0, 0, -1, Y0), 50, 40, CRS)
    aligned = read_window(path, grid, Window(0, 0, 50, 40), bands=1, dtype="float32")[0]
    assert np.array_equal(np.isnan(aligned), hole)
    np.testing.assert_array_equal(aligned[~hole], z[~hole])
    # the same grid shifted by half a cell is read through GDAL's warper: the same hole
    shifted = GridSpec(Affine(1, 0, X0 + 0.5, 0, -1, Y0), 49, 40, CRS)
    warped = read_window(path, shifted, Window(0, 0, 49, 40), bands=1, resampling="nearest",
                         dtype="float32")[0]
    assert np.isnan(warped[10:16, 21:29]).all() and np.isfinite(warped[:10]).all()


def test_input_on_another_grid_and_crs_is_resampled(tmp_path):
    from pyproj import Transformer

    # a plane in EPSG:3003 at 1 m; the output grid is in UTM 32N (EPSG:32632) at 2.5 m
    a, b, c = 0.02, -0.01, 300.0
    t = Affine(1, 0, X0, 0, -1, Y0)
    cols, rows = np.meshgrid(np.arange(400) + 0.5, np.arange(300) + 0.5)
    z = (a * (cols) + b * (-rows) + c).astype("float64")
    src = write(tmp_path / "p.tif", z, t)
    to_utm = Transformer.from_crs(CRS, "EPSG:32632", always_xy=True)
    ux, uy = to_utm.transform(X0 + 100, Y0 - 100)
    grid = GridSpec(Affine(2.5, 0, ux, 0, -2.5, uy), 60, 40, "EPSG:32632")
    from rasterio.windows import Window

    out = read_window(src, grid, Window(0, 0, 60, 40), resampling="bilinear")[0]
    xs, ys = Tile(0, Window(0, 0, 60, 40), 0, grid.transform).cell_centres()
    gx, gy = np.meshgrid(xs, ys)
    back = Transformer.from_crs("EPSG:32632", CRS, always_xy=True)
    sx, sy = back.transform(gx, gy)
    truth = a * (sx - X0) + b * (sy - Y0) + c
    # GDAL's approximate transformer: within 0.01 source pixel (0.01 m x 0.022 m/m)
    np.testing.assert_allclose(out, truth, atol=3e-4)
    # a finer resolution, same CRS, origin off the source lattice: bilinear is exact on a plane
    grid2 = GridSpec(Affine(0.7, 0, X0 + 17.2, 0, -0.7, Y0 - 11.9), 50, 40, CRS)
    out2 = read_window(src, grid2, Window(0, 0, 50, 40))[0]
    xs, ys = Tile(0, Window(0, 0, 50, 40), 0, grid2.transform).cell_centres()
    np.testing.assert_allclose(out2, a * (xs[None, :] - X0) + b * (ys[:, None] - Y0) + c,
                               atol=1e-6)


# -- the writer ------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape, dtype, predictor, levels", [
    ((80, 100), "float32", "3", []), ((600, 700), "int16", "2", [2])])
def test_writer_is_tiled_deflate_with_predictor_and_overviews(tmp_path, shape, dtype, predictor,
                                                              levels):
    grid = GridSpec(Affine(1, 0, X0, 0, -1, Y0), shape[1], shape[0], CRS)
    path = tmp_path / "w.tif"
    with RasterWriter(path, grid, 1, dtype, nodata=-9999) as w:
        for tile in iter_tiles(grid, 512):
            w.write(tile, np.ones(tile.shape, dtype))
    with rasterio.open(path) as src:
        assert src.block_shapes == [(512, 512)]  # tiled even when smaller than a tile
        assert src.compression.name == "deflate"
        assert src.tags(ns="IMAGE_STRUCTURE")["PREDICTOR"] == predictor
        assert src.overviews(1) == levels
        assert src.nodata == -9999 and src.crs.to_epsg() == 3003
    assert overview_levels(4000, 1000) == [2, 4, 8]


@pytest.mark.parametrize("cog,memory_mb", [(False, 0), (False, 64), (True, 0)])
def test_a_discarded_output_leaves_no_file(tmp_path, cog, memory_mb):
    """discard(): the written file (tiled, in memory, or the COG's tiled twin) is removed at the
    end of the block, without an error; the other files of the folder are kept."""
    grid = GridSpec(Affine(1, 0, X0, 0, -1, Y0), 700, 600, CRS)
    (tmp_path / "keep.txt").write_text("x")
    with RasterWriter(tmp_path / "d.tif", grid, 1, "uint8", nodata=0, cog=cog,
                      memory_mb=memory_mb) as w:
        for tile in iter_tiles(grid, 512):
            w.write(tile, np.ones(tile.shape, "uint8"))
        w.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_cog_passes_the_layout_checks_and_a_plain_tiff_does_not(tmp_path):
    grid = GridSpec(Affine(0.5, 0, X0, 0, -0.5, Y0), 1300, 900, CRS)
    rng = np.random.default_rng(1)
    for cog in (True, False):
        path = tmp_path / f"c{cog}.tif"
        with RasterWriter(path, grid, 4, "uint8", alpha=True, cog=cog,
                          band_descriptions=["r", "g", "b", "alpha"]) as w:
            for tile in iter_tiles(grid, 512):
                w.write(tile.window, rng.integers(0, 255, (4, *tile.shape), dtype="uint8"))
        problems = cog_problems(path)
        with rasterio.open(path) as src:
            assert src.colorinterp[-1].name == "alpha" and src.descriptions[0] == "r"
            assert src.block_shapes[0] == (512, 512) and src.overviews(1) == [2, 4]
            if cog:
                assert src.tags(ns="IMAGE_STRUCTURE")["LAYOUT"] == "COG"
        assert (problems == []) == cog, problems
        valid = gdal_cog_validator(path)  # GDAL's own validator, where its Python is installed
        assert valid is None or valid == cog
    assert not list(tmp_path.glob(".*"))  # the intermediate tiled file is gone


def gdal_cog_validator(path) -> bool | None:
    """GDAL's validate_cloud_optimized_geotiff.py (from the system's GDAL Python bindings, run
    by the system Python); None when not installed."""
    import shutil
    import subprocess

    python = shutil.which("python3", path="/usr/bin:/usr/local/bin")
    module = "osgeo_utils.samples.validate_cloud_optimized_geotiff"
    if python is None or subprocess.run([python, "-c", f"import {module}"],
                                         capture_output=True).returncode != 0:
        return None
    return subprocess.run([python, "-m", module, str(path)], capture_output=True).returncode == 0


def test_writer_block_cache_is_given_in_bytes(tmp_path):
    # rasterio hands an integer GDAL_CACHEMAX to GDALSetCacheMax as bytes: 256 would be a
    # 256-byte cache (every halo read then decodes its blocks again, ~6x slower reads)
    from rasterio.env import get_gdal_config

    grid = GridSpec(Affine(1, 0, 0, 0, -1, 10), 10, 10, None)
    with RasterWriter(tmp_path / "c.tif", grid, 1, "uint8", cache_mb=256):
        assert get_gdal_config("GDAL_CACHEMAX") == 256 * 2**20


def test_overviews_are_built_with_a_small_block_cache(tmp_path):
    """The overviews of a 20000 x 20000 DEM took 417 MB with the 256 MB writing cache and 177 MB
    with 32 MB, for the same CPU: they are built with OVERVIEW_CACHE_MB, the writing cache comes
    back after, and the level-2 overview is the 2 x 2 block average (numpy oracle)."""
    from rasterio.env import get_gdal_config
    from rasterio.windows import Window

    from toolbox.raster.writer import OVERVIEW_CACHE_MB

    seen = []

    class Spy:  # the open dataset, recording the cache while its overviews are built
        def __init__(self, dataset):
            self.dataset = dataset

        def build_overviews(self, *args):
            seen.append(get_gdal_config("GDAL_CACHEMAX"))
            self.dataset.build_overviews(*args)

        def __getattr__(self, name):
            return getattr(self.dataset, name)

    grid = GridSpec(Affine(1, 0, X0, 0, -1, Y0), 1100, 1030, CRS)
    values = np.random.default_rng(3).random((1030, 1100)).astype("float32")
    path = tmp_path / "o.tif"
    with RasterWriter(path, grid, 1, "float32", nodata=-9999, cache_mb=256) as w:
        w.dataset = Spy(w.dataset)
        w.write(Window(0, 0, 1100, 1030), values)
        assert get_gdal_config("GDAL_CACHEMAX") == 256 * 2**20
    assert seen == [OVERVIEW_CACHE_MB * 2**20]
    with rasterio.open(path) as src:
        assert src.overviews(1) == [2, 4]
        level2 = src.read(1, out_shape=(515, 550))  # GDAL serves the level-2 overview
    np.testing.assert_allclose(level2, values.reshape(515, 2, 550, 2).mean(axis=(1, 3)),
                               rtol=1e-6)


def test_failed_write_leaves_nothing(tmp_path):
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 10), 10, 10, None)
    path = tmp_path / "x.tif"
    with pytest.raises(RuntimeError), RasterWriter(path, grid, 1, "uint8", cog=True):
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


# -- warp mode --------------------------------------------------------------------------------------
def aux_map(tile, aux):
    """Source coordinates stored as rasters on the output grid (as a DEM-driven map gets its
    DEM): the map only crops and returns them."""
    return aux["col"][0][tile.crop], aux["row"][0][tile.crop]


def test_warp_with_auxiliary_arrays_and_tiles(tmp_path):
    rng = np.random.default_rng(7)
    photo = rng.integers(0, 60000, (3, 110, 120), dtype="uint16")
    photo_path = write(tmp_path / "photo.tif", photo, Affine.identity(), crs=None)
    grid = GridSpec(Affine(1, 0, X0, 0, -1, Y0), 70, 50, CRS)
    # output cell (i, j) samples source pixel (2i + 3, 120 - 1 - j) (centres at +0.5);
    # the last 10 columns map outside the photo
    ii, jj = np.mgrid[0:50, 0:70]
    col = (119 - jj + 0.5).astype("float32")
    col[:, 60:] = 500.0
    row = (2 * ii + 3 + 0.5).astype("float32")
    write(tmp_path / "col.tif", col, grid.transform)
    write(tmp_path / "row.tif", row, grid.transform)
    aux = {"col": RasterInput(tmp_path / "col.tif"), "row": RasterInput(tmp_path / "row.tif")}
    layout = warp_layout(photo_path, "alpha")
    outs = []
    for tile_size in (16, 512):
        path = tmp_path / f"w{tile_size}.tif"
        with RasterWriter(path, grid, layout.count, layout.dtype, alpha=True) as w:
            stats = warp_raster(photo_path, grid, aux_map, w, layout=layout,
                                resampling="nearest", aux=aux, aux_halo=1, tile_size=tile_size,
                                executor=LOCAL)
        assert stats.output_pixels > 0
        outs.append(read(path))
    assert np.array_equal(outs[0], outs[1])
    out = outs[0]
    expected = photo[:, 2 * ii[:, :60] + 3, 119 - jj[:, :60]]
    np.testing.assert_array_equal(out[:3, :, :60], expected)
    assert (out[3, :, :60] == 65535).all() and (out[3, :, 60:] == 0).all()


def test_homography_warp_tiled_equals_one_tile_and_generic_path(tmp_path):
    rng = np.random.default_rng(2)
    photo = rng.integers(0, 255, (200, 300), dtype="uint8")
    photo_path = write(tmp_path / "p.tif", photo, Affine.identity(), crs=None)
    grid = GridSpec(Affine(0.1, 0, 0, 0, -0.1, 25), 400, 300, None)
    h = np.array([[9.0, 1.0, 20.0], [0.5, -8.0, 210.0], [0.001, 0.002, 1.0]])
    hmap = HomographyMap(h, grid.transform)
    layout = warp_layout(photo_path, "nodata", 0)
    results = []
    for tile_size, fast in ((64, True), (1024, True), (64, False)):
        out = np.zeros((1, *grid.shape), "uint8")

        def put(tile, array, out=out):
            w = tile.window
            out[:, w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] = array

        warp_raster(photo_path, grid, hmap, put, layout=layout, tile_size=tile_size,
                    executor=LOCAL, fast=fast)
        results.append(out)
    # OpenCV samples at 1/32 pixel in fixed point: coordinates relative to each tile's source
    # window round differently in a few cases (one grey level), seams stay invisible
    diff = np.abs(results[0].astype(int) - results[1])
    assert diff.max() <= 1 and (diff > 0).mean() < 2e-3
    # warpPerspective and remap of the same coordinates agree within one grey level
    assert np.abs(results[0].astype(int) - results[2]).max() <= 1
    assert (results[0] > 0).mean() > 0.3


def _warp_to_array(photo_path, grid, hmap, layout, tile_size):
    out = np.zeros((layout.count, *grid.shape), layout.dtype)

    def put(tile, array):
        w = tile.window
        out[:, w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] = array

    warp_raster(photo_path, grid, hmap, put, layout=layout, tile_size=tile_size, executor=LOCAL)
    return out


@pytest.mark.parametrize("resampling", ["bilinear", "cubic"])
def test_packed_homography_path_equals_the_band_sequential_path(tmp_path, resampling):
    # an RGB photo takes the packed path (bands pixel-interleaved from the read to the writer,
    # edge pads built in place); the same photo with an opaque alpha band takes the
    # band-sequential one (alpha resampled): the same cells, the same alpha
    rng = np.random.default_rng(5)
    rgb = rng.integers(0, 255, (3, 200, 300), dtype="uint8")
    opaque = np.concatenate([rgb, np.full((1, 200, 300), 255, "uint8")])
    rgb_path = write(tmp_path / "rgb.tif", rgb, Affine.identity(), crs=None)
    rgba_path = write(tmp_path / "rgba.tif", opaque, Affine.identity(), crs=None,
                      photometric="RGB", alpha="YES")
    grid = GridSpec(Affine(0.1, 0, 0, 0, -0.1, 25), 400, 300, None)
    hmap = HomographyMap(np.array([[9.0, 1.0, 20.0], [0.5, -8.0, 210.0], [0.001, 0.002, 1.0]]),
                         grid.transform)
    assert warp_layout(rgba_path).source_alpha == 4 and warp_layout(rgb_path).source_alpha is None
    for tile_size in (512, 64):  # tiles inside, across and beyond the photo's edges
        packed = _warp_to_array(rgb_path, grid, hmap, warp_layout(rgb_path), tile_size)
        sequential = _warp_to_array(rgba_path, grid, hmap, warp_layout(rgba_path), tile_size)
        np.testing.assert_array_equal(packed, sequential)
        assert 0.3 < (packed[3] == 255).mean() < 0.95 and set(np.unique(packed[3])) == {0, 255}
    # outside=nodata (same 64-cell tiles): the same cells, nodata where the alpha output is 0,
    # a valid cell that lands on nodata (every band) one step off it, as gdalwarp; one band
    # alone too
    nodata = _warp_to_array(rgb_path, grid, hmap, warp_layout(rgb_path, "nodata", 7), 64)
    at_7 = (packed[:3] == 7).all(axis=0)
    np.testing.assert_array_equal(nodata, np.where(packed[3] == 0, 7,
                                                   np.where(at_7, 6, packed[:3])))
    grey_path = write(tmp_path / "grey.tif", rgb[1], Affine.identity(), crs=None)
    grey = _warp_to_array(grey_path, grid, hmap, warp_layout(grey_path), 64)
    np.testing.assert_array_equal(grey, packed[1::2])  # (2 bands: the band-sequential path)
    grey_nodata = _warp_to_array(grey_path, grid, hmap, warp_layout(grey_path, "nodata", 7), 64)
    np.testing.assert_array_equal(grey_nodata[0], np.where(  # one band: packed
        packed[3] == 0, 7, np.where(packed[1] == 7, 6, packed[1])))
    assert ((packed[3] > 0) & (packed[1] == 7)).sum() > 5  # (valid cells at 7 before: holes)


def test_kernels_may_be_partials_of_module_functions(tmp_path):
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 40), 40, 40, None)
    out = []
    process_raster(grid, None, partial(_constant, 3.0), lambda t, a: out.append(a),
                   tile_size=16, executor=Executor("local", 1))
    assert len(out) == 9 and all((a == 3.0).all() for a in out)


def _constant(value, tile, arrays):
    return np.full(tile.shape, value)


def _blas_threads(_):
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_blas_is_limited_to_one_thread_inside_tile_threads_only():
    from toolbox.executor import map_tiles

    before = _blas_threads(0)
    if not before or max(before) == 1:
        pytest.skip("no multi-threaded BLAS here")
    inside = list(map_tiles(_blas_threads, [0, 1, 2], workers=2))
    assert all(threads == [1] * len(before) for threads in inside)
    assert _blas_threads(0) == before  # restored afterwards


def test_small_output_written_from_memory_equals_the_streamed_one(tmp_path):
    """``memory_mb``: the whole output gathered in a MEM dataset, its overviews built there and
    copied once (GDAL's COPY_SRC_OVERVIEWS). Oracles: the arrays written (full resolution), the
    alpha-weighted 2 x 2 mean of NumPy (the first overview), the streamed file's layout."""
    grid = GridSpec(Affine(0.5, 0, X0, 0, -0.5, Y0), 1300, 900, CRS)
    rng = np.random.default_rng(3)
    data = rng.integers(0, 255, (4, 900, 1300), dtype="uint8")
    data[3] = 255
    data[3, :, :200] = 0  # a transparent strip: no weight in the overviews
    data[:3, :, :200] = 0
    files = {}
    for name, memory_mb in (("memory", 32), ("streamed", 0), ("too_large", 4)):
        path = files[name] = tmp_path / f"{name}.tif"
        writer = RasterWriter(path, grid, 4, "uint8", alpha=True, memory_mb=memory_mb,
                              band_descriptions=["r", "g", "b", "alpha"], tags={"k": "v"})
        assert writer.in_memory == (name == "memory")
        with writer as w:
            for tile in iter_tiles(grid, 512):
                w.write(tile.window, data[(slice(None), *tile.window.toslices())])
    with rasterio.open(files["memory"]) as m, rasterio.open(files["streamed"]) as s:
        np.testing.assert_array_equal(m.read(), data)
        assert m.profile == s.profile and m.overviews(1) == s.overviews(1) == [2, 4]
        assert m.colorinterp == s.colorinterp and m.colorinterp[-1].name == "alpha"
        assert m.descriptions == s.descriptions and m.tags()["k"] == "v"
        assert m.tags(ns="IMAGE_STRUCTURE")["PREDICTOR"] == "2"
    with rasterio.open(files["memory"], overview_level=0) as m, \
            rasterio.open(files["streamed"], overview_level=0) as s:
        level = m.read().astype("float64")
        np.testing.assert_array_equal(level, s.read())
    mean = data[:3].astype("float64").reshape(3, 450, 2, 650, 2).mean(axis=(2, 4))
    assert np.abs(level[:3, :, 100:] - mean[:, :, 100:]).max() <= 1  # GDAL rounds, NumPy not
    assert (level[3, :, :100] == 0).all() and (level[3, :, 100:] == 255).all()
    assert cog_problems(files["memory"]) == []  # copied with the overviews first: a COG layout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory.tif", "streamed.tif",
                                                          "too_large.tif"]


@pytest.mark.parametrize("memory_mb", [0, 32])
def test_one_gdal_thread_writes_the_same_file(tmp_path, memory_mb):
    """``threads=1`` (ortho:batch's photos, each on its own pool thread) changes who
    compresses, not what is written: the same bytes as GDAL's all-CPU default, streamed or
    gathered in memory."""
    grid = GridSpec(Affine(0.5, 0, X0, 0, -0.5, Y0), 1100, 700, CRS)
    data = np.random.default_rng(5).integers(0, 255, (4, 700, 1100), dtype="uint8")
    files = []
    for threads in (None, 1):
        path = tmp_path / f"{threads}.tif"
        writer = RasterWriter(path, grid, 4, "uint8", alpha=True, memory_mb=memory_mb,
                              threads=threads)
        one = threads == 1 and memory_mb > 0  # a streamed output keeps all CPUs
        assert writer.profile()["num_threads"] == ("1" if one else "all_cpus")
        with writer as w:
            for tile in iter_tiles(grid, 512):
                w.write(tile.window, data[(slice(None), *tile.window.toslices())])
        files.append(path.read_bytes())
    assert files[0] == files[1]


def test_warp_writer_threads_follow_the_executor(tmp_path, monkeypatch):
    """warp_to_geotiff's writer compresses on the local executor's threads (one: the tiles
    run on the caller's thread, whose neighbours keep the other cores busy); on Dask, GDAL's
    default."""
    import toolbox.raster.warp as warp

    seen = []

    class Stop(Exception):
        pass

    def writer(*args, **kwargs):
        seen.append(kwargs["threads"])
        raise Stop

    monkeypatch.setattr("toolbox.raster.writer.RasterWriter", writer)
    monkeypatch.setattr(warp, "open_photo", lambda source: (str(source), SimpleNamespace(
        close=lambda: None)))
    monkeypatch.setattr(warp, "output_layout", lambda *a: SimpleNamespace(
        count=1, dtype="uint8", nodata=None, alpha=False))
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 10), 10, 10, None)
    for executor in (Executor("local", 1), Executor("local", 3), Executor("dask", 2, "x:1"),
                     None):
        with pytest.raises(Stop):
            warp.warp_to_geotiff("in.tif", None, grid, tmp_path / "o.tif", executor=executor)
    assert seen == [1, 3, None, None]


def test_small_float_output_from_memory_keeps_nodata_out_of_the_overviews(tmp_path):
    grid = GridSpec(Affine(1, 0, X0, 0, -1, Y0), 1000, 600, CRS)
    values = np.arange(600 * 1000, dtype="float32").reshape(600, 1000) / 1000
    values[:, :2] = np.nan  # the kernels' "no value": written as nodata
    path = tmp_path / "f.tif"
    with RasterWriter(path, grid, 1, "float32", nodata=-9999.0, memory_mb=32) as w:
        w.write(rasterio.windows.Window(0, 0, 1000, 600), values)
    with rasterio.open(path) as src:
        assert src.nodata == -9999.0 and src.overviews(1) == [2]
        assert src.tags(ns="IMAGE_STRUCTURE")["PREDICTOR"] == "3"
        full = src.read(1)
    with rasterio.open(path, overview_level=0) as src:
        level = src.read(1)
    assert (full[:, :2] == -9999.0).all()
    np.testing.assert_array_equal(full[:, 2:], values[:, 2:])
    mean = values.astype("float64").reshape(300, 2, 500, 2).mean(axis=(1, 3))
    assert (level[:, 0] == -9999.0).all()
    np.testing.assert_allclose(level[:, 1:], mean[:, 1:], rtol=1e-6)


def test_failed_write_from_memory_leaves_nothing(tmp_path):
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 1000), 1000, 1000, None)
    with pytest.raises(RuntimeError), RasterWriter(tmp_path / "x.tif", grid, 1, "uint8",
                                                   memory_mb=32) as w:
        assert w.in_memory
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []
