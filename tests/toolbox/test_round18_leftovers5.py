"""Round 18, leftovers5: outputs as a QGIS user opens them.

1. A one-layer output (Shapefile, GeoJSON...) of an algorithm declaring a layer style
   (``Layer(style=...)``) got no style at all: a GeoPackage gets it in ``layer_styles``, and QGIS
   loads ``<stem>.qml`` beside a one-layer file. The runner now writes the declared QML/SLD there,
   staged and committed with the output; an input's own ``<stem>.qml`` is never overwritten by an
   output of the same stem in another format (it was, with --overwrite).
"""

from __future__ import annotations

import sqlite3
import xml.etree.ElementTree as ET
from contextlib import closing

import numpy as np
import pyarrow.parquet as pq
import pyogrio
import pytest

import toolbox
from tests.toolbox.export_files import write_export
from toolbox.errors import ParameterError


def _points(path):
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 50, (40, 2))
    geoms = [shapely.Point(680000 + x, 4800000 + y, 100 + 0.8 * x) for x, y in xy]
    gpd.GeoDataFrame({"id": range(40)}, geometry=geoms, crs="EPSG:32633").to_file(path)
    return path


def _renderer(qml_text: str) -> ET.Element:
    return ET.fromstring(qml_text).find("renderer-v2")


@pytest.mark.parametrize("ext", [".shp", ".geojson", ".parquet"])
def test_declared_style_is_written_beside_a_one_layer_output(tmp_path, ext):
    pts = _points(tmp_path / "pts.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": str(pts), "OUTPUT": str(tmp_path / "tin.gpkg")})
    with closing(sqlite3.connect(tmp_path / "tin.gpkg")) as db:
        embedded = db.execute("SELECT styleQML FROM layer_styles WHERE f_table_name = "
                              "'triangles'").fetchone()[0]
    out = tmp_path / f"tin{ext}"
    toolbox.run("tin:delaunay", {"INPUT": str(pts), "OUTPUT": str(out)})
    qml = tmp_path / "tin.qml"
    assert qml.is_file() and (tmp_path / "tin.sld").is_file()
    ET.parse(tmp_path / "tin.sld")  # well-formed
    renderer = _renderer(qml.read_text(encoding="utf-8"))
    truth = _renderer(embedded)
    assert renderer.get("type") == truth.get("type") == "graduatedSymbol"
    assert renderer.get("attr") == "slope_deg"
    written = pq.read_schema(out).names if ext == ".parquet" else pyogrio.read_info(out)["fields"]
    assert renderer.get("attr") in written  # the field as written
    # the other layers (nodes, edges) declare no style: no style file beside them
    assert not list(tmp_path.glob("tin_*.qml"))
    # nothing left of the staging
    assert not [p for p in tmp_path.iterdir() if p.is_dir()]


def test_contours_shapefile_style_names_the_written_fields(tmp_path):
    import rasterio
    from rasterio.transform import from_origin

    y, x = np.mgrid[0:30, 0:30]
    z = (100 + 30 * np.exp(-((x - 15) ** 2 + (y - 15) ** 2) / 60.0)).astype("float32")
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=30, height=30, count=1,
                       dtype="float32", crs="EPSG:32633",
                       transform=from_origin(680000, 4800000, 1, 1)) as dst:
        dst.write(z, 1)
    out = tmp_path / "c.shp"
    toolbox.run("carto:contours", {"INPUT": str(tmp_path / "dem.tif"), "INTERVAL": 5.0,
                                   "OUTPUT": str(out)})
    text = (tmp_path / "c.qml").read_text(encoding="utf-8")
    ET.fromstring(text)
    fields = set(pyogrio.read_info(out)["fields"])
    import re

    referenced = set(re.findall(r'"(\w+)"', ET.fromstring(text).find("renderer-v2").find(
        "rules").find("rule").get("filter")))
    assert referenced and referenced <= fields


def test_an_inputs_style_is_not_overwritten_by_an_output_of_its_stem(tmp_path):
    pts = _points(tmp_path / "pts.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": str(pts), "OUTPUT": str(tmp_path / "tin.shp")})
    mine = "<qgis><!-- the user's own style of tin.shp --></qgis>\n"
    (tmp_path / "tin.qml").write_text(mine)
    with pytest.raises(ParameterError, match="tin.qml"):
        toolbox.run("carto:contours", {"TIN": str(tmp_path / "tin.shp"), "INTERVAL": 5.0,
                                       "OUTPUT": str(tmp_path / "tin.geojson")}, overwrite=True)
    assert (tmp_path / "tin.qml").read_text() == mine
    assert not (tmp_path / "tin.geojson").exists()


