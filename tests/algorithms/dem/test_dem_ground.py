"""dem:ground on a rendered scene with known ground: analytic rolling terrain, box buildings and
Gaussian-blob trees sampled as a point cloud (and as a DSM raster). Truth: the analytic terrain
and the per-point ground flag of the rendering."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine
from click.testing import CliRunner

import toolbox
from toolbox.io.pointcloud import write_point_cloud

X0, Y0, SIZE = 1_688_000.0, 4_799_500.0, 160.0
BUILDINGS = [(20, 30, 50, 55, 12.0), (90, 20, 125, 40, 8.0), (100, 100, 140, 135, 15.0)]
TREES = [(40, 110, 4.0, 9.0), (70, 80, 3.0, 7.0), (140, 70, 3.5, 10.0), (20, 140, 3.0, 6.0)]


def terrain(x, y):
    """Ground height at local x, y (m): a 4 m high rolling surface on a 3 % tilt."""
    return 250.0 + 0.03 * x + 4.0 * np.sin(x / 25.0) * np.cos(y / 30.0)


def objects(x, y):
    """Height of buildings (flat roofs) and trees above the ground, m."""
    h = np.zeros_like(x)
    for x1, y1, x2, y2, height in BUILDINGS:
        h = np.where((x >= x1) & (x <= x2) & (y >= y1) & (y <= y2), np.maximum(h, height), h)
    for cx, cy, radius, height in TREES:
        r2 = ((x - cx) ** 2 + (y - cy) ** 2) / radius ** 2
        h = np.maximum(h, np.where(r2 < 4, height * np.exp(-r2), 0.0))
    return h


def in_buildings(x, y, margin=0.0):
    inside = np.zeros(np.shape(x), bool)
    for x1, y1, x2, y2, _ in BUILDINGS:
        inside |= (x >= x1 - margin) & (x <= x2 + margin) & (y >= y1 - margin) & (y <= y2 + margin)
    return inside


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ground")
    rng = np.random.default_rng(11)
    n = 60_000  # ~2.3 points / m²
    x, y = rng.uniform(0, SIZE, n), rng.uniform(0, SIZE, n)
    h = objects(x, y)
    z = terrain(x, y) + h + rng.normal(0, 0.03, n)
    laz = tmp / "scene.laz"
    write_point_cloud(laz, np.column_stack([X0 + x, Y0 + y, z]), "EPSG:3003")
    # the same scene as a 1 m DSM raster (cell centres)
    c = np.arange(SIZE) + 0.5
    gx, gy = np.meshgrid(c, SIZE - c)
    dsm = (terrain(gx, gy) + objects(gx, gy)).astype("float32")
    dsm_path = tmp / "dsm.tif"
    with rasterio.open(dsm_path, "w", driver="GTiff", width=int(SIZE), height=int(SIZE), count=1,
                       dtype="float32", crs="EPSG:3003",
                       transform=Affine(1, 0, X0, 0, -1, Y0 + SIZE)) as ds:
        ds.write(dsm, 1)
    return {"tmp": tmp, "laz": laz, "dsm": dsm_path, "h": h,
            "xyz": np.column_stack([x, y, z])}


def _read_local(path):
    """Band 1 (masked), the local x, y of its cell centres and its transform."""
    with rasterio.open(path) as ds:
        band = ds.read(1, masked=True)
        t = ds.transform
    rows, cols = np.indices(band.shape)
    return band, t.c + (cols + 0.5) * t.a - X0, t.f + (rows + 0.5) * t.e - Y0, t


def _check_dtm(path, label):
    dtm, x, y, t = _read_local(path)
    inner = (x > 3) & (x < SIZE - 3) & (y > 3) & (y < SIZE - 3) & ~dtm.mask
    err = (dtm.data - terrain(x, y))[inner]
    rmse = float(np.sqrt(np.mean(err ** 2)))
    roofs = inner & in_buildings(x, y)
    roof_err = np.abs(dtm.data - terrain(x, y))[roofs]
    assert inner.sum() > 0.9 * (SIZE - 6) ** 2 / t.a ** 2, label
    assert rmse < 0.25, (label, rmse)  # terrain relief 9 m, buildings up to 15 m
    assert np.percentile(roof_err, 99) < 1.0, (label, np.percentile(roof_err, 99))
    return rmse


def test_ground_from_point_cloud(scene):
    tmp = scene["tmp"]
    res = toolbox.run("dem:ground", {"INPUT": str(scene["laz"]), "CELL_SIZE": 2.0,
                                     "OUTPUT": str(tmp / "dtm.tif"),
                                     "NONGROUND": str(tmp / "ng.tif"),
                                     "HEIGHTS": str(tmp / "heights.tif"),
                                     "GROUND_POINTS": str(tmp / "classified.laz")})
    _check_dtm(tmp / "dtm.tif", "points")
    # HEIGHTS: the highest point of each 2 m cell above the DTM: roofs at their rendered height,
    # open ground (5 m from any object) near 0
    heights, x, y, _ = _read_local(tmp / "heights.tif")
    for x1, y1, x2, y2, height in BUILDINGS:
        roof = (x > x1 + 1) & (x < x2 - 1) & (y > y1 + 1) & (y < y2 - 1) & ~heights.mask
        # the DTM under a roof is interpolated (within 1 m, _check_dtm), a cell spans 2 m of slope
        assert np.abs(heights.data[roof] - height).max() < 1.0, height
    gx, gy = np.meshgrid(np.linspace(-5, 5, 5), np.linspace(-5, 5, 5))
    near = np.zeros(x.shape, bool)
    for dx, dy in zip(gx.ravel(), gy.ravel(), strict=True):
        near |= objects(x + dx, y + dy) > 0.05
    open_ground = ~near & ~heights.mask
    assert open_ground.sum() > 1000 and np.percentile(heights.data[open_ground], 99) < 0.3
    # per-point classification against the rendering's truth
    import laspy

    las = laspy.read(tmp / "classified.laz")
    got = np.asarray(las.classification) == 2
    h = scene["h"]  # objects lower than ELEVATION_THRESHOLD (tree skirts) are ground to any filter
    assert np.mean(got[h > 2.0]) < 0.005  # objects called ground (type II)
    assert np.mean(got[h > 1.0]) < 0.05  # smooth 1-2 m tree skirts pass as terrain
    assert np.mean(~got[h == 0]) < 0.02  # ground called objects (type I)
    # the mask: building cells are 1, open-ground cells far from objects are 0
    with rasterio.open(tmp / "ng.tif") as ds:
        mask = ds.read(1)
        t = ds.transform
    rows, cols = np.indices(mask.shape)
    x, y = t.c + (cols + 0.5) * t.a - X0, t.f + (rows + 0.5) * t.e - Y0
    assert np.mean(mask[in_buildings(x, y, -1.0)] == 1) > 0.98
    assert res["STATISTICS"]["ground_filter"]["ground"] == got.sum()
    # the DTM is dem:tin_linear of the ground points (the same gridding code, no fork)
    with rasterio.open(tmp / "dtm.tif") as ds:
        dtm, bounds = ds.read(1, masked=True), ds.bounds
    toolbox.run("dem:tin_linear", {"INPUT": str(tmp / "classified.laz"), "CLASSES": "2",
                                   "CELL_SIZE": 2.0, "EXTENT": ",".join(map(str, bounds)),
                                   "OUTPUT": str(tmp / "again.tif")})
    with rasterio.open(tmp / "again.tif") as ds:
        again = ds.read(1, masked=True)
    assert np.array_equal(again.mask, dtm.mask)
    assert np.abs(again - dtm).max() < 2e-3  # the LAZ stores millimetres


def test_ground_from_dsm(scene):
    tmp = scene["tmp"]
    toolbox.run("dem:ground", {"DSM": str(scene["dsm"]), "OUTPUT": str(tmp / "dtm_dsm.tif"),
                               "NONGROUND": str(tmp / "ng_dsm.tif"),
                               "HEIGHTS": str(tmp / "heights_dsm.tif")})
    with rasterio.open(tmp / "dtm_dsm.tif") as ds, rasterio.open(scene["dsm"]) as ref:
        assert ds.transform == ref.transform and ds.shape == ref.shape
    _check_dtm(tmp / "dtm_dsm.tif", "dsm")
    # HEIGHTS: the DSM above the DTM, against the rendered objects' heights at the cell centres
    heights, x, y, _ = _read_local(tmp / "heights_dsm.tif")
    truth = objects(x, y)
    inner = (x > 3) & (x < SIZE - 3) & (y > 3) & (y < SIZE - 3) & ~heights.mask
    err = np.abs(heights.data - truth)[inner]
    assert np.percentile(err, 95) < 0.5, np.percentile(err, 95)
    roofs = inner & in_buildings(x, y, -1.0)
    assert np.abs(heights.data - truth)[roofs].max() < 1.0  # 8-15 m roofs stand up


def test_ground_from_an_integer_dsm_with_nodata(scene, tmp_path):
    """An Int16 DSM of whole metres with a nodata hole (integer DSMs are common) gives the DTM,
    mask and point count of the same heights stored as Float32 with the same nodata, cell for
    cell (it crashed: "Cannot convert fill_value nan to dtype int16")."""
    with rasterio.open(scene["dsm"]) as ref:
        metres = np.rint(ref.read(1)).astype("int16")
        profile = ref.profile | {"nodata": -32768}
    metres[40:44, 60:64] = -32768
    runs = {}
    for dtype in ("int16", "float32"):
        dsm = tmp_path / f"dsm_{dtype}.tif"
        with rasterio.open(dsm, "w", **(profile | {"dtype": dtype})) as ds:
            ds.write(metres.astype(dtype), 1)
        res = toolbox.run("dem:ground", {"DSM": str(dsm), "OUTPUT": str(tmp_path / f"{dtype}.tif"),
                                         "NONGROUND": str(tmp_path / f"ng_{dtype}.tif")})
        with rasterio.open(tmp_path / f"{dtype}.tif") as a, \
                rasterio.open(tmp_path / f"ng_{dtype}.tif") as b:
            runs[dtype] = a.read(1), b.read(1), res["STATISTICS"]["ground_filter"]["points"]
    assert runs["int16"][2] == metres.size - 16  # the hole is no DSM point
    np.testing.assert_array_equal(runs["int16"][0], runs["float32"][0])
    np.testing.assert_array_equal(runs["int16"][1], runs["float32"][1])
    assert (runs["int16"][0] != -9999.0).mean() > 0.9  # NODATA's default


def test_ground_bad_input_exit_2(scene, tmp_path):
    from toolbox.cli import main

    out = tmp_path / "d.tif"
    runner = CliRunner()
    for args, text in (([], "give exactly one of INPUT"),
                       (["--INPUT", str(scene["laz"]), "--DSM", str(scene["dsm"])],
                        "give exactly one"),
                       (["--DSM", str(scene["dsm"]), "--FILTER_CELL", "2"], "FILTER_CELL"),
                       (["--INPUT", str(scene["laz"]), "--CLASSES", "6"], "CLASSES 6 not in")):
        res = runner.invoke(main, ["run", "dem:ground", *args, "--OUTPUT", str(out),
                                   "--NONGROUND", str(tmp_path / "m.tif")])
        assert res.exit_code == 2, (args, res.output)
        assert text in res.stderr and "Traceback" not in res.output
        assert len(res.stderr.strip().splitlines()) == 1
        assert not out.exists() and not (tmp_path / "m.tif").exists()


def test_ground_refuses_a_mask_in_another_crs_and_a_south_up_dsm(scene, tmp_path):
    """The MASK (like TEMPLATE and EXTENT) must share the DSM's CRS: a mask in UTM was applied
    with its raw numbers (22,000 cells more kept, in silence); a DSM stored south-up is refused
    naming DSM (the message named a TEMPLATE the user never gave)."""
    import geopandas as gpd
    import shapely

    mask = gpd.GeoDataFrame(geometry=[shapely.box(X0 + 5, Y0 + 5, X0 + 50, Y0 + 50)],
                            crs="EPSG:3003").to_crs("EPSG:32632")
    mask.to_file(tmp_path / "mask_utm.gpkg")
    with pytest.raises(toolbox.InputDataError, match="MASK is in EPSG:32632 but DSM is in "
                                                     "EPSG:3003"):
        toolbox.run("dem:ground", {"DSM": str(scene["dsm"]),
                                   "MASK": str(tmp_path / "mask_utm.gpkg"),
                                   "OUTPUT": str(tmp_path / "a.tif"),
                                   "NONGROUND": str(tmp_path / "b.tif")})
    with rasterio.open(scene["dsm"]) as ref:
        z, t, profile = ref.read(1), ref.transform, ref.profile
    flipped = tmp_path / "dsm_south_up.tif"
    with rasterio.open(flipped, "w", **(profile | {"transform": Affine(
            t.a, 0, t.c, 0, -t.e, t.f + t.e * z.shape[0])})) as dst:
        dst.write(z[::-1], 1)
    with pytest.raises(toolbox.ParameterError, match="DSM .*south-up.*gdalwarp"):
        toolbox.run("dem:ground", {"DSM": str(flipped), "OUTPUT": str(tmp_path / "c.tif"),
                                   "NONGROUND": str(tmp_path / "d.tif")})
    assert not (tmp_path / "a.tif").exists() and not (tmp_path / "c.tif").exists()
