"""I/O helpers: formats in, GeoPackage layers out, GeoTIFF options, windows, grids, staging, CRS."""

from __future__ import annotations

from pathlib import Path

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import rasterio
import shapely
from affine import Affine

from tests.toolbox.test_output_folders import hashes
from toolbox.errors import InputDataError, ParameterError
from toolbox.io.crs import common_crs, parse_crs
from toolbox.io.grid import GridSpec
from toolbox.io.raster import geotiff_profile
from toolbox.io.staging import OutputStaging, atomic_path
from toolbox.io.vector import read_vector
from toolbox.io.vector_points import points_xyz, vertices_xyz
from toolbox.io.vector_write import write_layers
from toolbox.raster.writer import write_raster


def test_several_named_layers_in_one_geopackage(tmp_path):
    path = tmp_path / "out.gpkg"
    pts = gpd.GeoDataFrame({"id": [1]}, geometry=[shapely.Point(0, 0, 5)], crs=3003)
    polys = gpd.GeoDataFrame({"id": [1, 2]}, geometry=[shapely.box(0, 0, 1, 1),
                                                       shapely.MultiPolygon([shapely.box(2, 2, 3, 3)])])
    empty = gpd.GeoDataFrame({"id": []}, geometry=[], crs=3003)
    write_layers(path, {"nodes": pts, "areas": polys, "errors": empty}, crs="EPSG:3003",
                 geometry_types={"errors": "Point"})
    layers = dict(pyogrio.list_layers(path))
    assert layers == {"nodes": "Point Z", "areas": "MultiPolygon", "errors": "Point"}
    assert read_vector(f"{path}|layername=areas").crs.to_epsg() == 3003


