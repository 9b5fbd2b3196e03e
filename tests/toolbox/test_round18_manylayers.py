"""Round 18, vector:info on a GeoPackage of many layers: each OGR call opens the file again, and
GDAL's open of a GeoPackage grows with its tables (70 ms for 200 layers with their R-trees);
two calls per layer (information, then geometries) took 34 s for 200 layers of 50 points
(``ogrinfo -so -al``: 0.3 s). Its feature tables are now read by a few SQL statements over
all of them (toolbox.io.vector.layers_geometries): the description must stay identical to the
per-layer reading (every_layer + read_geometries, kept as the oracle)."""

from __future__ import annotations

import struct

import numpy as np
import pytest
import shapely

import toolbox
from toolbox.errors import InputDataError

LOCAL_WKT = ('PROJCS["local",GEOGCS["g",DATUM["d",SPHEROID["s",6378137,298.257223563]],'
             'PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],'
             'PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],'
             'PARAMETER["central_meridian",12.5],PARAMETER["scale_factor",0.9996],'
             'PARAMETER["false_easting",1500000],PARAMETER["false_northing",0],UNIT["metre",1]]')


def _write(path, layer, geoms, fields, crs="EPSG:3003", gtype="Unknown", **kwargs):
    from pyogrio.raw import write

    names = list(fields)
    write(str(path), geometry=None if geoms is None else np.array(geoms, dtype=object),
          field_data=[fields[n] for n in names], fields=names, geometry_type=gtype, crs=crs,
          driver="GPKG", layer=layer, **kwargs)


def _mixed(path):
    """An empty layer first, points with every field type and a null geometry, LineString Z
    with an empty one, an invalid polygon (EPSG:4326), a CircularString (written as ISO WKB:
    shapely has no curves), MultiPoint Z without CRS, a custom WKT CRS, a geometry column and
    a layer name of their own, and an attribute-only ``layer_styles`` table."""
    wkb = shapely.to_wkb
    _write(path, "empty", [], {"a": np.array([], np.int64)}, gtype="Point")
    _write(path, "pts", [wkb(shapely.Point(1, 2)), wkb(shapely.Point(3, 5)), None],
           {"i32": np.array([1, 2, 3], np.int32), "i64": np.array([1, 2, 2**40]),
            "f": np.array([0.5, np.nan, 2.0]), "b": np.array([True, False, True]),
            "s": np.array(["a", None, "c"], dtype=object),
            "d": np.array(["2020-01-01", "2021-05-06", "NaT"], dtype="datetime64[D]"),
            "t": np.array(["2020-01-01T10:00", "2021-01-01", "NaT"], dtype="datetime64[ms]")},
           gtype="Point")
    _write(path, "lines3d", [wkb(shapely.LineString([(0, 0, 1), (5, 5, 9)])),
                             wkb(shapely.LineString())], {"n": np.array([1, 2], np.int16)},
           crs="EPSG:32632", gtype="LineString Z")
    _write(path, "polys", [wkb(shapely.Polygon([(0, 0), (2, 0), (0, 2), (2, 2)])),
                           wkb(shapely.box(10, 10, 20, 30))], {"x": np.array([1.5, 2.5], np.float32)},
           crs="EPSG:4326", gtype="Polygon")
    arc = struct.pack("<BII6d", 1, 8, 3, 0.0, 0.0, 1000.0, 1000.0, 2000.0, 0.0)
    _write(path, "arcs", [arc], {"code": np.array([1])}, crs="EPSG:32632")
    _write(path, "nocrs", [wkb(shapely.MultiPoint([(1, 1, 1), (2, 2, 2)]))],
           {"k": np.array(["x"], dtype=object)}, crs=None, gtype="MultiPoint Z")
    _write(path, 'odd "name" layer', [wkb(shapely.Point(7, 8))], {"k k": np.array([1])},
           crs=LOCAL_WKT, layer_options={"GEOMETRY_NAME": "shape"})
    _write(path, "layer_styles", None, {"f_table_name": np.array(["pts"], dtype=object),
                                        "styleQML": np.array(["<qgis/>"], dtype=object)},
           crs=None)
    return path


def _oracle(path):
    """The description by the per-layer reading (the code path before round 18)."""
    from algorithms.vector.info import geometry_summary, layer_crs_label
    from toolbox.io.vector import every_layer, open_layer, read_geometries

    out = []
    for layer in every_layer(open_layer(str(path))):
        layer, geoms = read_geometries(layer)
        out.append({"name": layer.layer, "crs": layer_crs_label(layer),
                    "fields": layer.field_types, **geometry_summary(geoms)})
    return out


@pytest.fixture
def mixed(tmp_path):
    with pytest.warns(UserWarning, match="crs"):
        return _mixed(tmp_path / "mixed.gpkg")


