"""Round 18 leftovers (7): balanced mosaic values kept off the nodata value."""

import numpy as np
import rasterio
from rasterio.transform import from_origin

import toolbox


def _ortho(path, arr, x0, nodata=0):
    with rasterio.open(path, "w", driver="GTiff", width=arr.shape[-1], height=arr.shape[-2],
                       count=1, dtype=arr.dtype, crs="EPSG:32633", nodata=nodata,
                       transform=from_origin(500000 + x0, 5000040, 1, 1)) as dst:
        dst.write(arr, 1)


def test_balanced_dark_pixel_is_not_written_as_nodata(tmp_path):
    # B is A + 20 over the overlap -> offsets +10 / -10; B's valid shadow (5) outside the
    # overlap is balanced to 5 - 10 -> 0 by numpy (clipped), the nodata value: it was written
    # as no data (a hole of 20 x 40 cells); it is kept valid at 1 (one step off nodata)
    rng = np.random.default_rng(0)
    base = rng.integers(60, 200, (40, 100)).astype("uint8")
    a = base[:, :60].copy()
    b = (base[:, 40:100] + 20).astype("uint8")
    b[:, 40:] = 5
    _ortho(tmp_path / "a.tif", a, 0.0)
    _ortho(tmp_path / "b.tif", b, 40.0)
    res = toolbox.run("mosaic:build", {"INPUT": [str(tmp_path / "a.tif"), str(tmp_path / "b.tif")],
                                       "BLEND": "none", "BALANCE": True,
                                       "OUTPUT": str(tmp_path / "m.tif")})
    g = np.array(res["STATISTICS"]["gains"])[:, 0]
    o = np.array(res["STATISTICS"]["offsets"])[:, 0]
    assert np.allclose(g, 1.0, atol=1e-3) and np.allclose(o, [10.0, -10.0], atol=0.05)
    assert np.clip(np.rint(g[1] * 5 + o[1]), 0, 255) == 0  # numpy: onto the nodata value
    with rasterio.open(tmp_path / "m.tif") as src:
        assert src.nodata == 0 and (src.width, src.height) == (100, 40)
        m = src.read(1, masked=True)
    assert not np.ma.getmaskarray(m).any()  # every cell has data in an input
    assert (m.data[:, 80:] == 1).all()  # the shadow: one step off nodata
    # elsewhere the numpy truth on the same gains: A's own cells (x < 40) are a·g0 + o0
    assert np.array_equal(m.data[:, :30], np.clip(np.rint(a[:, :30] * g[0] + o[0]), 0, 255))


def test_keep_off_nodata_moves_valid_cells_with_every_band_at_nodata_only():
    from toolbox.raster.writer import keep_off_nodata

    data = np.array([[[0, 255, 7], [255, 0, 0]]], "uint8")
    valid = np.array([[True, True, True], [True, False, True]])
    assert keep_off_nodata(data.copy(), valid, 0).tolist() == [[[1, 255, 7], [255, 0, 1]]]
    assert keep_off_nodata(data.copy(), valid, 255).tolist() == [[[0, 254, 7], [254, 0, 0]]]
    rgb = np.array([[[0, 0]], [[0, 0]], [[255, 0]]], "uint8")  # pure blue stays, black moves
    assert keep_off_nodata(rgb, np.ones((1, 2), bool), 0)[:, 0].T.tolist() == [[0, 0, 255],
                                                                              [1, 1, 1]]
    f = np.array([[[-9999.0, 3.0]]], "float32")
    out = keep_off_nodata(f.copy(), np.ones((1, 2), bool), -9999.0)
    # (past the ~4 float ulps GDAL's mask still reads as -9999: test_round18_warpnodata)
    assert out[0, 0, 0] != np.float32(-9999.0) and abs(out[0, 0, 0] + 9999.0) < 1e-2
    assert keep_off_nodata(f.copy(), np.ones((1, 2), bool), float("nan")).tolist() == f.tolist()


def test_engine_aligned_multiband_read_masks_by_the_dataset_mask(tmp_path):
    # an RGB with nodata 0: the pure-blue pixel (0, 0, 255) is valid for GDAL's dataset mask,
    # the black one is not; the aligned read masked band by band (blue -> (NaN, NaN, 255)),
    # the warped read of the same photo (GDAL's warper) kept it
    from affine import Affine
    from rasterio.windows import Window

    from toolbox.io.grid import GridSpec
    from toolbox.raster.engine import read_window

    d = np.full((3, 8, 8), 100, "uint8")
    d[:, 3, 3] = [0, 0, 255]
    d[:, 5, 5] = 0
    path = tmp_path / "rgb.tif"
    with rasterio.open(path, "w", driver="GTiff", width=8, height=8, count=3, dtype="uint8",
                       crs="EPSG:32633", nodata=0, transform=from_origin(0, 8, 1, 1)) as f:
        f.write(d)
    with rasterio.open(path) as f:
        valid = f.dataset_mask() > 0
    assert valid[3, 3] and not valid[5, 5] and valid.sum() == 63
    truth = np.where(valid, d.astype("float32"), np.nan)
    for t in (Affine(1, 0, 0, 0, -1, 8), Affine(1, 0, 0, 0, -1.0000001, 8)):  # aligned, warped
        out = read_window(str(path), GridSpec(t, 8, 8, "EPSG:32633"), Window(0, 0, 8, 8),
                          dtype="float32", resampling="nearest")
        np.testing.assert_array_equal(out, truth)


