"""attribution:apply on realistic files: readers, counts, attributes, colours, styles, QGIS."""

from __future__ import annotations

import json
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import geopandas as gpd
import numpy as np
import pandas as pd
import pyogrio
import pytest
import shapely
from restitution_files import make_files  # the test folder's helper module

import toolbox
from tests.helpers_cli import qgis_python
from toolbox.attribution.restitution import read_ascii, read_dxf, read_two_tables
from toolbox.errors import InputDataError
from toolbox.styles.gpkg import read_layer_styles


@pytest.fixture
def files(tmp_path):
    """Code, colour, parameter files and an ASCII export with every defect (see make_files)."""
    return make_files(tmp_path)


E0, N0 = 1688500.0, 4799700.0  # as in restitution_files.py


@pytest.fixture
def applied(files):
    out = files["folder"] / "coded.gpkg"
    feedback = toolbox.Feedback()
    result = toolbox.run("attribution:apply", {
        "INPUT": files["export"], "CODES": files["codes"], "COLOURS": files["colours"],
        "PARAMETERS": files["params"], "CRS": "EPSG:3003", "OUTPUT": out,
        "STYLE_FILES": True}, feedback=feedback)
    return out, result["STATISTICS"], feedback


def test_counts_per_code_and_reason(applied):
    _, stats, feedback = applied
    assert stats["entities"] == 13 and stats["resolved"] == 5 and stats["unresolved"] == 8
    assert stats["unresolved_by_reason"] == {
        "unclosed_polygon": 1, "degenerate": 2, "type_mismatch": 1, "unknown_code": 2,
        "invalid_polygon": 1, "no_vertices": 1}
    assert stats["per_code"]["FAB01002"] == {"entities": 3, "resolved": 2,
                                             "unclosed_polygon": 1}
    assert stats["per_code"]["VEG01001"] == {"entities": 2, "invalid_polygon": 1,
                                             "degenerate": 1}
    assert stats["unknown_codes"] == ["XYZ99999", "str02001"]
    # declared but carried by no entity (VEG01001 and MAR01001 have entities, unresolved)
    assert stats["unused_codes"] == ["ALB01001", "TOP01001"]
    assert stats["polygons_closed"] == 1
    assert stats["layers"] == {"FAB01002": 2, "FER01001": 1, "QUO01001": 1, "STR02001": 1}
    assert any("2 codes of CODES not used: ALB01001, TOP01001" in w for w in feedback.warnings)
    # a shared parameter file's entries for other steps: said as information, not a warning
    infos = [text for level, text in feedback.messages if level == "info"]
    assert any("'passo di spline' (line 6)" in m for m in infos)
    assert not any("'passo di spline'" in w for w in feedback.warnings)


def test_layers_attributes_and_translation(applied):
    out, _, _ = applied
    layers = {name: kind for name, kind in pyogrio.list_layers(out)}
    assert layers == {"FAB01002": "Polygon Z", "FER01001": "LineString Z",
                      "QUO01001": "Point Z", "STR02001": "LineString Z",
                      "unresolved": "Point Z", "layer_styles": None}
    fab = gpd.read_file(out, layer="FAB01002")
    assert fab["entity"].tolist() == [1, 2]
    assert fab["description"].tolist() == ["muro perimetrale di fabbricato civile"] * 2
    assert fab["colour"].tolist() == ["#4d4d4d"] * 2  # 30 % -> 76.5 -> 77 = 0x4d
    assert fab[["r", "g", "b"]].to_numpy().tolist() == [[77, 77, 77]] * 2
    assert fab["source"].iloc[0] == "1" and pd.isna(fab["source"].iloc[1])
    assert fab["area"].tolist() == [200.0, 80.0] and fab["perimeter"].tolist() == [60.0, 36.0]
    # stored coordinates + translation = map coordinates; Z kept in the geometry
    assert fab.total_bounds.tolist() == [E0, N0, E0 + 40, N0 + 10]
    assert shapely.get_coordinates(fab.geometry.iloc[1], include_z=True)[-1].tolist() == \
        [E0 + 30, N0, 331.0]  # closed: the last vertex snapped onto the first
    assert fab["z_min"].tolist() == [330.0, 331.0] and fab["z_mean"].tolist() == [330.0, 331.0]
    road = gpd.read_file(out, layer="STR02001")
    assert road["length"].iloc[0] == pytest.approx(2 * np.hypot(30, 0.5), abs=1e-6)
    assert road[["z_min", "z_max", "z_mean"]].iloc[0].tolist() == pytest.approx(
        [320.0, 320.4, 320.2])
    assert road["colour"].iloc[0] == "#ff0000"
    rail = gpd.read_file(out, layer="FER01001")  # colour 44 is not in the colour file
    assert rail["colour"].iloc[0] is None and rail["colour_index"].iloc[0] == "44"
    spot = gpd.read_file(out, layer="QUO01001")
    assert spot.geometry.iloc[0].z == 321.25 and spot["colour"].iloc[0] == "#0000ff"