def test_many_kinds_of_layers_described_as_layer_by_layer(mixed):
    layers = toolbox.run("vector:info", {"INPUT": mixed})["INFO"]["layers"]
    assert layers == _oracle(mixed)
    by_name = {la["name"]: la for la in layers}
    assert list(by_name) == ["empty", "pts", "lines3d", "polys", "arcs", "nocrs",
                             'odd "name" layer', "layer_styles"]
    assert by_name["pts"]["fields"] == {"i32": "int32", "i64": "int64", "f": "float64",
                                        "b": "bool", "s": "object", "d": "datetime64[D]",
                                        "t": "datetime64[ms]"}
    assert by_name["arcs"]["bounds"][2] == 2000.0  # the half circle, linearised
    assert by_name["arcs"]["bounds"][3] == pytest.approx(1000.0, abs=0.01)
    assert by_name['odd "name" layer']["crs"] == "local"
    assert by_name["layer_styles"]["features"] == 1


def test_feature_tables_read_by_a_few_sql_statements(mixed, monkeypatch):
    """A few OGR reads for the whole file, not two per layer: fields, CRS and WKB by SQL."""
    import pyogrio._io
    import pyogrio.core

    expected = _oracle(mixed)
    calls = []
    for module, name in ((pyogrio._io, "ogr_read"), (pyogrio.core, "ogr_read_info")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, _real=real, **k:
                            calls.append(k.get("layer")) or _real(*a, **k))
    layers = toolbox.run("vector:info", {"INPUT": mixed})["INFO"]["layers"]
    assert layers == expected
    # per layer: the input's first layer (opened as INPUT) and layer_styles (no geometry: its
    # information and rows); the others by SQL statements (layer None)
    assert [c for c in calls if c is not None] == ["empty", "layer_styles", "layer_styles"]
    # + 1 (tables and columns) + 1 (fields) + 1 (the EPSG and custom systems of
    # gpkg_spatial_ref_sys) + 1 (GDAL's "Undefined SRS": a CRS from OGR; the custom one too
    # before round 20, a statement each of the 5 systems before round 19) + 1 (counts) + 1
    # (geometries); one by one: 17, two per layer
    assert len(calls) == 9


def test_nan_coordinates_refused_as_layer_by_layer(tmp_path):
    path = tmp_path / "nan.gpkg"
    _write(path, "a", [shapely.to_wkb(shapely.Point(1, 1))], {"k": np.array([1])})
    _write(path, "b", [shapely.to_wkb(shapely.Point(1, 1)), shapely.to_wkb(shapely.Point(np.nan, 1))],
           {"k": np.array([1, 2])})
    with pytest.raises(InputDataError) as old:
        _oracle(path)
    with pytest.raises(InputDataError) as new:
        toolbox.run("vector:info", {"INPUT": path})
    assert str(new.value) == str(old.value)
    assert "row 2" in str(new.value) and "layername=b'" in str(new.value)


def test_a_generated_column_is_described_as_layer_by_layer(mixed):
    """GDAL lists a generated column among the fields (``pragma_table_info`` does not): such a
    table takes the per-layer path."""
    import sqlite3

    with sqlite3.connect(mixed) as db:
        db.execute("ALTER TABLE pts ADD COLUMN twice INTEGER GENERATED ALWAYS AS (i32 * 2) "
                   "VIRTUAL")
    db.close()
    layers = toolbox.run("vector:info", {"INPUT": mixed})["INFO"]["layers"]
    assert layers == _oracle(mixed)
    assert layers[1]["fields"]["twice"] == "int64"


def test_statements_split_as_described_as_layer_by_layer(mixed, monkeypatch):
    """Joins of 2 tables, unions of 3 tables or of 2 features at most: the same description."""
    from toolbox.io import vector

    monkeypatch.setattr(vector, "_SQL_TABLES", 2)
    monkeypatch.setattr(vector, "_SQL_PARTS", 3)
    monkeypatch.setattr(vector, "_SQL_FEATURES", 2)
    layers = toolbox.run("vector:info", {"INPUT": mixed})["INFO"]["layers"]
    assert layers == _oracle(mixed)
    assert [la["features"] for la in layers] == [0, 3, 2, 2, 1, 1, 1, 1]


def test_a_measured_layer_takes_the_per_layer_path(mixed):
    """A layer declared with M values (``gpkg_geometry_columns.m``): read layer by layer,
    whose reader warns that the M values are dropped."""
    import sqlite3

    from toolbox.io import vector

    with sqlite3.connect(mixed) as db:
        db.execute("UPDATE gpkg_geometry_columns SET m = 2 WHERE table_name = 'lines3d'")
    db.close()
    plan = vector._gpkg_plan(mixed, vector.layer_names(mixed))
    assert "lines3d" not in plan["info"] and "pts" in plan["info"]
    assert toolbox.run("vector:info", {"INPUT": mixed})["INFO"]["layers"] == _oracle(mixed)