def test_points_from_csv_geometry_z_and_field(tmp_path):
    csv = tmp_path / "p.csv"
    csv.write_text("name,x,y,z,h\na,1,2,3,30\nb,4,5,6,60\n")
    frame = read_vector(csv, crs="EPSG:3003")
    assert frame.crs.to_epsg() == 3003
    np.testing.assert_array_equal(points_xyz(frame), [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(points_xyz(frame, "h")[:, 2], [30, 60])


def test_points_without_z_or_with_nan_refused():
    flat = gpd.GeoDataFrame(geometry=[shapely.Point(0, 0)])
    with pytest.raises(InputDataError, match="no Z"):
        points_xyz(flat)
    nan = gpd.GeoDataFrame({"z": [np.nan]}, geometry=[shapely.Point(0, 0)])
    with pytest.raises(InputDataError, match="NaN"):
        points_xyz(nan, "z")
    lines = gpd.GeoDataFrame(geometry=[shapely.LineString([(0, 0, 1), (1, 1, 2)])])
    with pytest.raises(InputDataError, match="must contain points"):
        points_xyz(lines)


def test_points_without_z_or_with_nan_are_named_by_input_row():
    """Rows count the input's features from 1, nulls and multipoint parts included."""
    p = shapely.Point
    some_2d = gpd.GeoDataFrame(geometry=[p(0, 0, 1), p(1, 0), None, p(2, 0, 1), p(3, 0)])
    with pytest.raises(InputDataError, match=r"^INPUT: 2 of 4 features \(rows 2, 5, counting "
                                             r"from 1\) have no Z: give a Z field \(Z_FIELD\) "
                                             r"or use 3D points$"):
        points_xyz(some_2d)
    nan = gpd.GeoDataFrame(geometry=[None, shapely.MultiPoint([(0, 0, 1), (1, 0, 2)]),
                                     p(2, 0, np.nan)])
    with pytest.raises(InputDataError, match=r"^INPUT: 1 feature\(s\) \(row 3, counting from "
                                             r"1\) have NaN/inf coordinates or Z$"):
        points_xyz(nan)


def test_line_vertices_with_nan_z_are_named_by_feature_row():
    """The NaN Z is vertex 4 of the layer, on feature 2: the message names feature 2."""
    lines = gpd.GeoDataFrame(geometry=[shapely.LineString([(0, 0, 1), (1, 0, 1), (2, 0, 1)]),
                                       shapely.LineString([(0, 1, 1), (1, 1, np.nan)])])
    with pytest.raises(InputDataError, match=r"^BREAKLINES: 1 feature\(s\) \(row 2, counting "
                                             r"from 1\) have NaN/inf coordinates or Z$"):
        vertices_xyz(lines, name="BREAKLINES")


def test_line_vertices_with_contour_field():
    lines = gpd.GeoDataFrame({"elev": [100.0, 105.0]},
                             geometry=[shapely.LineString([(0, 0), (1, 0)]),
                                       shapely.LineString([(0, 1), (1, 1), (2, 1)])])
    xyz, index = vertices_xyz(lines, "elev")
    assert xyz.shape == (5, 3) and list(index) == [0, 0, 1, 1, 1]
    assert list(xyz[:, 2]) == [100, 100, 105, 105, 105]


@pytest.mark.filterwarnings("ignore:.crs. was not provided")
def test_dxf_and_geojson_are_read(tmp_path):
    frame = gpd.GeoDataFrame({"Layer": ["a"]}, geometry=[shapely.LineString([(0, 0, 1), (5, 5, 2)])])
    frame.to_file(tmp_path / "l.dxf", driver="DXF")
    frame.set_crs(3003).to_file(tmp_path / "l.geojson", driver="GeoJSON")
    dxf = read_vector(tmp_path / "l.dxf", crs="EPSG:3003")
    assert dxf.geometry.iloc[0].has_z and dxf.crs.to_epsg() == 3003
    assert len(read_vector(tmp_path / "l.geojson")) == 1


def test_geotiff_profile_is_tiled_compressed(tmp_path):
    path = tmp_path / "big.tif"
    data = np.arange(1024 * 600, dtype="float32").reshape(600, 1024)
    write_raster(path, data, Affine(1, 0, 0, 0, -1, 600), "EPSG:3003", nodata=-1, overviews=True)
    with rasterio.open(path) as ds:
        assert ds.profile["tiled"] and ds.profile["compress"] == "deflate"
        assert ds.tags(ns="IMAGE_STRUCTURE").get("PREDICTOR") == "3"
        assert ds.overviews(1) == [2] and ds.nodata == -1
        np.testing.assert_array_equal(ds.read(1), data)
    assert geotiff_profile(10, 10, 1, "uint8", None, Affine.identity())["predictor"] == 2


def test_grid_snapping_centres_and_guard():
    grid = GridSpec.from_bounds((1688001.3, 4799000.2, 1688010.1, 4799005.0), 2.0, "EPSG:3003")
    assert grid.bounds == (1688000.0, 4799000.0, 1688012.0, 4799006.0)
    assert (grid.width, grid.height) == (6, 3)
    x, y = grid.cell_centers()
    assert x[0] == 1688001.0 and y[0] == 4799005.0
    with pytest.raises(ParameterError, match="over the limit"):
        GridSpec.from_bounds((0, 0, 1e6, 1e6), 0.01, max_cells=10**9)


def test_staging_commit_and_rollback(tmp_path):
    staging = OutputStaging()
    staged = staging.stage(tmp_path / "sub" / "a.txt")
    staged.write_text("ok")
    (staged.parent / "a.txt.aux.xml").write_text("<x/>")
    assert not (tmp_path / "sub" / "a.txt").exists()
    staging.commit()
    assert (tmp_path / "sub" / "a.txt").read_text() == "ok"
    assert (tmp_path / "sub" / "a.txt.aux.xml").exists()
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["a.txt", "a.txt.aux.xml"]
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "b.txt") as p:
        p.write_text("half")
        raise RuntimeError
    assert not (tmp_path / "b.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub"]


def _points(n, x0=0.0, crs=3003):
    return gpd.GeoDataFrame({"id": np.arange(n)}, geometry=shapely.points(
        np.column_stack([x0 + np.arange(n) * 10.0, np.zeros(n)])), crs=crs)


@pytest.mark.filterwarnings("ignore:.crs. was not provided")
def test_a_new_shapefile_drops_the_index_of_the_file_it_replaces(tmp_path):
    """--overwrite of a Shapefile, or a new one where only the old one's .qix and .sbn lie: the
    old .qix, .sbn and .prj, which the new file does not rewrite, go; GDAL's bbox query (which
    reads the .qix) then finds the new points."""
    out = tmp_path / "w.shp"
    for overwrite in (True, False):
        pyogrio.write_dataframe(_points(500, x0=5000.0), out,
                                layer_options={"SPATIAL_INDEX": "YES"})
        (tmp_path / "w.sbn").write_text("old index")
        if not overwrite:  # the old file deleted, its indexes left
            for suffix in (".shp", ".shx", ".dbf", ".prj", ".cpg"):
                out.with_suffix(suffix).unlink()
        assert (tmp_path / "w.qix").exists()
        staging = OutputStaging()
        pyogrio.write_dataframe(_points(30, crs=None), staging.stage(out))  # no .prj, no .qix
        staging.commit(overwrite=overwrite)
        names = {p.name for p in tmp_path.iterdir()}
        assert {"w.shp", "w.shx", "w.dbf"} <= names and not names & {"w.qix", "w.sbn", "w.prj"}
        assert len(pyogrio.read_dataframe(out, bbox=(-1, -1, 95, 1))) == 10
        assert pyogrio.read_info(out)["crs"] is None


def test_a_new_raster_drops_a_stale_aux_xml(tmp_path):
    """A leftover a.tif.aux.xml (of a deleted a.tif) is removed when a new a.tif comes in,
    with or without --overwrite: GDAL reads the new file's own CRS, transform and nodata."""
    for overwrite in (False, True):
        out = tmp_path / f"a{overwrite}.tif"
        Path(f"{out}.aux.xml").write_text(
            "<PAMDataset><SRS>EPSG:32632</SRS><GeoTransform>5e5, 10, 0, 4.8e6, 0, -10"
            "</GeoTransform><PAMRasterBand band='1'><NoDataValue>0</NoDataValue><Offset>100"
            "</Offset><Scale>2</Scale></PAMRasterBand></PAMDataset>")
        staging = OutputStaging()
        write_raster(staging.stage(out), np.ones((3, 4), "float32"),
                     Affine(2.0, 0, 1688000.0, 0, -2.0, 4799000.0), "EPSG:3003", nodata=-9999.0)
        staging.commit(overwrite=overwrite)
        assert not Path(f"{out}.aux.xml").exists()
        with rasterio.open(out) as src:
            assert src.crs.to_epsg() == 3003 and src.nodata == -9999.0
            assert src.transform == Affine(2.0, 0, 1688000.0, 0, -2.0, 4799000.0)
            assert src.scales == (1.0,) and src.offsets == (0.0,)


def _stale_wal(tmp_path, gpkg):
    """The -wal an earlier GeoPackage left when its writer had it open (QGIS) or crashed."""
    import shutil
    import sqlite3

    old = tmp_path / "old.gpkg"
    pyogrio.write_dataframe(_points(50), old, driver="GPKG")
    con = sqlite3.connect(old)
    con.execute("pragma journal_mode=wal")
    con.execute("pragma wal_autocheckpoint=0")
    con.execute("create table junk(a)")
    con.executemany("insert into junk values (?)", [(i,) for i in range(1000)])
    con.commit()
    shutil.copy(f"{old}-wal", f"{gpkg}-wal")
    con.close()
    old.unlink()


def _geopackage_ok(path):
    import sqlite3

    con = sqlite3.connect(path)
    try:
        return con.execute("pragma integrity_check").fetchall() == [("ok",)]
    finally:
        con.close()


def test_a_new_geopackage_drops_a_stale_wal(tmp_path):
    """A -wal left beside the output's name (no GeoPackage there, or one replaced with
    --overwrite) goes before the new file comes in: SQLite would replay it into the new file
    ("malformed database schema")."""
    out = tmp_path / "x.gpkg"
    for overwrite in (False, True):
        _stale_wal(tmp_path, out)
        staging = OutputStaging()
        pyogrio.write_dataframe(_points(7), staging.stage(out), driver="GPKG")
        staging.commit(overwrite=overwrite)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["x.gpkg"]
        assert _geopackage_ok(out) and len(pyogrio.read_dataframe(out)) == 7


@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="seen through Linux's /proc/locks")
def test_a_geopackage_open_in_another_program_is_not_replaced(tmp_path):
    """--overwrite of a GeoPackage another process has open in WAL mode (QGIS showing it):
    refused, naming it; the file and its -wal are left as they are."""
    import subprocess
    import sys

    out = tmp_path / "y.gpkg"
    pyogrio.write_dataframe(_points(5), out, driver="GPKG")
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sqlite3, sys; c = sqlite3.connect(sys.argv[1]); "
        "c.execute('pragma journal_mode=wal'); c.execute('create table t(a)'); c.commit(); "
        "print('open', flush=True); sys.stdin.read()"), str(out)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "open"
        before = hashes(tmp_path)
        assert "y.gpkg-wal" in before
        staging = OutputStaging()
        pyogrio.write_dataframe(_points(7), staging.stage(out), driver="GPKG")
        with pytest.raises(ParameterError, match=r"OUTPUT '.*y.gpkg' is open in another program"):
            staging.commit(overwrite=True)
        staging.rollback()
        assert hashes(tmp_path) == before
    finally:
        holder.stdin.close()
        holder.wait()

