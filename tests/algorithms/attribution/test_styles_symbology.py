"""The QGIS (QML) and SLD styles carry the code file's symbology as the map sheet draws it:
hatched areas, dashed and dotted lines, widths in mm at print size, point symbols, scarp ticks,
delivered codes. Checked against QML written by hand from QGIS 3.22's format (parsed, not
compared as text), and in real QGIS 3.22 (headless): the symbol layers it reads back, and what
it renders (hatch spacing, ticks on the left of the line)."""

from __future__ import annotations

import json
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from tests.helpers_cli import qgis_python
from toolbox.demo.samples import restitution
from toolbox.io.code_file import read_code_file, read_colour_file
from toolbox.styles.files import write_code_styles
from toolbox.styles.gpkg import read_layer_styles

# colours (the demo's colour file): 1 = 20 80 0 % -> 51,204,0; 2 = 10 65 65 %; 3 = red;
# 5 = blue; 7 = 60 40 20 % -> 153,102,51; 12 = 30 30 30 % -> 77,77,77
CODES = """\
codice;descrizione;tipologia;colore;spessore;tipo linea;simbolo;campitura;codice consegna
FAB01002;muro perimetrale di fabbricato civile;poligono;12;0.25;continua;;45/1.0;EDIFICIO
VEG01001;area a verde;poligono;1;0.13;tratteggiata;;solid;AREA_VERDE
STR02001;limite di strada;polilinea;3;0.18;continua;;;BORDO_STRADA
MAR01001;marciapiede;polilinea;2;0.30;tratteggiata;;;BORDO_STRADA
SCA01001;scarpata;polilinea;7;0.18;scarpata;;;SCARPATA
SEN01001;sentiero;polilinea;7;0.13;punteggiata;;;SENTIERO
QUO01001;punto quotato;punto;5;0.13;;dot 0.7;;PUNTO_QUOTATO
ALB01001;albero isolato;punto;1;0.13;;tree 2.0;;ALBERO
VER01001;vertice trigonometrico;punto;8;0.2;;triangle 1.5;;VERTICE
"""


@pytest.fixture(scope="module")
def styles(tmp_path_factory):
    folder = tmp_path_factory.mktemp("symbology")
    codes = folder / "codes.txt"
    codes.write_text(CODES, encoding="utf-8")
    colours = folder / "colours.txt"
    colours.write_text(restitution.COLOUR_FILE_TEXT, encoding="utf-8")
    written = write_code_styles(folder / "styles", read_code_file(codes),
                                read_colour_file(colours))
    return folder, {p.name: p for p in written}


