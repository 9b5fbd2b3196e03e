"""Round 20 (seamfast): mosaic:seamlines writes its four layers from plain columns
(write_table_layers, no GeoDataFrame). The reference is the GeoDataFrame writer the algorithm
used before (write_layers, pyogrio's raw writer under it): the same features, field types, CRS
definition rows, spatial indexes and GeoPackage metadata."""

from __future__ import annotations

import sqlite3

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely
from pyproj import CRS

import toolbox
from tests.toolbox.gpkg_check import gpkg_problems
from toolbox.demo.samples.mosaic import make_block, pair_specs
from toolbox.io.vector_write import write_layers

CRS_3003 = CRS("EPSG:3003")
TYPES = {"polys": "MultiPolygon", "lines": "MultiLineString", "points": "Point",
         "empty": "MultiLineString"}


def _tables() -> dict:
    square = shapely.box(0, 0, 10, 10)
    multi = shapely.MultiPolygon([shapely.box(20, 0, 30, 10), shapely.box(40, 0, 50, 10)])
    return {
        "polys": ({"source_id": np.array([1, 2], dtype="int64"),
                   "source": np.array(["a", "ç€"], dtype=object),
                   "area": np.array([100.0, 200.0])}, [square, multi]),
        "lines": ({"a": np.array(["x"], dtype=object), "length": np.array([2.5])},
                  [shapely.MultiLineString([[(0, 0), (1, 1)], [(2, 2), (3, 5)]])]),
        "points": ({"source_id": np.array([7, 8], dtype="int64")},
                   [shapely.Point(1, 2), shapely.Point(3, 4)]),
        "empty": ({"a_id": np.array([], dtype="float64"), "a": np.array([], dtype="float64")},
                  []),
    }


def _metadata(path) -> list:
    """Every GeoPackage table of metadata, the schema and each layer's spatial index rows
    (gpkg_contents without its last_change time stamp)."""
    with sqlite3.connect(path) as db:
        rows = [db.execute("SELECT * FROM gpkg_spatial_ref_sys ORDER BY srs_id").fetchall(),
                db.execute("SELECT * FROM gpkg_geometry_columns ORDER BY table_name").fetchall(),
                db.execute("SELECT * FROM gpkg_extensions ORDER BY table_name, extension_name"
                           ).fetchall(),
                db.execute("SELECT table_name, data_type, identifier, min_x, min_y, max_x, max_y,"
                           " srs_id FROM gpkg_contents ORDER BY table_name").fetchall(),
                db.execute("SELECT type, name, sql FROM sqlite_master ORDER BY name").fetchall(),
                db.execute("PRAGMA application_id").fetchall(),
                db.execute("PRAGMA user_version").fetchall()]
        for (name,) in db.execute("SELECT table_name FROM gpkg_contents ORDER BY table_name"):
            rows.append(db.execute(f'SELECT * FROM "rtree_{name}_geom" ORDER BY id').fetchall())
    db.close()
    return rows


def _assert_same_layers(ours, reference, names) -> None:
    """The layers ``names`` (None: a one-layer file's) hold the same fields, types, features."""
    for name in names:
        got, want = pyogrio.read_info(ours, layer=name), pyogrio.read_info(reference, layer=name)
        assert list(got["fields"]) == list(want["fields"])
        assert list(got["dtypes"]) == list(want["dtypes"])
        assert got["geometry_type"] == want["geometry_type"]
        assert got["features"] == want["features"]
        a = pyogrio.read_dataframe(ours, layer=name)
        b = pyogrio.read_dataframe(reference, layer=name)
        for column in a.columns:
            if column != "geometry":
                assert a[column].tolist() == b[column].tolist()
        assert shapely.equals_exact(np.asarray(a.geometry.values),
                                    np.asarray(b.geometry.values), 0.0).all()


@pytest.mark.parametrize("ext", [".gpkg", ".shp", ".fgb"])
def test_table_layers_are_the_geodataframe_writers_layers(tmp_path, ext):
    from toolbox.io.vector_write import write_table_layers

    tables = _tables()
    frames = {name: gpd.GeoDataFrame(dict(fields), geometry=gpd.GeoSeries(geoms, crs=CRS_3003),
                                     crs=CRS_3003) for name, (fields, geoms) in tables.items()}
    ours, reference = tmp_path / f"ours{ext}", tmp_path / f"reference{ext}"
    write_table_layers(ours, tables, CRS_3003, TYPES)
    write_layers(reference, frames, geometry_types=TYPES)
    if ext == ".gpkg":
        _assert_same_layers(ours, reference, list(tables))
        assert _metadata(ours) == _metadata(reference)
        assert gpkg_problems(ours) == []
        with sqlite3.connect(ours) as db:  # GDAL's EPSG definition, not pyproj's WKT
            (definition,) = db.execute("SELECT definition FROM gpkg_spatial_ref_sys WHERE "
                                       "srs_id = 3003").fetchone()
        db.close()
        assert 'AUTHORITY["EPSG","7022"]' in definition
    else:
        assert sorted(p.name.replace("ours", "") for p in tmp_path.glob("ours*")) == \
            sorted(p.name.replace("reference", "") for p in tmp_path.glob("reference*"))
        for layer in ("", "_lines", "_points", "_empty"):
            _assert_same_layers(tmp_path / f"ours{layer}{ext}", tmp_path /
                                f"reference{layer}{ext}", [None])


def test_seamlines_builds_no_geodataframe_and_writes_the_same_file(tmp_path, monkeypatch):
    orthos, _ = make_block(tmp_path / "in", pair_specs(gain=1.1, offset=-5))
    paths = [str(o.path) for o in orthos]
    toolbox.run("mosaic:seamlines", {"INPUT": paths, "OUTPUT": str(tmp_path / "ref.gpkg")})

    def refuse(*args, **kwargs):
        raise AssertionError("a GeoDataFrame was built")

    monkeypatch.setattr(gpd.GeoDataFrame, "__init__", refuse)
    out = tmp_path / "out.gpkg"
    toolbox.run("mosaic:seamlines", {"INPUT": paths, "OUTPUT": str(out)})
    monkeypatch.undo()
    _assert_same_layers(out, tmp_path / "ref.gpkg",
                        ["cut_polygons", "seamlines", "footprints", "centres"])
    assert _metadata(out) == _metadata(tmp_path / "ref.gpkg")
    assert gpkg_problems(out) == []  # GeoPackage 1.2
    cells = pyogrio.read_dataframe(out, layer="cut_polygons")
    assert cells["source"].tolist() == ["ortho_a", "ortho_b"]
    assert cells["path"].tolist() == ["in/ortho_a.tif", "in/ortho_b.tif"]
    seams = pyogrio.read_dataframe(out, layer="seamlines")
    assert seams["method"].tolist() == ["least_cost"]
