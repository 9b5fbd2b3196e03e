"""Round 19 (seamspeed): write_layers hands pyogrio's raw writer what pyogrio.write_dataframe
would (no pandas inference per layer), and keeps SQLite's rollback journal in memory while
writing a staged GeoPackage. The reference is pyogrio's own write_dataframe of the same frames."""

from __future__ import annotations

import sqlite3
import warnings

import geopandas as gpd
import numpy as np
import pandas as pd
import pyogrio
import pytest
import shapely
from pyproj import CRS

from toolbox.io.vector import GPKG_DATASET_OPTIONS
from toolbox.io.vector_write import staged_gpkg_writes, write_layers

CRS_3003 = CRS("EPSG:3003")


def _frames() -> tuple[dict, dict]:
    """Layers of every column kind the toolbox writes, with missing values and geometries."""
    square = shapely.box(0, 0, 10, 10)
    multi = shapely.MultiPolygon([shapely.box(20, 0, 30, 10), shapely.box(40, 0, 50, 10)])
    polys = gpd.GeoDataFrame({
        "n": np.array([1, 2, 3, 4], dtype="int64"),
        "small": np.array([1, 2, 3, 4], dtype="int32"),
        "x": [1.5, np.nan, np.inf, -0.25],
        "flag": [True, False, True, False],
        "text": ["a", None, "ç€", ""],
        "label": pd.array(["p", pd.NA, "q", "r"], dtype="string"),
        "count": pd.array([1, None, 3, 4], dtype="Int64"),
        "ok": pd.array([True, None, False, True], dtype="boolean"),
        "when": pd.to_datetime(["2024-01-02", "2024-03-04", None, "2025-12-31"]),
        "mixed": [1, "two", 3.0, None],
    }, geometry=[square, multi, None, shapely.Polygon()], crs=CRS_3003)
    lines = gpd.GeoDataFrame({"a": ["x", "y"]}, geometry=[
        shapely.LineString([(0, 0), (1, 1)]),
        shapely.MultiLineString([[(2, 2), (3, 3)], [(4, 4), (5, 6)]])], crs=CRS_3003)
    points_z = gpd.GeoDataFrame({"z": [1.0, 2.0]}, geometry=[shapely.Point(1, 2, 3),
                                                             shapely.Point(4, 5, 6)], crs=CRS_3003)
    single = gpd.GeoDataFrame({"k": [1, 2]}, geometry=[square, multi], crs=CRS_3003)
    empty = gpd.GeoDataFrame({"k": np.array([], dtype="int64")},
                             geometry=gpd.GeoSeries([], crs=CRS_3003), crs=CRS_3003)
    no_crs = gpd.GeoDataFrame({"k": [7]}, geometry=[shapely.Point(0, 0)])
    layers = {"polys": polys, "lines": lines, "points_z": points_z, "single": single,
              "empty": empty, "no_crs": no_crs}
    types = {"polys": "MultiPolygon", "lines": "MultiLineString", "points_z": "Point Z",
             "single": "Polygon", "empty": "Point", "no_crs": "Point"}
    return layers, types