def test_unresolved_layer_has_every_entity_with_its_reason(applied):
    out, _, _ = applied
    unresolved = gpd.read_file(out, layer="unresolved")
    assert dict(zip(unresolved["entity"], unresolved["reason"], strict=True)) == {
        3: "unclosed_polygon", 5: "degenerate", 7: "type_mismatch", 8: "unknown_code",
        9: "invalid_polygon", 10: "degenerate", 11: "no_vertices", 13: "unknown_code"}
    row = unresolved.set_index("entity").loc[3]
    assert row["detail"] == "ends 1.200 apart (closure tolerance 0.5)"
    assert row["line"] == 17  # the CODE line of entity 3 in the export
    assert (row.geometry.x, row.geometry.y) == (E0 + 50, N0)
    assert shapely.from_wkt(row["geometry_wkt"]).equals(shapely.LineString(
        [(E0 + 50, N0), (E0 + 60, N0), (E0 + 60, N0 + 8), (E0 + 50, N0 + 8),
         (E0 + 50, N0 + 1.2)]))
    assert unresolved.set_index("entity").loc[5, "detail"] == "line with one vertex"
    assert unresolved.set_index("entity").loc[11].geometry is None


def test_type_layout(files):
    out = files["folder"] / "by_type.gpkg"
    toolbox.run("attribution:apply", {
        "INPUT": files["export"], "CODES": files["codes"], "COLOURS": files["colours"],
        "PARAMETERS": files["params"], "CRS": "EPSG:3003", "LAYOUT": "type", "OUTPUT": out})
    lines = gpd.read_file(out, layer="lines")
    assert lines["code"].tolist() == ["STR02001", "FER01001"]  # entity order
    assert set(pyogrio.list_layers(out)[:, 0]) == {"lines", "points", "polygons", "unresolved",
                                                   "layer_styles"}


def _rgba(text):
    return tuple(int(v) for v in text.split(","))


def test_styles_are_qml_qgis_reads_and_sld(applied):
    out, stats, _ = applied
    rows = read_layer_styles(out)
    assert sorted(r["f_table_name"] for r in rows) == sorted(stats["styled_layers"]) == [
        "FAB01002", "FER01001", "QUO01001", "STR02001", "unresolved"]
    assert all(r["useAsDefault"] == 1 and r["f_geometry_column"] == "geom" and
               r["f_table_schema"] == "" for r in rows)
    qml = {r["f_table_name"]: ET.fromstring(r["styleQML"].split("\n", 1)[1]) for r in rows}
    fab = qml["FAB01002"].find("renderer-v2")
    assert fab.get("type") == "singleSymbol"
    layer = fab.find("symbols/symbol/layer")
    assert fab.find("symbols/symbol").get("type") == "fill" and layer.get("class") == \
        "SimpleFill"
    props = {o.get("name"): o.get("value") for o in layer.find("Option")}
    assert _rgba(props["outline_color"]) == (77, 77, 77, 255)
    assert _rgba(props["color"])[:3] == (77, 77, 77)
    assert qml["FAB01002"].find("labeling/settings/text-style").get("fieldName") == \
        "description"
    line = qml["STR02001"].find("renderer-v2/symbols/symbol/layer")
    assert line.get("class") == "SimpleLine"
    assert _rgba({p.get("k"): p.get("v") for p in line.findall("prop")}["line_color"]) == \
        (255, 0, 0, 255)
    assert qml["STR02001"].find("labeling") is None
    sld = ET.fromstring(rows[0]["styleSLD"].split("\n", 1)[1])
    ns = {"sld": "http://www.opengis.net/sld"}
    assert sld.find(".//sld:PolygonSymbolizer/sld:Stroke/sld:CssParameter", ns).text == \
        "#4d4d4d"
    # the same styles beside the GeoPackage
    qml_file = out.with_name("coded.gpkg.FAB01002.qml")
    assert qml_file.read_text(encoding="utf-8") == next(
        r["styleQML"] for r in rows if r["f_table_name"] == "FAB01002")
    assert out.with_name("coded.gpkg.unresolved.sld").exists()