# 2. carto:contours wrote its ``closed`` flag as an Integer 0/1 (QGIS: a number, not a
#    checkbox): a Boolean field now (GeoPackage column type BOOLEAN, OGR Integer(Boolean)).

def _dem(path):
    import rasterio
    from rasterio.transform import from_origin

    y, x = np.mgrid[0:30, 0:30]
    z = (100 + 30 * np.exp(-((x - 15) ** 2 + (y - 15) ** 2) / 60.0) + 0.5 * x).astype("float32")
    with rasterio.open(path, "w", driver="GTiff", width=30, height=30, count=1,
                       dtype="float32", crs="EPSG:32633",
                       transform=from_origin(680000, 4800000, 1, 1)) as dst:
        dst.write(z, 1)
    return path


@pytest.mark.parametrize("ext", [".gpkg", ".geojson", ".fgb"])
def test_contours_closed_is_a_boolean_field(tmp_path, ext):
    import shapely

    out = tmp_path / f"c{ext}"
    toolbox.run("carto:contours", {"INPUT": str(_dem(tmp_path / "dem.tif")), "INTERVAL": 5.0,
                                   "OUTPUT": str(out)})
    if ext == ".gpkg":  # the GeoPackage's own declaration of the column
        with closing(sqlite3.connect(out)) as db:
            types = {row[1]: row[2] for row in db.execute("PRAGMA table_info(contours)")}
        assert types["closed"] == "BOOLEAN"
    info = pyogrio.read_info(out, layer="contours")
    assert dict(zip(info["fields"], info["dtypes"], strict=True))["closed"] == "bool"
    frame = pyogrio.read_dataframe(out, layer="contours")
    rings = [shapely.equals_exact(shapely.get_point(g, 0), shapely.get_point(g, -1), 0.0)
             for g in frame.geometry]
    assert any(rings) and not all(rings)
    assert frame["closed"].tolist() == rings


# 4. SOURCE_DATE_EPOCH (reproducible builds): a map sheet printed today's date, a GeoPackage
#    recorded the current time (gpkg_contents.last_change, layer_styles.update_time), so two
#    runs differed; a malformed value was an internal error (exit 3) in carto:sheet.

EPOCH = 1700000000  # 2023-11-14 22:13:20 UTC (date -u -d @1700000000)


def _sheet(tmp_path, name):
    out = tmp_path / name
    toolbox.run("carto:sheet", {"EXTENT": "680000,4799960,680040,4800000 [EPSG:32633]",
                                "SCALE": 1000, "OUTPUT": str(out)})
    return out


def test_sheet_pdf_is_reproducible_and_dated_by_source_date_epoch(tmp_path, monkeypatch):
    import pypdf

    monkeypatch.setenv("SOURCE_DATE_EPOCH", str(EPOCH))
    a, b = _sheet(tmp_path, "a.pdf"), _sheet(tmp_path, "b.pdf")
    assert a.read_bytes() == b.read_bytes()
    reader = pypdf.PdfReader(a)
    assert reader.metadata["/CreationDate"] == "D:20231114221320Z"
    assert "2023-11-14" in reader.pages[0].extract_text()  # the title block's date