def _reference(path, layers: dict, types: dict) -> None:
    """pyogrio.write_dataframe as write_layers called it before (geometry_type only)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k, (name, frame) in enumerate(layers.items()):
            options = {"dataset_options": GPKG_DATASET_OPTIONS} if k == 0 and \
                str(path).endswith(".gpkg") else {}
            pyogrio.write_dataframe(frame, path, layer=name, geometry_type=types[name],
                                    **options)


def _same_layer(a, b, layer: str | None = None) -> None:
    info_a, info_b = pyogrio.read_info(a, layer=layer), pyogrio.read_info(b, layer=layer)
    for key in ("crs", "fields", "dtypes", "geometry_type", "features", "fid_column"):
        assert str(info_a[key]) == str(info_b[key]), (layer, key, info_a[key], info_b[key])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fa = pyogrio.read_dataframe(a, layer=layer, fid_as_index=True)
        fb = pyogrio.read_dataframe(b, layer=layer, fid_as_index=True)
    pd.testing.assert_frame_equal(fa.drop(columns="geometry"), fb.drop(columns="geometry"))
    assert list(fa.index) == list(fb.index)
    assert list(shapely.to_wkb(fa.geometry.values)) == list(shapely.to_wkb(fb.geometry.values))


def test_write_layers_writes_what_pyogrio_write_dataframe_writes(tmp_path):
    layers, types = _frames()
    ours, ref = tmp_path / "ours.gpkg", tmp_path / "ref.gpkg"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_layers(ours, layers, geometry_types=types)
    _reference(ref, layers, types)
    assert pyogrio.list_layers(ours).tolist() == pyogrio.list_layers(ref).tolist()
    for name in layers:
        _same_layer(ours, ref, name)
    queries = ["SELECT table_name, data_type, srs_id, min_x, min_y, max_x, max_y "
               "FROM gpkg_contents ORDER BY 1",
               "SELECT * FROM gpkg_geometry_columns ORDER BY 1",
               "SELECT * FROM gpkg_extensions ORDER BY 1, 2, 3",
               "SELECT type, name, sql FROM sqlite_master ORDER BY name",
               "PRAGMA application_id", "PRAGMA user_version"]
    with sqlite3.connect(ours) as da, sqlite3.connect(ref) as db:
        for q in queries:
            assert da.execute(q).fetchall() == db.execute(q).fetchall(), q
        for name in layers:  # the spatial index holds the same boxes
            table = f"rtree_{name}_geom"
            if da.execute("SELECT count(*) FROM sqlite_master WHERE name = ?",
                          (table,)).fetchone()[0]:
                q = f"SELECT * FROM {table} ORDER BY id"
                assert da.execute(q).fetchall() == db.execute(q).fetchall()
    da.close()
    db.close()


@pytest.mark.parametrize("ext", [".shp", ".geojson", ".fgb"])
def test_one_layer_formats_are_written_as_pyogrio_writes_them(tmp_path, ext):
    layers, types = _frames()
    frame = layers["lines"]
    ours, ref = tmp_path / f"ours{ext}", tmp_path / f"ref{ext}"
    write_layers(ours, {"lines": frame}, geometry_types={"lines": types["lines"]})
    _reference(ref, {"lines": frame}, types)
    _same_layer(ours, ref)


def test_mixed_dimensions_in_flatgeobuf_still_refused_by_pyogrio(tmp_path):
    """FlatGeobuf takes no 2D and 3D in one layer: pyogrio's own check still runs."""
    frame = gpd.GeoDataFrame({"k": [1, 2]}, geometry=[shapely.Point(0, 0),
                                                      shapely.Point(1, 1, 1)], crs=CRS_3003)
    with pytest.raises(pyogrio.errors.DataSourceError, match="Mixed 2D and 3D"):
        pyogrio.write_dataframe(frame, tmp_path / "ref.fgb", geometry_type="Point")
    with pytest.raises(Exception, match="Mixed 2D and 3D"):  # named a write error there
        write_layers(tmp_path / "ours.fgb", {"k": frame}, geometry_types={"k": "Point"})


def test_plain_frames_skip_write_dataframe(tmp_path, monkeypatch):
    """Fails on the old code: every layer went through write_dataframe (its inference of the
    geometry types and dimensions through pandas: about 1.3 ms a layer)."""
    layers, types = _frames()
    plain = {k: layers[k] for k in ("lines", "points_z", "single", "empty")}

    def refuse(*args, **kwargs):
        raise AssertionError("write_dataframe called")

    monkeypatch.setattr(pyogrio, "write_dataframe", refuse)
    write_layers(tmp_path / "plain.gpkg", plain, geometry_types=types)
    assert [n for n, _ in pyogrio.list_layers(tmp_path / "plain.gpkg")] == list(plain)


def test_dates_with_time_zones_still_go_through_write_dataframe(tmp_path):
    """A column pyogrio converts itself (a date with a time zone) takes its own path."""
    frame = gpd.GeoDataFrame(
        {"when": pd.to_datetime(["2024-01-02 10:00", "2024-06-01 12:30"]).tz_localize(
            "Europe/Rome")}, geometry=[shapely.Point(0, 0), shapely.Point(1, 1)], crs=CRS_3003)
    ours, ref = tmp_path / "ours.gpkg", tmp_path / "ref.gpkg"
    write_layers(ours, {"t": frame}, geometry_types={"t": "Point"})
    _reference(ref, {"t": frame}, {"t": "Point"})
    _same_layer(ours, ref, "t")


def test_staged_writes_keep_the_journal_in_memory_and_restore_it():
    """Fails on the old code: only OGR_SQLITE_SYNCHRONOUS was set (each layer written made and
    removed a -journal file beside the GeoPackage)."""
    from pyogrio import get_gdal_config_option, set_gdal_config_options

    set_gdal_config_options({"OGR_SQLITE_JOURNAL": None, "OGR_SQLITE_SYNCHRONOUS": None})
    with staged_gpkg_writes():
        assert get_gdal_config_option("OGR_SQLITE_JOURNAL") == "MEMORY"
        # pyogrio reads an ON/OFF option as a Boolean
        assert get_gdal_config_option("OGR_SQLITE_SYNCHRONOUS") in ("OFF", False)
    assert get_gdal_config_option("OGR_SQLITE_JOURNAL") is None
    assert get_gdal_config_option("OGR_SQLITE_SYNCHRONOUS") is None
