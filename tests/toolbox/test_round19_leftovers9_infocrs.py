"""vector:info on a GeoPackage of many layers in many CRSs opened the file once per CRS (a
statement per spatial reference system): now the EPSG systems come from one read of
``gpkg_spatial_ref_sys``, and each layer's CRS is still what OGR says (pyogrio.read_info per
layer, the independent reference), the tricky rows of that table included."""

from __future__ import annotations

import sqlite3

import numpy as np
import pyogrio
import pytest
import shapely
from pyproj import CRS

import toolbox
import toolbox.io.vector as vector


def _layer(path, name, crs, x0=500000.0):
    pyogrio.write_dataframe(__import__("geopandas").GeoDataFrame(
        {"a": np.arange(3)}, geometry=shapely.points(np.c_[np.arange(3) + x0, np.arange(3)]),
        crs=crs), path, layer=name)


@pytest.fixture
def counted(monkeypatch):
    calls = []
    real = vector._sql_read
    monkeypatch.setattr(vector, "_sql_read", lambda *a, **k: calls.append(a[1]) or real(*a, **k))
    return calls


def test_many_crs_take_a_bounded_number_of_opens(tmp_path, counted):
    path = tmp_path / "many.gpkg"
    codes = [32601 + i for i in range(12)]
    for i, code in enumerate(codes):
        _layer(path, f"l{i:02d}", code)
    info = toolbox.run("vector:info", {"INPUT": str(path)})["INFO"]
    assert [layer["crs"] for layer in info["layers"]] == \
        [pyogrio.read_info(path, layer=f"l{i:02d}")["crs"] for i in range(12)] == \
        [f"EPSG:{c}" for c in codes]
    assert len(counted) <= 5, counted  # was 4 + one per CRS: 16


def test_each_layer_keeps_the_crs_ogr_reads(tmp_path, counted):
    path = tmp_path / "odd.gpkg"
    custom = CRS.from_proj4("+proj=tmerc +lat_0=0 +lon_0=12.3 +k=0.9996 +x_0=500000 +y_0=0 "
                            "+ellps=intl +units=m +no_defs")
    for i, crs in enumerate([3003, 3004, custom, 32632, 6707, 4326]):
        _layer(path, f"l{i}", crs, x0=10.0 if crs == 4326 else 500000.0)
    wkt = {code: CRS.from_epsg(code).to_wkt("WKT1_GDAL") for code in (3003, 3004)}
    with sqlite3.connect(path) as db:
        # srs_id 3004 defined by 3003's text: GDAL takes it from its code, 3004
        db.execute("UPDATE gpkg_spatial_ref_sys SET definition = ? WHERE srs_id = 3004",
                   (wkt[3003],))
        # 32632 under lowercase 'epsg'; 6707 with a code that is not its srs_id (GDAL reads
        # the definition, whose root authority is 3003)
        db.execute("UPDATE gpkg_spatial_ref_sys SET organization = 'epsg' WHERE srs_id = 32632")
        db.execute("INSERT INTO gpkg_spatial_ref_sys VALUES ('moved', 200000, 'EPSG', 6707, ?, "
                   "NULL)", (wkt[3003],))
        db.execute("UPDATE gpkg_geometry_columns SET srs_id = 200000 WHERE table_name = 'l4'")
        # a code PROJ does not know, its definition's root authority the same code
        db.execute("INSERT INTO gpkg_spatial_ref_sys VALUES ('bogus', 999999, 'EPSG', 999999, "
                   "?, NULL)", (wkt[3003].replace('AUTHORITY["EPSG","3003"]]',
                                                  'AUTHORITY["EPSG","999999"]]'),))
        db.execute("UPDATE gpkg_geometry_columns SET srs_id = 999999 WHERE table_name = 'l5'")
    ogr = [pyogrio.read_info(path, layer=f"l{i}")["crs"] for i in range(6)]
    assert ogr[:2] == ["EPSG:3003", "EPSG:3004"] and ogr[3:] == \
        ["EPSG:32632", "EPSG:3003", "EPSG:999999"], ogr
    info = toolbox.run("vector:info", {"INPUT": str(path)})["INFO"]
    got = [layer["crs"] for layer in info["layers"]]
    assert got[:2] + got[3:] == ogr[:2] + ogr[3:], got
    assert CRS.from_wkt(ogr[2]).name == "unknown"  # no code nor name: labelled by its PROJ text
    assert got[2] == f"an unnamed CRS ({CRS.from_wkt(ogr[2]).to_proj4().replace(' +type=crs', '')})"
    # 3004 (its text) and the moved: by OGR; the custom from gpkg_spatial_ref_sys (round 20)
    assert len(counted) == 7, counted
