"""vector:info on a GeoPackage whose layers are in custom (non-EPSG) CRSs: the SQL reader asked
OGR for each such system's CRS by a statement of its own, one open of the file each; their
definitions now come from the one read of gpkg_spatial_ref_sys that gives the EPSG codes. The
labels are checked against OGR's own per layer (pyogrio.read_info, labelled as vector:info
labels): the same for every layer, whatever the number of custom CRSs."""

from __future__ import annotations

import sqlite3

import geopandas as gpd
import pyogrio
import shapely
from pyproj import CRS

import toolbox
import toolbox.io.vector as vector
from toolbox.io.crs import crs_label

CUSTOM = ["+proj=tmerc +lon_0=12.5 +k=0.9996 +x_0=2520000 +ellps=intl +units=m +no_defs",
          "+proj=lcc +lat_0=42 +lon_0=12 +lat_1=40 +lat_2=45 +datum=WGS84 +units=m +no_defs",
          "+proj=tmerc +lon_0=9 +k=0.9996 +x_0=1500000 +ellps=intl "
          "+towgs84=-104.1,-49.1,-9.9,0.971,-2.917,0.714,-11.68 +units=m +no_defs",
          "+proj=omerc +lat_0=46 +lonc=10 +alpha=30 +k=1 +x_0=0 +y_0=0 +ellps=bessel "
          "+units=m +no_defs"]


def gpkg(path, crss):
    """One layer per CRS of ``crss`` (custom ones, then EPSG:3003), a point each."""
    for k, crs in enumerate([*crss, "EPSG:3003"]):
        gpd.GeoDataFrame({"a": [k]}, geometry=[shapely.Point(1000 + k, 2000)],
                         crs=CRS.from_user_input(crs)).to_file(path, layer=f"l{k}")
    return path


def ogr_labels(path):
    """Each layer's CRS label from OGR's own reading of it (pyogrio.read_info per layer)."""
    out = {}
    for name, _ in pyogrio.list_layers(path):
        crs = pyogrio.read_info(path, layer=name)["crs"]
        out[str(name)] = crs if crs.startswith("EPSG:") and crs[5:].isdigit() else \
            crs_label(CRS.from_user_input(crs))
    return out


def described(path, monkeypatch):
    statements = []
    real = vector._sql_read

    def counted(*args, **kwargs):
        statements.append(args[1])
        return real(*args, **kwargs)

    monkeypatch.setattr(vector, "_sql_read", counted)
    layers = toolbox.run("vector:info", {"INPUT": path})["INFO"]["layers"]
    monkeypatch.undo()
    return {la["name"]: la["crs"] for la in layers}, statements


def test_custom_crs_layers_take_no_open_each(tmp_path, monkeypatch):
    one = gpkg(tmp_path / "one.gpkg", CUSTOM[:1])
    four = gpkg(tmp_path / "four.gpkg", CUSTOM)
    labels_one, opens_one = described(one, monkeypatch)
    labels_four, opens_four = described(four, monkeypatch)
    assert labels_one == ogr_labels(one)
    assert labels_four == ogr_labels(four)
    assert all(labels_four[f"l{k}"].startswith("an unnamed CRS") for k in range(4))
    assert labels_four["l4"] == "EPSG:3003"
    assert len(opens_four) == len(opens_one) == 5, opens_four  # not one more per custom CRS


def test_a_wkt2_definition_and_other_writers_rows(tmp_path, monkeypatch):
    """A GeoPackage with the WKT 2 extension (definition_12_063, which GDAL prefers), and a
    custom row another program wrote (organization NONE, a UTM 32N WKT without authority: OGR
    identifies it): vector:info labels each as OGR reads it."""
    path = gpkg(tmp_path / "w.gpkg", CUSTOM[:2])
    con = sqlite3.connect(path)
    with con:
        srs = {t: s for t, s in con.execute("SELECT table_name, srs_id FROM "
                                            "gpkg_geometry_columns")}
        con.execute("ALTER TABLE gpkg_spatial_ref_sys ADD COLUMN definition_12_063 TEXT NOT "
                    "NULL DEFAULT 'undefined'")
        con.execute("UPDATE gpkg_spatial_ref_sys SET definition_12_063 = ? WHERE srs_id = ?",
                    (CRS.from_user_input(CUSTOM[3]).to_wkt("WKT2_2019"), srs["l1"]))
        utm = CRS.from_epsg(32632).to_wkt("WKT1_GDAL").rsplit(',AUTHORITY["EPSG","32632"]', 1)[0]
        con.execute("UPDATE gpkg_spatial_ref_sys SET organization = 'NONE', definition = ? "
                    "WHERE srs_id = ?", (utm + "]", srs["l0"]))
        con.execute("INSERT INTO gpkg_extensions VALUES ('gpkg_spatial_ref_sys', "
                    "'definition_12_063', 'gpkg_crs_wkt', 'http://www.geopackage.org/spec120/"
                    "#extension_crs_wkt', 'read-write')")
    con.close()
    labels, _ = described(path, monkeypatch)
    assert labels == ogr_labels(path), (labels, ogr_labels(path))
    assert labels["l0"] == "EPSG:32632" and "+proj=omerc" in labels["l1"]