# Written by hand from QGIS 3.22's QML (the props QgsSimpleLineSymbolLayer,
# QgsLinePatternFillSymbolLayer, QgsHashedLineSymbolLayer and QgsSimpleMarkerSymbolLayer
# read) and the code file above: the sheet's symbology (toolbox.cartography.symbols: dashes
# 2/1 mm, dots 0.3/0.7 mm, scarp ticks 1.2 mm every 2 mm on the left, hatch lines 0.1 mm,
# solid fills at alpha 96).
HAND_WRITTEN = {
    # hatched at 45 degrees, 1 mm apart, in the outline's colour, under a 0.25 mm outline
    "FAB01002": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="fill" name="0">
      <layer class="LinePatternFill"><prop k="angle" v="45"/><prop k="distance" v="1"/>
        <prop k="distance_unit" v="MM"/><prop k="color" v="77,77,77,255"/>
        <symbol type="line" name="@0@0"><layer class="SimpleLine">
          <prop k="line_color" v="77,77,77,255"/><prop k="line_width" v="0.1"/>
          <prop k="line_width_unit" v="MM"/></layer></symbol></layer>
      <layer class="SimpleLine"><prop k="line_color" v="77,77,77,255"/>
        <prop k="line_width" v="0.25"/><prop k="line_width_unit" v="MM"/>
        <prop k="use_custom_dash" v="0"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    # a light solid fill with no outline of its own, then a dashed 0.13 mm outline
    "VEG01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="fill" name="0">
      <layer class="SimpleFill"><prop k="color" v="51,204,0,96"/><prop k="style" v="solid"/>
        <prop k="outline_style" v="no"/></layer>
      <layer class="SimpleLine"><prop k="line_color" v="51,204,0,255"/>
        <prop k="line_width" v="0.13"/><prop k="line_width_unit" v="MM"/>
        <prop k="use_custom_dash" v="1"/><prop k="customdash" v="2;1"/>
        <prop k="customdash_unit" v="MM"/><prop k="capstyle" v="flat"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    "STR02001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="line" name="0">
      <layer class="SimpleLine"><prop k="line_color" v="255,0,0,255"/>
        <prop k="line_width" v="0.18"/><prop k="line_width_unit" v="MM"/>
        <prop k="use_custom_dash" v="0"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    # delivered as BORDO_STRADA, whose first working code is STR02001: drawn as a road edge
    "MAR01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="line" name="0">
      <layer class="SimpleLine"><prop k="line_color" v="255,0,0,255"/>
        <prop k="line_width" v="0.18"/><prop k="use_custom_dash" v="0"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    # the line, then ticks 1.2 mm long every 2 mm (the first at 1 mm), 0.6 mm to the left
    "SCA01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="line" name="0">
      <layer class="SimpleLine"><prop k="line_color" v="153,102,51,255"/>
        <prop k="line_width" v="0.18"/><prop k="use_custom_dash" v="0"/></layer>
      <layer class="HashLine"><prop k="placement" v="interval"/><prop k="interval" v="2"/>
        <prop k="interval_unit" v="MM"/><prop k="offset_along_line" v="1"/>
        <prop k="hash_length" v="1.2"/><prop k="hash_length_unit" v="MM"/>
        <prop k="hash_angle" v="0"/><prop k="rotate" v="1"/><prop k="offset" v="-0.6"/>
        <prop k="offset_unit" v="MM"/>
        <symbol type="line" name="@0@1"><layer class="SimpleLine">
          <prop k="line_color" v="153,102,51,255"/><prop k="line_width" v="0.126"/>
        </layer></symbol></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    "SEN01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="line" name="0">
      <layer class="SimpleLine"><prop k="line_color" v="153,102,51,255"/>
        <prop k="line_width" v="0.13"/><prop k="use_custom_dash" v="1"/>
        <prop k="customdash" v="0.3;0.7"/><prop k="customdash_unit" v="MM"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    # a filled dot 0.7 mm, no outline
    "QUO01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="marker" name="0">
      <layer class="SimpleMarker"><prop k="name" v="circle"/><prop k="size" v="0.7"/>
        <prop k="size_unit" v="MM"/><prop k="color" v="0,0,255,255"/>
        <prop k="outline_style" v="no"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    # a tree 2 mm: a hollow crown 4/3 mm above its centre and a 2/3 mm stem below
    "ALB01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="marker" name="0">
      <layer class="SimpleMarker"><prop k="name" v="circle"/><prop k="size" v="1.33333"/>
        <prop k="color" v="0,0,0,0"/><prop k="outline_color" v="51,204,0,255"/>
        <prop k="outline_width" v="0.13"/><prop k="offset" v="0,-0.333333"/></layer>
      <layer class="SimpleMarker"><prop k="name" v="line"/><prop k="size" v="0.666667"/>
        <prop k="outline_color" v="51,204,0,255"/><prop k="offset" v="0,0.666667"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
    "VER01001": """<qgis><renderer-v2 type="singleSymbol"><symbols><symbol type="marker" name="0">
      <layer class="SimpleMarker"><prop k="name" v="triangle"/><prop k="size" v="1.5"/>
        <prop k="color" v="0,0,0,0"/><prop k="outline_color" v="0,0,0,255"/>
        <prop k="outline_style" v="solid"/><prop k="outline_width" v="0.2"/></layer>
    </symbol></symbols></renderer-v2></qgis>""",
}


def _layers(symbol: ET.Element) -> list:
    """(class, props, sub-symbol layers) of each symbol layer, bottom first."""
    out = []
    for layer in symbol.findall("layer"):
        sub = layer.find("symbol")
        out.append((layer.get("class"), {p.get("k"): p.get("v") for p in layer.findall("prop")},
                    None if sub is None else _layers(sub)))
    return out


