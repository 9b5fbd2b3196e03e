"""The style model, its QML/SLD writers, the layer_styles table and the example style files."""

from __future__ import annotations

import sqlite3
import xml.etree.ElementTree as ET
from pathlib import Path

import geopandas as gpd
import pyogrio
import pytest
import shapely

from toolbox.demo.samples import restitution
from toolbox.io.code_file import read_code_file, read_colour_file
from toolbox.styles import layer_style, qml_document, read_layer_styles, write_layer_styles
from toolbox.styles.files import write_code_styles
from toolbox.styles.model import matplotlib_kwargs, style_model

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture
def demo_tables(tmp_path):
    made = restitution.make(tmp_path, {})
    return (read_code_file(made["restitution_codes"]),
            read_colour_file(made["restitution_colours"]))


@pytest.fixture
def plain_tables(tmp_path):
    """The demo's code file without its symbology columns (code, description, type, colour):
    the simple style (test_styles_symbology.py checks the symbology)."""
    made = restitution.make(tmp_path, {})
    lines = made["restitution_codes"].read_text(encoding="latin-1").splitlines()
    plain = tmp_path / "plain_codes.txt"
    plain.write_text("\n".join(";".join(line.split(";")[:4]) for line in lines
                               if not line.startswith("#")) + "\n", encoding="latin-1")
    return read_code_file(plain), read_colour_file(made["restitution_colours"])


def test_style_model_per_code(plain_tables):
    table, colours = plain_tables
    model = style_model(table, colours)
    fab = model["FAB01002"]
    assert (fab.kind, fab.rgb, fab.fill, fab.label) == (
        "polygon", (77, 77, 77), (77, 77, 77, 96), "muro perimetrale di fabbricato civile")
    assert model["STR02001"].kind == "line" and model["STR02001"].rgb == (255, 0, 0)
    assert model["TOP01001"].label == "toponimo (località)"  # read from Latin-1
    assert model["MAR01001"].rgb == (26, 166, 166)
    kwargs = matplotlib_kwargs(model["STR02001"])
    assert kwargs["color"] == (1.0, 0.0, 0.0, 1.0)
    assert kwargs["linewidth"] == pytest.approx(0.35 * 72 / 25.4)


def test_shipped_style_files_are_not_stale(demo_tables, tmp_path):
    """A staleness check (the generator against its own earlier output), not a correctness
    check: test_generated_qml_is_the_hand_written_qgis_style checks the content."""
    written = write_code_styles(tmp_path / "styles", *demo_tables)
    assert len(written) == 22
    for path in written:
        shipped = ROOT / "styles" / "siena" / path.name
        assert shipped.read_text(encoding="utf-8") == path.read_text(encoding="utf-8"), (
            f"{shipped} is stale: run python -m toolbox.demo.styles styles/siena")
    polygons = ET.fromstring((tmp_path / "styles" / "polygons.qml").read_text().split("\n", 1)[1])
    assert polygons.find("renderer-v2").get("type") == "categorizedSymbol"
    assert [c.get("value") for c in polygons.find("renderer-v2/categories")] == [
        "FAB01002", "VEG01001"]


def test_layer_styles_table_like_qgis(tmp_path, plain_tables):
    table, colours = plain_tables
    path = tmp_path / "x.gpkg"
    gpd.GeoDataFrame({"code": ["FAB01002"]}, geometry=[shapely.box(0, 0, 1, 1)],
                     crs="EPSG:3003").to_file(path, layer="FAB01002", driver="GPKG")
    style = layer_style("FAB01002", "polygon", ["FAB01002"], table, colours)
    write_layer_styles(path, "FAB01002", qml_document(style), "<sld/>", default=True)
    write_layer_styles(path, "FAB01002", qml_document(style), None, default=True, name="bis")
    rows = read_layer_styles(path)
    assert [(r["styleName"], r["useAsDefault"]) for r in rows] == [("FAB01002", 0), ("bis", 1)]
    with sqlite3.connect(path) as db:
        columns = [row[1] for row in db.execute("PRAGMA table_info(layer_styles)")]
        contents = db.execute("SELECT data_type FROM gpkg_contents WHERE table_name = "
                              "'layer_styles'").fetchone()
    assert columns == ["id", "f_table_catalog", "f_table_schema", "f_table_name",
                       "f_geometry_column", "styleName", "styleQML", "styleSLD", "useAsDefault",
                       "description", "owner", "ui", "update_time"]
    assert contents == ("attributes",)
    # GDAL reads the table as an attribute layer
    styles = pyogrio.read_dataframe(path, layer="layer_styles")
    assert styles["f_table_name"].tolist() == ["FAB01002", "FAB01002"]
    assert styles["useAsDefault"].tolist() == [False, True]
    with pytest.raises(ValueError, match="not a spatial layer"):
        write_layer_styles(path, "nope", "<qgis/>")