def test_mixed_crs_refused():
    a, b = parse_crs("EPSG:3003"), parse_crs("EPSG:32632")
    assert common_crs({"INPUT": a, "LINES": None}) == a
    with pytest.raises(InputDataError, match="LINES is in EPSG:32632 but INPUT is in EPSG:3003"):
        common_crs({"INPUT": a, "LINES": b})


OPEN_WITHOUT_PANDAS = """
import sys
path = sys.argv[1]
from toolbox.io.vector import open_layer
from toolbox.io.vector_points import read_points_xyz
ref = open_layer(path + "|layername=pts")
assert (ref.count, ref.fields, ref.geometry_kind) == (2, ["h"], "point"), ref.info
assert "pandas" not in sys.modules and "geopandas" not in sys.modules, "pandas imported"
assert read_points_xyz(ref, "h").tolist() == [[0.0, 0.0, 1.0], [1.0, 1.0, 2.0]]
assert "pandas" not in sys.modules and "geopandas" not in sys.modules, "pandas imported"
import numpy as np, shapely
from rasterio.crs import CRS
from toolbox.io.vector_write import write_wkb_layer
out = path.replace("p.gpkg", "lines.gpkg")
write_wkb_layer(out, "lines", shapely.to_wkb([shapely.LineString([(0, 0, 5), (1, 2, 5)])],
                output_dimension=3), {"elev": np.array([5.0])}, "LineString Z",
                CRS.from_epsg(3003))
assert "pandas" not in sys.modules and "geopandas" not in sys.modules, "pandas imported"
import pyogrio  # the rest of pyogrio still works, loaded on first use
from pyogrio import read_dataframe
assert read_dataframe(path)["h"].tolist() == [1.0, 2.0]
back = read_dataframe(out, layer="lines")
assert back["elev"].tolist() == [5.0] and back.crs.to_epsg() == 3003
assert back.geometry[0].equals(shapely.LineString([(0, 0, 5), (1, 2, 5)]))
assert pyogrio.__version__ and "geopandas" in sys.modules
"""