def test_geopackage_timestamps_follow_source_date_epoch(tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", str(EPOCH))
    dem = _dem(tmp_path / "dem.tif")
    outs = [tmp_path / "a.gpkg", tmp_path / "b.gpkg"]
    for out in outs:
        toolbox.run("carto:contours", {"INPUT": str(dem), "INTERVAL": 5.0, "OUTPUT": str(out)})
    assert outs[0].read_bytes() == outs[1].read_bytes()
    with closing(sqlite3.connect(outs[0])) as db:
        stamps = {r[0] for r in db.execute("SELECT last_change FROM gpkg_contents")}
        stamps |= {r[0] for r in db.execute("SELECT update_time FROM layer_styles")}
    assert stamps == {"2023-11-14T22:13:20.000Z"}
    import os

    assert "OGR_CURRENT_DATE" not in os.environ  # set for the run only


@pytest.mark.parametrize("value", ["yesterday", "-5", "1.5e9"])
def test_malformed_source_date_epoch_is_refused(tmp_path, monkeypatch, value):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", value)
    with pytest.raises(ParameterError, match="SOURCE_DATE_EPOCH"):
        _sheet(tmp_path, "bad.pdf")
    assert not (tmp_path / "bad.pdf").exists()


# 3. A GeoJSON output holds +-inf as null (JSON has no infinity: GDAL's default), which told it
#    from nothing but a RuntimeWarning naming no field: one toolbox warning now names the
#    fields and counts; NaN (a float field's "no value") is null without a warning.

def test_geojson_infinite_values_are_null_with_a_warning_naming_the_field(tmp_path, caplog):
    import json
    import logging

    import geopandas as gpd
    import shapely

    from toolbox.io.vector_write import write_layers, write_wkb_layer

    frame = gpd.GeoDataFrame({"ratio": [1.5, np.inf, -np.inf, np.nan], "n": [1, 2, 3, 4],
                              "gap": [np.nan, 0.0, 1.0, 2.0]},
                             geometry=[shapely.Point(i, 0) for i in range(4)], crs=32633)
    for writer, out in ((lambda p: write_layers(p, {"x": frame}), tmp_path / "a.geojson"),
                        (lambda p: write_wkb_layer(p, "x", shapely.to_wkb(frame.geometry.values),
                                                   {c: frame[c].to_numpy()
                                                    for c in ("ratio", "n", "gap")},
                                                   "Point", frame.crs), tmp_path / "b.geojson")):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="toolbox"):
            writer(out)
        doc = json.loads(out.read_text())  # strict JSON: no Infinity/NaN tokens
        assert [f["properties"].get("ratio") for f in doc["features"]] == [1.5, None, None, None]
        messages = [r.getMessage() for r in caplog.records if r.name == "toolbox"]
        assert len(messages) == 1 and "ratio (2)" in messages[0] and "gap" not in messages[0]


# 5. attribution:merge / apply: of two duplicates across models, the entity of the model given
#    first is kept (undocumented, and the count was only an info line): a warning counts them
#    and names the rule.

@pytest.mark.parametrize("order", [("a", "b"), ("b", "a")])
def test_merge_duplicates_keep_the_first_model_and_are_warned(tmp_path, order):
    import geopandas as gpd
    import shapely

    square = [(0, 0, 330), (10, 0, 330), (10, 10, 330), (0, 10, 330), (0, 0, 330)]
    moved = [(x + 0.03, y + 0.02, z + 0.02) for x, y, z in square]  # the same building again
    models = {"a": [("FAB01002", square), ("QUO01001", [(50, 5, 320.5)])],
              "b": [("FAB01002", moved), ("QUO01001", [(50.02, 5.01, 320.55)])]}
    paths = [write_export(tmp_path / f"{name}.txt", models[name]) for name in order]
    feedback = toolbox.Feedback()
    out = tmp_path / "merged.gpkg"
    stats = toolbox.run("attribution:merge", {"INPUT": paths, "SNAP_TOLERANCE": 0.2,
                                              "HEIGHT_SNAP_TOLERANCE": 0.1, "CRS": "EPSG:3003",
                                              "OUTPUT": out}, feedback=feedback)["STATISTICS"]
    assert stats["duplicates_removed"] == 2
    warned = [w for w in feedback.warnings if "duplicate" in w]
    assert len(warned) == 1 and "2 duplicate entities" in warned[0] and "first" in warned[0]
    kept = gpd.read_file(out, layer="lines")  # the building's outline: the first model's
    first = models[order[0]][0][1]
    assert len(kept) == 1 and kept["model"].tolist() == [1]
    np.testing.assert_allclose(shapely.get_coordinates(kept.geometry.iloc[0], include_z=True),
                               np.array(first) + [1688600, 4799900, 0], atol=1e-6)


def test_no_style_file_for_a_layer_file_holding_another_kind(tmp_path):
    import geopandas as gpd
    import shapely

    from toolbox.io.vector_write import write_layers
    from toolbox.styles.layers import write_declared_style_files

    pts = gpd.GeoDataFrame({"severity": ["error"]}, geometry=[shapely.Point(0, 0)], crs=32633)
    out = tmp_path / "x.shp"
    write_layers(out, {"errors_points": pts})
    # declared as an areas (polygon) layer first: the file holds points, so no areas style
    assert write_declared_style_files(out, [("areas", "areas", "Polygon")]) == []
    assert write_declared_style_files(out, [("errors_points", "errors", "Point")]) == [
        tmp_path / "x.qml", tmp_path / "x.sld"]
    assert 'attr="severity"' in (tmp_path / "x.qml").read_text()