@pytest.mark.parametrize("suffix", [".shp", ".geojson", ".fgb"])
def test_one_layer_formats_get_every_layer_and_its_style_file(applied, files, suffix):
    """OUTPUT in a one-layer format (offered by the help) was refused as a corrupt INPUT
    ("file is not a database": the styles were written into it with SQLite). Each layer is
    written beside the first as <stem>_<layer><ext> with the GeoPackage's features, and its
    style as <file stem>.qml / .sld (the file QGIS loads with the layer)."""
    gpkg, stats, _ = applied
    out = files["folder"] / f"coded{suffix}"
    toolbox.run("attribution:apply", {
        "INPUT": files["export"], "CODES": files["codes"], "COLOURS": files["colours"],
        "PARAMETERS": files["params"], "CRS": "EPSG:3003", "OUTPUT": out})
    styles = {r["f_table_name"]: r["styleQML"] for r in read_layer_styles(gpkg)}
    names = [str(n) for n, _ in pyogrio.list_layers(gpkg) if str(n) != "layer_styles"]
    for k, name in enumerate(names):
        layer_file = out if k == 0 else out.with_name(f"coded_{name}{suffix}")
        ours = gpd.read_file(layer_file)
        assert len(ours) == len(gpd.read_file(gpkg, layer=name)) and ours.crs.to_epsg() == 3003
        if name in styles:
            expected = styles[name]
            if suffix == ".shp":  # the style names the fields as the DBF holds them
                expected = expected.replace('="description"', '="descriptio"')
                assert "descriptio" not in styles[name] or "descriptio" in list(
                    pyogrio.read_info(layer_file)["fields"])
            assert layer_file.with_suffix(".qml").read_text(encoding="utf-8") == expected
            assert layer_file.with_suffix(".sld").exists()


def test_categorised_style_for_a_layer_of_several_codes(files):
    out = files["folder"] / "by_type.gpkg"
    toolbox.run("attribution:apply", {
        "INPUT": files["export"], "CODES": files["codes"], "COLOURS": files["colours"],
        "PARAMETERS": files["params"], "CRS": "EPSG:3003", "LAYOUT": "type", "OUTPUT": out})
    row = next(r for r in read_layer_styles(out) if r["f_table_name"] == "lines")
    renderer = ET.fromstring(row["styleQML"].split("\n", 1)[1]).find("renderer-v2")
    assert renderer.get("type") == "categorizedSymbol" and renderer.get("attr") == "code"
    categories = [(c.get("value"), c.get("symbol")) for c in renderer.find("categories")]
    assert categories == [("FER01001", "0"), ("STR02001", "1")]
    colours = {s.get("name"): _rgba({p.get("k"): p.get("v") for p in s.find("layer")
                                     .findall("prop")}["line_color"])
               for s in renderer.find("symbols")}
    assert colours == {"0": (128, 128, 128, 255), "1": (255, 0, 0, 255)}