# Written by hand from QGIS's QML format (the props QGIS 3 writes for a simple line, fill and
# marker layer) and the demo's code and colour files: STR02001 colour 3 = 100 0 0 % -> red,
# 0.35 mm line; FAB01002 colour 12 = 30 30 30 % -> 77,77,77 outline, fill at alpha 96;
# QUO01001 colour 5 = 0 0 100 % -> blue circle, 2 mm. Areas and points are labelled with the
# description field, lines are not.
# duplicate-ok: the expected QML is written out by hand per code on purpose (independent truth)
HAND_WRITTEN = {
    "STR02001": """<qgis styleCategories="Symbology|Labeling" labelsEnabled="0">
  <renderer-v2 type="singleSymbol"><symbols><symbol type="line" name="0" alpha="1">
    <layer class="SimpleLine" enabled="1">
      <prop k="line_color" v="255,0,0,255"/><prop k="line_style" v="solid"/>
      <prop k="line_width" v="0.35"/><prop k="line_width_unit" v="MM"/>
    </layer></symbol></symbols></renderer-v2>
  <layerGeometryType>1</layerGeometryType>
</qgis>""",
    "FAB01002": """<qgis styleCategories="Symbology|Labeling" labelsEnabled="1">
  <renderer-v2 type="singleSymbol"><symbols><symbol type="fill" name="0" alpha="1">
    <layer class="SimpleFill" enabled="1">
      <prop k="color" v="77,77,77,96"/><prop k="style" v="solid"/>
      <prop k="outline_color" v="77,77,77,255"/><prop k="outline_style" v="solid"/>
      <prop k="outline_width_unit" v="MM"/>
    </layer></symbol></symbols></renderer-v2>
  <labeling type="simple"><settings><text-style fieldName="description"/></settings></labeling>
  <layerGeometryType>2</layerGeometryType>
</qgis>""",
    "QUO01001": """<qgis styleCategories="Symbology|Labeling" labelsEnabled="1">
  <renderer-v2 type="singleSymbol"><symbols><symbol type="marker" name="0" alpha="1">
    <layer class="SimpleMarker" enabled="1">
      <prop k="color" v="0,0,255,255"/><prop k="name" v="circle"/>
      <prop k="size" v="2"/><prop k="size_unit" v="MM"/>
    </layer></symbol></symbols></renderer-v2>
  <labeling type="simple"><settings><text-style fieldName="description"/></settings></labeling>
  <layerGeometryType>0</layerGeometryType>
</qgis>""",
}


def _essentials(root: ET.Element) -> dict:
    """What QGIS draws from a QML: renderer, symbol and layer types, every prop, label field,
    geometry type (attributes QGIS fills with defaults are left out)."""
    symbol = root.find("renderer-v2/symbols/symbol")
    layer = symbol.find("layer")
    text = root.find("labeling/settings/text-style")
    return {"renderer": root.find("renderer-v2").get("type"), "symbol": symbol.get("type"),
            "alpha": symbol.get("alpha"), "class": layer.get("class"),
            "props": {p.get("k"): p.get("v") for p in layer.findall("prop")},
            "label": None if text is None else text.get("fieldName"),
            "labels_enabled": root.get("labelsEnabled"),
            "geometry": root.findtext("layerGeometryType")}


@pytest.mark.parametrize("code", sorted(HAND_WRITTEN))
def test_generated_qml_is_the_hand_written_qgis_style(plain_tables, tmp_path, code):
    written = {p.name: p for p in write_code_styles(tmp_path / "styles", *plain_tables)}
    text = written[f"{code}.qml"].read_text(encoding="utf-8")
    got = _essentials(ET.fromstring(text.split("\n", 1)[1]))  # after the DOCTYPE line
    want = _essentials(ET.fromstring(HAND_WRITTEN[code]))
    extra = set(got["props"]) - set(want["props"])
    got["props"] = {k: v for k, v in got["props"].items() if k in want["props"]}
    assert got == want
    # the generator's other props are ones QGIS knows for that layer class
    assert extra <= {"capstyle", "joinstyle", "outline_width", "angle", "outline_color",
                     "outline_style", "outline_width_unit", "use_custom_dash"}, extra