def _compare(got: list, want: list, where: str) -> None:
    assert [g[0] for g in got] == [w[0] for w in want], where
    for (cls, props, sub), (_, wprops, wsub) in zip(got, want, strict=True):
        for key, value in wprops.items():
            assert props.get(key) == value, f"{where} {cls} {key}: {props.get(key)} != {value}"
        assert (sub is None) == (wsub is None), where
        if wsub is not None:
            _compare(sub, wsub, f"{where} {cls} sub-symbol")


@pytest.mark.parametrize("code", sorted(HAND_WRITTEN))
def test_qml_is_the_hand_written_symbology(styles, code):
    text = styles[1][f"{code}.qml"].read_text(encoding="utf-8")
    root = ET.fromstring(text.split("\n", 1)[1])  # after the DOCTYPE line
    want = ET.fromstring(HAND_WRITTEN[code])
    assert root.find("renderer-v2").get("type") == "singleSymbol"
    symbol = root.find("renderer-v2/symbols/symbol")
    assert symbol.get("type") == want.find("renderer-v2/symbols/symbol").get("type")
    _compare(_layers(symbol), _layers(want.find("renderer-v2/symbols/symbol")), code)
    # props are written twice (QGIS >= 3.18 reads the Option map): both say the same
    for layer in root.iter("layer"):
        options = {o.get("name"): o.get("value") for o in layer.findall("Option/Option")}
        assert options == {p.get("k"): p.get("v") for p in layer.findall("prop")}


def test_spot_heights_are_labelled_with_their_height(styles):
    """A code drawn as a dot (a spot height) is labelled with the point's Z, one decimal, as
    the sheet does; the other point codes with their description."""
    def text_style(name):
        root = ET.fromstring(styles[1][name].read_text(encoding="utf-8").split("\n", 1)[1])
        return root.find("labeling/settings/text-style").attrib

    quo = text_style("QUO01001.qml")
    assert (quo["fieldName"], quo["isExpression"]) == ("format_number(z($geometry), 1)", "1")
    tree = text_style("ALB01001.qml")
    assert (tree["fieldName"], tree["isExpression"]) == ("description", "0")
    points = text_style("points.qml")
    assert points["fieldName"] == ('CASE WHEN "code" IN (\'QUO01001\') THEN '
                                   'format_number(z($geometry), 1) ELSE "description" END')


def test_categorised_legend_names_the_delivered_codes(styles):
    root = ET.fromstring(styles[1]["lines.qml"].read_text(encoding="utf-8").split("\n", 1)[1])
    labels = {c.get("value"): c.get("label") for c in root.find("renderer-v2/categories")}
    assert labels == {"MAR01001": "BORDO_STRADA limite di strada",
                      "SCA01001": "SCARPATA scarpata", "SEN01001": "SENTIERO sentiero",
                      "STR02001": "BORDO_STRADA limite di strada"}


SLD_NS = {"sld": "http://www.opengis.net/sld"}


def _css(element: ET.Element) -> dict:
    return {p.get("name"): p.text for p in element.findall("sld:CssParameter", SLD_NS)}


def test_sld_carries_dashes_hatching_and_marks(styles):
    """OGC pixels are 0.28 mm: a 2/1 mm dash is 7.14/3.57 px; the hatch is a horline mark
    1 mm (3.57 px) apart, rotated clockwise by -45 (the hatch angle is counter-clockwise)."""
    def rule(code):
        text = styles[1][f"{code}.sld"].read_text(encoding="utf-8")
        return ET.fromstring(text.split("\n", 1)[1]).find(".//sld:Rule", SLD_NS)

    veg = rule("VEG01001")
    stroke = _css(veg.find("sld:LineSymbolizer/sld:Stroke", SLD_NS))
    assert stroke == {"stroke": "#33cc00", "stroke-width": "0.46",
                      "stroke-dasharray": "7.14 3.57"}
    assert _css(veg.find("sld:PolygonSymbolizer/sld:Fill", SLD_NS)) == {
        "fill": "#33cc00", "fill-opacity": "0.38"}
    graphic = rule("FAB01002").find("sld:PolygonSymbolizer/sld:Fill/sld:GraphicFill/"
                                    "sld:Graphic", SLD_NS)
    assert graphic.findtext("sld:Mark/sld:WellKnownName", namespaces=SLD_NS) == "horline"
    assert (graphic.findtext("sld:Size", namespaces=SLD_NS),
            graphic.findtext("sld:Rotation", namespaces=SLD_NS)) == ("3.57", "-45")
    mark = rule("VER01001").find("sld:PointSymbolizer/sld:Graphic/sld:Mark", SLD_NS)
    assert mark.findtext("sld:WellKnownName", namespaces=SLD_NS) == "triangle"
    assert mark.find("sld:Fill", SLD_NS) is None  # hollow
    assert len(rule("SCA01001").findall("sld:LineSymbolizer", SLD_NS)) == 2  # line + ticks