QGIS_SCRIPT = """
import json, sys
from qgis.core import QgsApplication, QgsVectorLayer
app = QgsApplication([], False); app.initQgis()
out = {}
for name in sys.argv[2:]:
    layer = QgsVectorLayer(f"{sys.argv[1]}|layername={name}", name, "ogr")
    r = layer.renderer()
    out[name] = {"valid": layer.isValid(), "renderer": r.type(),
                 "colour": r.symbol().color().name() if r.type() == "singleSymbol" else None,
                 "labels": layer.labelsEnabled()}
    if r.type() == "categorizedSymbol":
        out[name]["categories"] = [[r.classAttribute(), c.value(), c.symbol().color().name()]
                                   for c in r.categories()]
print(json.dumps(out))
"""


@pytest.mark.skipif(qgis_python() is None, reason="QGIS (python3-qgis) is not installed")
def test_qgis_opens_every_layer_with_its_default_style(applied, files, tmp_path):
    out, _, _ = applied
    script = tmp_path / "qgis_check.py"
    script.write_text(QGIS_SCRIPT)
    run = subprocess.run([qgis_python(), str(script), str(out), "FAB01002", "STR02001",
                          "QUO01001", "unresolved"], capture_output=True, text=True,
                         env={"QT_QPA_PLATFORM": "offscreen", "PATH": "/usr/bin:/bin",
                              "HOME": str(tmp_path)}, timeout=60)
    assert run.returncode == 0, run.stderr
    seen = json.loads(run.stdout.strip().splitlines()[-1])
    assert seen == {
        "FAB01002": {"valid": True, "renderer": "singleSymbol", "colour": "#4d4d4d",
                     "labels": True},
        "STR02001": {"valid": True, "renderer": "singleSymbol", "colour": "#ff0000",
                     "labels": False},
        "QUO01001": {"valid": True, "renderer": "singleSymbol", "colour": "#0000ff",
                     "labels": True},
        "unresolved": {"valid": True, "renderer": "singleSymbol", "colour": "#e41a1c",
                       "labels": True}}
    # a layer of several codes: categorised on code, each category in its code's colour
    by_type = tmp_path / "by_type.gpkg"
    toolbox.run("attribution:apply", {
        "INPUT": files["export"], "CODES": files["codes"], "COLOURS": files["colours"],
        "PARAMETERS": files["params"], "CRS": "EPSG:3003", "LAYOUT": "type", "OUTPUT": by_type})
    run = subprocess.run([qgis_python(), str(script), str(by_type), "lines"],
                         capture_output=True, text=True, timeout=60,
                         env={"QT_QPA_PLATFORM": "offscreen", "PATH": "/usr/bin:/bin",
                              "HOME": str(tmp_path)})
    lines = json.loads(run.stdout.strip().splitlines()[-1])["lines"]
    assert lines["renderer"] == "categorizedSymbol"
    assert lines["categories"] == [["code", "FER01001", "#808080"],
                                   ["code", "STR02001", "#ff0000"]]