def test_extent_takes_the_crs_with_or_without_brackets():
    # the help said 'xmin,ymin,xmax,ymax [CRS]': "... EPSG:32633" (the brackets read as
    # "optional") was refused with exit 2; QGIS's bracketed text stays accepted
    from pyproj import CRS

    from toolbox.errors import ParameterError
    from toolbox.parameters import ExtentParameter
    from toolbox.parameters.base import ValidationContext

    p = ExtentParameter("EXTENT")
    utm = CRS.from_epsg(32633)
    for text in ("500000,5000000,501000,5001000 EPSG:32633",
                 "500000,5000000,501000,5001000 [EPSG:32633]",
                 " 500000 5000000 501000 5001000  epsg:32633 ",
                 "500000,5000000,501000,5001000,EPSG:32633"):
        e = p.resolve(text, ValidationContext())
        assert e.bounds == (500000, 5000000, 501000, 5001000) and e.crs == utm, text
    e = p.resolve("-1.5e3,2,3,4 +proj=utm +zone=33 +datum=WGS84", ValidationContext())
    assert e.bounds == (-1500, 2, 3, 4) and e.crs.to_epsg() == 32633
    assert p.resolve("1,2,3,4", ValidationContext()).crs is None
    for text, fragment in (("1,2,3,4 5", "xmin,ymin,xmax,ymax EPSG:3003"),
                           ("1,2,3 EPSG:32633", "xmin,ymin,xmax,ymax EPSG:3003"),
                           ("1,2,3,4 nowhere", "'nowhere' is not a CRS")):
        try:
            p.resolve(text, ValidationContext())
        except ParameterError as exc:
            assert str(exc).startswith("EXTENT") and fragment in str(exc), str(exc)
        else:
            raise AssertionError(f"{text!r} accepted")


def test_every_extent_help_shows_what_to_type():
    from toolbox import registry
    from toolbox.parameters import ExtentParameter

    seen = 0
    for alg in registry.algorithms():
        for p in alg.parameters:
            if isinstance(p, ExtentParameter):
                seen += 1
                text = f"{p.description} {p.expected()}"
                assert "[CRS]" not in text, (alg.id, text)
    assert seen >= 8


def test_source_date_epoch_reaches_dask_workers_started_before_the_run(tmp_path, monkeypatch):
    # mosaic:cut writes each sheet's GeoPackage on a worker: a worker process started before
    # SOURCE_DATE_EPOCH was set wrote the current time as gpkg_contents.last_change
    import sqlite3

    import geopandas as gpd
    import shapely
    from distributed import LocalCluster

    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    monkeypatch.delenv("OGR_CURRENT_DATE", raising=False)
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    gpd.GeoDataFrame({"v": [1, 2]}, geometry=[shapely.Point(10, 10), shapely.Point(60, 10)],
                     crs="EPSG:32633").to_file(tmp_path / "pts.gpkg", layer="pts")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # 2023-11-14T22:13:20Z
        toolbox.run("mosaic:cut", {"INPUT": str(tmp_path / "pts.gpkg"), "SCALE": 100,
                                   "SHEET_WIDTH": 50, "SHEET_HEIGHT": 40,
                                   "OUTPUT": str(tmp_path / "out"),
                                   "SCHEDULER": cluster.scheduler_address})
    files = sorted((tmp_path / "out").glob("*.gpkg"))
    assert [f.name for f in files] == ["0_0.gpkg", "1_0.gpkg", "sheets.gpkg"]
    for f in files:
        with sqlite3.connect(f) as db:
            assert db.execute("select last_change from gpkg_contents").fetchall() == [
                ("2023-11-14T22:13:20.000Z",)], f.name


def test_on_worker_sets_and_restores_the_date(monkeypatch):
    import os

    from toolbox.io.source_date import on_worker

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "5")
    monkeypatch.delenv("OGR_CURRENT_DATE", raising=False)
    with on_worker("1700000000"):
        with on_worker("1700000000"):
            assert os.environ["SOURCE_DATE_EPOCH"] == "1700000000"
        assert os.environ["OGR_CURRENT_DATE"] == "2023-11-14T22:13:20.000Z"
    assert os.environ["SOURCE_DATE_EPOCH"] == "5" and "OGR_CURRENT_DATE" not in os.environ
    with on_worker(None):
        assert os.environ["SOURCE_DATE_EPOCH"] == "5"