# -- real QGIS -----------------------------------------------------------------------------
QGIS_SCRIPT = r"""
import json, sys
from qgis.core import (QgsApplication, QgsVectorLayer, QgsMapSettings, QgsRectangle,
                       QgsMapRendererSequentialJob, QgsExpression, QgsExpressionContext,
                       QgsExpressionContextUtils)
from qgis.PyQt.QtCore import QSize
from qgis.PyQt.QtGui import QColor
app = QgsApplication([], False); app.initQgis()
jobs = json.loads(open(sys.argv[1]).read())

def layers(symbol):
    out = []
    for sl in symbol.symbolLayers():
        item = {"type": sl.layerType(), "props": sl.properties()}
        if sl.subSymbol() is not None and sl.layerType() != "SimpleMarker":
            item["sub"] = layers(sl.subSymbol())
        out.append(item)
    return out

report = {}
for job in jobs:
    layer = QgsVectorLayer(job["source"], job["name"], "ogr")
    if job.get("qml"):
        message, ok = layer.loadNamedStyle(job["qml"])
    if job.get("sld"):
        message, ok = layer.loadSldStyle(job["sld"])
    renderer = layer.renderer()
    symbols = ([renderer.symbol()] if renderer.type() == "singleSymbol"
               else [c.symbol() for c in renderer.categories()])
    report[job["name"]] = {"valid": layer.isValid(), "renderer": renderer.type(),
                           "symbols": [layers(s) for s in symbols], "labels": None}
    if layer.labelsEnabled():  # each feature's label text, as QGIS evaluates it
        settings = layer.labeling().settings()
        expression = QgsExpression(settings.fieldName if settings.isExpression
                                   else QgsExpression.quotedColumnRef(settings.fieldName))
        context = QgsExpressionContext(QgsExpressionContextUtils.globalProjectLayerScopes(layer))
        texts = []
        for feature in layer.getFeatures():
            context.setFeature(feature)
            texts.append(str(expression.evaluate(context)))
        report[job["name"]]["labels"] = texts
    if job.get("png"):  # rendered at 254 dpi: 10 pixels per mm
        settings = QgsMapSettings()
        settings.setLayers([layer]); settings.setDestinationCrs(layer.crs())
        settings.setOutputSize(QSize(*job["size"])); settings.setOutputDpi(254)
        settings.setExtent(QgsRectangle(*job["extent"]))
        settings.setBackgroundColor(QColor(255, 255, 255))
        render = QgsMapRendererSequentialJob(settings); render.start(); render.waitForFinished()
        render.renderedImage().save(job["png"])
print("QGIS_STYLES " + json.dumps(report, default=str), flush=True)
import os
os._exit(0)  # exitQgis() with layers and symbols still referenced crashes at exit
"""


def _run_qgis(folder: Path, jobs: list[dict]) -> dict:
    script, spec = folder / "qgis_styles.py", folder / "qgis_jobs.json"
    script.write_text(QGIS_SCRIPT)
    spec.write_text(json.dumps(jobs))
    run = subprocess.run([qgis_python(), str(script), str(spec)], capture_output=True,
                         text=True, timeout=120,
                         env={"QT_QPA_PLATFORM": "offscreen", "PATH": "/usr/bin:/bin",
                              "HOME": str(folder)})
    assert run.returncode == 0, run.stderr
    line = [t for t in run.stdout.splitlines() if t.startswith("QGIS_STYLES ")][-1]
    return json.loads(line.split(" ", 1)[1])


def _period_px(profile: np.ndarray) -> float:
    p = profile - profile.mean()
    spectrum = np.abs(np.fft.rfft(p * np.hanning(len(p))))
    k = int(np.argmax(spectrum[2:])) + 2
    return len(p) / k