# -- readers ------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, message", [
    ("CODE A\n1 2 3\nCODE B\n", "line 3: CODE before the END of the entity started on line 1"),
    ("1 2 3\n", "line 1: coordinates outside an entity"),
    ("CODE A\n1 2\nEND\n", "line 2: expected 'E N Z' (three numbers), got '1 2'"),
    ("CODE A\n1 2 x\nEND\n", "line 2: expected 'E N Z'"),
    ("END\n", "line 1: END without a CODE"),
    ("CODE A\n1 2 3\n", "the entity started on line 1 (CODE A) has no END"),
    ("CODE\nEND\n", "line 1: CODE without a code"),
])
def test_ascii_export_errors_name_file_and_line(tmp_path, text, message):
    path = tmp_path / "export.txt"
    path.write_text(text)
    with pytest.raises(InputDataError) as err:
        read_ascii(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_two_table_form(tmp_path):
    """Descriptions (record; code; vertices; colour; source; bbox; first) + coordinates
    (colour; E; N; Z); record 3's bounding box is wrong (reported, kept)."""
    desc = tmp_path / "descrizioni.txt"
    desc.write_text("record;code;vertices;colour;source;xmin;ymin;xmax;ymax;first\n"
                    "1;FAB01002;5;12;1;100;200;110;210;1\n"
                    "2;QUO01001;1;5;3;105;205;105;205;6\n"
                    "3;STR02001;2;3;1;100;190;101;191;7\n")
    coords = tmp_path / "coordinate.txt"
    coords.write_text("colour;E;N;Z\n" + "".join(
        f"12;{x};{y};300\n" for x, y in [(100, 200), (110, 200), (110, 210), (100, 210),
                                          (100, 200)])
        + "5;105;205;301.5\n3;100;180;299\n3;120;180;299.5\n")
    frame, report = read_two_tables(desc, coords)
    assert frame["code"].tolist() == ["FAB01002", "QUO01001", "STR02001"]
    assert frame["colour"].tolist() == ["12", "5", "3"] and frame["source"].tolist() == \
        ["1", "3", "1"]
    assert frame.geometry.iloc[1].equals(shapely.Point(105, 205, 301.5))
    assert shapely.get_coordinates(frame.geometry.iloc[2], include_z=True).tolist() == \
        [[100, 180, 299], [120, 180, 299.5]]
    assert report["bbox_mismatches"] == [3]
    bad = tmp_path / "bad.txt"
    bad.write_text("1;FAB01002;5;12;1;100;200;110;210;6\n")
    with pytest.raises(InputDataError, match=r"line 1: vertices 6..10 are not in "
                                             r"'coordinate.txt' \(8 records\)"):
        read_two_tables(bad, coords)


def _dxf(path):
    import ezdxf

    doc = ezdxf.new("R2010")
    doc.layers.add("FAB01002", color=8)
    doc.layers.add("ALB01001", color=3)
    doc.blocks.new("ALBERO").add_circle((0, 0), 1)
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 5), (0, 5)], close=True,
                       dxfattribs={"layer": "FAB01002", "elevation": 330.0})
    msp.add_polyline3d([(0, 10, 320), (5, 10, 320.5), (9, 11, 321)],
                       dxfattribs={"layer": "STR02001", "color": 1})
    msp.add_line((0, 20, 1), (5, 20, 2), dxfattribs={"layer": "STR02001"})
    msp.add_point((3, 3, 331.5), dxfattribs={"layer": "QUO01001"})
    msp.add_blockref("ALBERO", (20, 5, 321), dxfattribs={"layer": "ALB01001", "rotation": 30,
                                                          "xscale": 1.5, "yscale": 2.0})
    msp.add_text("Località Il Poggio", height=2.5, rotation=15,
                 dxfattribs={"layer": "TOP01001", "insert": (4, 2, 330)})
    msp.add_solid([(50, 50), (53, 50), (50, 53)], dxfattribs={"layer": "VEG01001"})
    doc.saveas(path)


def test_dxf_reader(tmp_path):
    path = tmp_path / "restituzione.dxf"
    _dxf(path)
    frame, report = read_dxf(path)
    assert frame["code"].tolist() == ["FAB01002", "STR02001", "STR02001", "QUO01001",
                                      "ALB01001", "TOP01001"]
    assert frame["kind"].tolist() == ["line", "line", "line", "point", "symbol", "label"]
    assert report["skipped_dxf_entities"] == {"SOLID": 1}
    building = shapely.get_coordinates(frame.geometry.iloc[0], include_z=True)
    assert building.tolist() == [[0, 0, 330], [10, 0, 330], [10, 5, 330], [0, 5, 330],
                                 [0, 0, 330]]
    assert frame["colour"].tolist()[:2] == ["8", "1"]  # BYLAYER resolved; explicit ACI 1
    tree = frame.iloc[4]
    assert (tree["block"], tree["rotation"], tree["scale_x"], tree["scale_y"]) == \
        ("ALBERO", 30.0, 1.5, 2.0)
    assert tree.geometry.equals(shapely.Point(20, 5, 321))
    label = frame.iloc[5]
    assert (label["text"], label["text_height"], label["rotation"]) == \
        ("Località Il Poggio", 2.5, 15.0)