def test_opening_a_layer_imports_neither_pandas_nor_geopandas(tmp_path):
    """Parameter validation opens inputs through pyogrio.core only (start-up < 0.5 s), points
    are read through Arrow and a layer written from arrays without pandas; the rest of pyogrio
    (read_dataframe, __version__) is loaded on first use."""
    import subprocess
    import sys

    path = tmp_path / "p.gpkg"
    gpd.GeoDataFrame({"h": [1.0, 2.0]}, geometry=shapely.points([0, 1], [0, 1]),
                     crs=3003).to_file(path, layer="pts")
    proc = subprocess.run([sys.executable, "-c", OPEN_WITHOUT_PANDAS, str(path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_window_transform_is_rasterios():
    """GridSpec.window_transform writes rasterio's windows.transform out: the same numbers,
    bit for bit, on large projected coordinates and any window."""
    import warnings

    from affine import Affine
    from rasterio.windows import Window, transform

    from toolbox.io.grid import GridSpec

    rng = np.random.default_rng(4)
    for _ in range(200):
        t = Affine(rng.uniform(0.1, 5), 0.0, rng.uniform(1e6, 2e6), 0.0, -rng.uniform(0.1, 5),
                   rng.uniform(4e6, 5e6))
        window = Window(int(rng.integers(0, 9000)), int(rng.integers(0, 9000)), 512, 300)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rasterio's own Affine * deprecation warning
            expected = transform(window, t)
        assert tuple(GridSpec(t, 9999, 9999).window_transform(window)) == tuple(expected)


@pytest.mark.parametrize("name", ["lines.gpkg", "lines.parquet", "lines.fgb"])
def test_wkb_layer_from_arrays(tmp_path, name):
    from pyproj import CRS

    from toolbox.io.vector_write import write_wkb_layer

    lines = [shapely.LineString([(0, 0, 5), (1, 2, 5)]),
             shapely.LineString([(3, 3, 7), (4, 3, 7), (4, 4, 7), (3, 3, 7)])]
    fields = {"elev": np.array([5.0, 7.0]), "index": np.array([0, 1], dtype="int32")}
    path = tmp_path / name
    write_wkb_layer(path, "contours", shapely.to_wkb(lines, output_dimension=3), fields,
                    "LineString Z", CRS.from_epsg(3003))
    read = gpd.read_parquet if name.endswith(".parquet") else gpd.read_file
    back = read(path).sort_values("elev")  # FlatGeobuf's index orders features in space
    assert back.crs.to_epsg() == 3003
    assert list(back["elev"]) == [5.0, 7.0] and list(back["index"]) == [0, 1]
    assert all(a.equals(b) and b.has_z for a, b in zip(lines, back.geometry))
    # an empty layer is still created, with its type
    empty = tmp_path / ("empty_" + name)
    write_wkb_layer(empty, "contours", np.empty(0, dtype=object),
                    {"elev": np.empty(0)}, "LineString Z", CRS.from_epsg(3003))
    assert len(read(empty)) == 0