@pytest.mark.skipif(qgis_python() is None, reason="QGIS (python3-qgis) is not installed")
def test_qgis_reads_and_draws_the_symbology(styles):
    """QGIS 3.22 loads each QML on a layer of its code: the symbol layers it reads back are the
    sheet's, and what it renders at 10 px/mm has the hatch 1.414 mm apart along a row (1 mm
    at 45 degrees) and the scarp's ticks on the left (north of a west -> east line) every
    2 mm."""
    from PIL import Image

    folder, written = styles
    data = folder / "data.gpkg"
    crs = "EPSG:3003"
    # 100 m at 1:... any: the render is 400 px = 40 mm wide over 100 m of ground
    gpd.GeoDataFrame({"code": ["FAB01002"]}, geometry=[shapely.box(10, 10, 90, 90)],
                     crs=crs).to_file(data, layer="FAB01002")
    gpd.GeoDataFrame({"code": ["SCA01001"]}, geometry=[shapely.LineString([(0, 50),
                                                                           (100, 50)])],
                     crs=crs).to_file(data, layer="SCA01001")
    for code in ("VEG01001", "SEN01001", "ALB01001", "QUO01001", "VER01001"):
        kind = {"VEG01001": "polygon", "SEN01001": "line"}.get(code, "point")
        geom = {"polygon": shapely.box(0, 0, 1, 1), "line": shapely.LineString([(0, 0),
                                                                                 (1, 1)]),
                "point": shapely.Point(0, 0)}[kind]
        gpd.GeoDataFrame({"code": [code]}, geometry=[geom], crs=crs).to_file(data, layer=code)
    jobs = [{"name": code, "source": f"{data}|layername={code}",
             "qml": str(written[f"{code}.qml"])}
            for code in ("FAB01002", "SCA01001", "VEG01001", "SEN01001", "ALB01001",
                         "QUO01001", "VER01001")]
    for job in jobs[:2]:
        job.update(png=str(folder / f"{job['name']}.png"), size=[400, 400],
                   extent=[0, 0, 100, 100])
    jobs += [{"name": f"{code} (SLD)", "source": f"{data}|layername={code}",
              "sld": str(written[f"{code}.sld"])} for code in ("FAB01002", "VEG01001")]
    seen = _run_qgis(folder, jobs)
    # QGIS reads the SLD too: the hatching as a line pattern fill, the dashes (px, 0.28 mm)
    fab_sld = [layer["type"] for layer in seen.pop("FAB01002 (SLD)")["symbols"][0]]
    assert fab_sld == ["LinePatternFill", "SimpleLine"]
    veg_sld = seen.pop("VEG01001 (SLD)")["symbols"][0]
    assert veg_sld[-1]["props"]["customdash"] == "7.14;3.57"
    kinds = {name: [(layer["type"], layer.get("sub") and [s["type"] for s in layer["sub"]])
                    for layer in got["symbols"][0]] for name, got in seen.items()}
    assert kinds == {
        "FAB01002": [("LinePatternFill", ["SimpleLine"]), ("SimpleLine", None)],
        "SCA01001": [("SimpleLine", None), ("HashLine", ["SimpleLine"])],
        "VEG01001": [("SimpleFill", None), ("SimpleLine", None)],
        "SEN01001": [("SimpleLine", None)],
        "ALB01001": [("SimpleMarker", None), ("SimpleMarker", None)],
        "QUO01001": [("SimpleMarker", None)], "VER01001": [("SimpleMarker", None)]}
    props = {name: [layer["props"] for layer in got["symbols"][0]]
             for name, got in seen.items()}
    assert {k: props["FAB01002"][0][k] for k in ("angle", "distance", "distance_unit")} == {
        "angle": "45", "distance": "1", "distance_unit": "MM"}
    assert seen["FAB01002"]["symbols"][0][0]["sub"][0]["props"]["line_width"] == "0.1"
    assert props["FAB01002"][1]["line_width"] == "0.25"
    veg = props["VEG01001"][1]
    assert (veg["use_custom_dash"], veg["customdash"], veg["customdash_unit"]) == (
        "1", "2;1", "MM")
    assert props["SEN01001"][0]["customdash"] == "0.3;0.7"
    assert props["VEG01001"][0]["color"] == "51,204,0,96"
    hashes = props["SCA01001"][1]
    assert {k: hashes[k] for k in ("interval", "hash_length", "offset", "offset_along_line")} \
        == {"interval": "2", "hash_length": "1.2", "offset": "-0.6", "offset_along_line": "1"}
    assert [props["ALB01001"][0]["name"], props["ALB01001"][1]["name"]] == ["circle", "line"]
    assert props["QUO01001"][0]["size"] == "0.7"
    assert props["VER01001"][0]["name"] == "triangle"
    # what QGIS draws
    fab = np.asarray(Image.open(folder / "FAB01002.png").convert("L"), dtype=float)
    row = fab[200, 60:340]  # inside the building (x 10-90 m -> columns 40-360)
    assert row.min() < 200 and row.max() > 250  # 0.1 mm grey lines on white
    assert _period_px(row) == pytest.approx(14.14, rel=0.05)
    scarp = np.asarray(Image.open(folder / "SCA01001.png").convert("L"), dtype=float)
    line_row = int(np.argmin(scarp[:, 200]))  # the line, near row 200
    above = scarp[line_row - 7, 20:380]  # 0.7 mm north of the line
    below = scarp[line_row + 7, 20:380]
    assert above.min() < 200 and below.min() > 250
    assert _period_px(above) == pytest.approx(20.0, rel=0.05)