def test_dxf_through_apply(tmp_path, files):
    path = tmp_path / "restituzione.dxf"
    _dxf(path)
    out = tmp_path / "dxf.gpkg"
    feedback = toolbox.Feedback()
    stats = toolbox.run("attribution:apply", {
        "INPUT": path, "CODES": files["codes"], "COLOURS": files["colours"],
        "CRS": "EPSG:3857",  # coordinates near 0, 0: inside this CRS's area (not EPSG:3003's)
        "OUTPUT": out}, feedback=feedback)["STATISTICS"]
    assert stats["layers"] == {"ALB01001": 1, "FAB01002": 1, "QUO01001": 1, "STR02001": 2}
    assert stats["labels"] == 1 and stats["unresolved"] == 0
    assert any("DXF entities not read: 1 SOLID" in w for w in feedback.warnings)
    trees = gpd.read_file(out, layer="ALB01001")
    assert trees[["block", "rotation", "scale_x", "scale_y"]].iloc[0].tolist() == \
        ["ALBERO", 30.0, 1.5, 2.0]
    labels = gpd.read_file(out, layer="labels")
    assert labels[["code", "text", "description"]].iloc[0].tolist() == \
        ["TOP01001", "Località Il Poggio", "toponimo di località"]
    assert {r["f_table_name"] for r in read_layer_styles(out)} == {
        "ALB01001", "FAB01002", "QUO01001", "STR02001", "labels", "unresolved"}


def test_ogr_layer_with_a_code_field(tmp_path, files):
    frame = gpd.GeoDataFrame(
        {"codice": ["FAB01002", "STR02001", None]},
        geometry=[shapely.MultiPolygon([shapely.box(0, 0, 10, 10), shapely.box(20, 0, 30, 5)]),
                  shapely.LineString([(0, 20), (30, 20)]), shapely.Point(1, 1)],
        crs="EPSG:3857")  # coordinates near 0, 0: inside this CRS's area (not EPSG:3003's)
    src = tmp_path / "lines.gpkg"
    frame.to_file(src, driver="GPKG")
    out = tmp_path / "ogr.gpkg"
    stats = toolbox.run("attribution:apply", {"INPUT": f"{src}|layername=lines",
                                              "CODES": files["codes"], "OUTPUT": out}
                        )["STATISTICS"]
    assert stats["layers"] == {"FAB01002": 2, "STR02001": 1}
    assert stats["unresolved_by_reason"] == {"no_code": 1}
    assert stats["readers"]["input_1"] == {"code_field": "codice", "multipart_split": 1}
    assert gpd.read_file(out, layer="FAB01002")["area"].tolist() == [100.0, 50.0]


def test_bad_code_file_fails_before_any_output(files):
    bad = files["folder"] / "bad_codes.txt"
    bad.write_text("codice;tipologia\nFAB01002;esagono\n")
    out = files["folder"] / "never.gpkg"
    with pytest.raises(InputDataError, match="line 2: type 'esagono'"):
        toolbox.run("attribution:apply", {"INPUT": files["export"], "CODES": bad,
                                          "OUTPUT": out})
    assert not out.exists()


VALIDATOR = "/usr/lib/python3/dist-packages/osgeo_utils/samples/validate_gpkg.py"
CHECK_SCRIPT = """
import json, sys
sys.path.insert(0, sys.argv[1])
import validate_gpkg
errors = validate_gpkg.check(sys.argv[2], abort_at_first_error=False)
print(json.dumps([e[1] for e in errors]))
"""


@pytest.mark.skipif(not Path(VALIDATOR).exists() or qgis_python() is None,
                    reason="GDAL's validate_gpkg.py (python3-gdal) is not installed")
def test_geopackage_passes_gdal_validator(applied, tmp_path):
    """GDAL's GeoPackage validator (Debian's GDAL 3.6) finds nothing: the toolbox writes
    GeoPackage 1.2 (with the R-tree triggers that version names), the layers, their contents
    rows and layer_styles are valid."""
    out, _, _ = applied
    script = tmp_path / "check.py"
    script.write_text(CHECK_SCRIPT)
    run = subprocess.run([qgis_python(), str(script), str(Path(VALIDATOR).parent), str(out)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    errors = json.loads(run.stdout.strip().splitlines()[-1])
    assert errors == [], errors