@pytest.mark.skipif(qgis_python() is None, reason="QGIS (python3-qgis) is not installed")
def test_attribution_apply_embeds_the_symbology_qgis_applies(tmp_path):
    """attribution:apply on the demo restitution (its code file has symbology columns): the
    default style QGIS applies on opening the GeoPackage hatches the buildings and draws the
    spot heights as 0.7 mm dots; the sidecar QML is the same style."""
    files = restitution.make(tmp_path, {})
    out = tmp_path / "coded.gpkg"
    toolbox.run("attribution:apply", {
        "INPUT": [files["restitution_model_12"], files["restitution_model_13"]],
        "PARAMETERS": files["restitution_parameters"], "CODES": files["restitution_codes"],
        "COLOURS": files["restitution_colours"], "CRS": "EPSG:3003", "OUTPUT": out,
        "STYLE_FILES": True})
    rows = {r["f_table_name"]: r for r in read_layer_styles(out)}
    assert rows["FAB01002"]["styleQML"] == (tmp_path / "coded.gpkg.FAB01002.qml").read_text(
        encoding="utf-8")
    seen = _run_qgis(tmp_path, [{"name": n, "source": f"{out}|layername={n}"}
                                for n in ("FAB01002", "QUO01001")])
    fab = seen["FAB01002"]["symbols"][0]
    assert [layer["type"] for layer in fab] == ["LinePatternFill", "SimpleLine"]
    assert (fab[0]["props"]["angle"], fab[0]["props"]["distance"]) == ("45", "1")
    assert fab[1]["props"]["line_width"] == "0.25"
    quo = seen["QUO01001"]["symbols"][0][0]["props"]
    assert (quo["name"], quo["size"], quo["color"]) == ("circle", "0.7", "0,0,255,255")
    # spot heights are labelled with their height (one decimal), as the sheet prints them;
    # buildings with their description
    heights = [f"{g.z:.1f}" for g in gpd.read_file(out, layer="QUO01001").geometry]
    assert heights and seen["QUO01001"]["labels"] == heights
    assert set(seen["FAB01002"]["labels"]) == {"muro perimetrale di fabbricato civile"}


def test_bad_symbology_stops_attribution_apply_before_any_work(tmp_path):
    """The styles now read the symbology columns: a bad one is a one-line error naming the
    line, before the restitution is read (no warnings first), and no output is left."""
    from conftest import run_cli

    files = restitution.make(tmp_path, {})
    bad = tmp_path / "bad_codes.txt"
    bad.write_bytes(files["restitution_codes"].read_bytes().replace(b";45/1.0;", b";diagonal;"))
    out = tmp_path / "coded.gpkg"
    proc = run_cli("run", "attribution:apply", "--INPUT", files["restitution_model_12"],
                   "--PARAMETERS", files["restitution_parameters"], "--CODES", bad,
                   "--CRS", "EPSG:3003", "--OUTPUT", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "CODES: line 5: hatch 'diagonal'" in lines[0], lines
    assert not out.exists()
