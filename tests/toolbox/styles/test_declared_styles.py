"""Every output layer whose spec names a style (``Layer(style=...)``, shown by ``toolbox help ID
--json``) gets it as its default in the GeoPackage's ``layer_styles`` table, written by the
runner: topology areas and errors, photo footprints, rectify residuals, TIN triangles. The
styles are checked against the layers actually written (read with pyogrio/sqlite): renderer
type, classified field present, symbol type of the layer's geometry, every value found in the
data drawn by a category or range; and in real QGIS 3.22 when it is installed."""

from __future__ import annotations

import json
import subprocess
import xml.etree.ElementTree as ET

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely

import toolbox
from tests.helpers_cli import qgis_python
from toolbox.demo.samples import linework
from toolbox.registry import spec_index
from toolbox.styles.gpkg import read_layer_styles
from toolbox.styles.layers import STYLES

SLD_ROOT = "{http://www.opengis.net/sld}StyledLayerDescriptor"
SYMBOL_OF = {"Point": "marker", "LineString": "line", "Polygon": "fill"}  # QGIS symbol types


def _xml(text: str) -> ET.Element:
    """Parse a QML (DOCTYPE first) or an SLD (XML declaration first)."""
    return ET.fromstring(text.split("\n", 1)[1])


def check_styles(path, expected: dict[str, tuple[str, str | None]]) -> dict[str, ET.Element]:
    """The file has one default style row per layer of ``expected`` (layer -> (renderer type,
    classified field)), none for other layers; its QML draws the layer's geometry with that
    renderer on a field the layer has, its SLD parses. Returns the QML renderers by layer."""
    rows = read_layer_styles(path)
    assert sorted(r["f_table_name"] for r in rows) == sorted(expected)
    info = {str(name): str(gtype) for name, gtype in pyogrio.list_layers(path)}
    renderers = {}
    for row in rows:
        layer = row["f_table_name"]
        assert row["useAsDefault"] == 1 and row["f_geometry_column"] == "geom"
        kind, field = expected[layer]
        renderer = _xml(row["styleQML"]).find("renderer-v2")
        assert renderer.get("type") == kind
        assert renderer.get("attr") == field
        if field is not None:
            assert field in pyogrio.read_info(path, layer=layer)["fields"]
        geometry = info[layer].removesuffix(" Z").removeprefix("Multi")
        assert {s.get("type") for s in renderer.find("symbols")} == {SYMBOL_OF[geometry]}
        assert _xml(row["styleSLD"]).tag == SLD_ROOT
        renderers[layer] = renderer
    return renderers


def categories(renderer: ET.Element) -> set[str]:
    return {c.get("value") for c in renderer.find("categories")}


@pytest.fixture(scope="module")
def linework_data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("linework")
    return linework.make(folder, {})


def _linework(data: dict, out) -> dict:
    return {"INPUT": data["linework"], "LABELS": data["linework_labels"],
            "PARAMETERS": data["linework_parameters"], "OUTPUT": out}


@pytest.fixture(scope="module")
def areas_gpkg(linework_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("areas") / "areas.gpkg"
    toolbox.run("topology:build_areas", _linework(linework_data, out))
    return out


def test_build_areas_styles_areas_and_errors(areas_gpkg):
    renderers = check_styles(areas_gpkg, {
        "areas": ("singleSymbol", None), "errors_points": ("categorizedSymbol", "severity"),
        "errors_lines": ("categorizedSymbol", "severity")})
    fill = renderers["areas"].find("symbols/symbol/layer")
    props = {p.get("k"): p.get("v") for p in fill.findall("prop")}
    assert fill.get("class") == "SimpleFill" and props["outline_style"] == "solid"
    for layer in ("errors_points", "errors_lines"):  # every severity written has its colour
        found = set(gpd.read_file(areas_gpkg, layer=layer)["severity"])
        assert found and found <= categories(renderers[layer])


def test_check_styles_its_error_layers(linework_data, tmp_path):
    out = tmp_path / "check.gpkg"
    toolbox.run("topology:check", _linework(linework_data, out))
    check_styles(out, {"errors_points": ("categorizedSymbol", "severity"),
                       "errors_lines": ("categorizedSymbol", "severity")})


def test_footprints_outline_only(tmp_path):
    from tests.algorithms.orientation.test_orientation_algorithms import nadir_block

    out = tmp_path / "fp.gpkg"
    toolbox.run("orientation:footprints", {"PROJECT": nadir_block(tmp_path),
                                           "MEAN_HEIGHT": 100.0, "OUTPUT": out})
    fill = check_styles(out, {"footprints": ("singleSymbol", None)})["footprints"].find(
        "symbols/symbol/layer")
    props = {p.get("k"): p.get("v") for p in fill.findall("prop")}
    assert props["color"].split(",")[3] == "0" and props["outline_style"] == "solid"


def test_residuals_by_role(tmp_path):
    from tests.algorithms.rectify import rectify_scene as scene

    ids, image, ground, roles = scene.gcp_table(16, noise=0.2, gross={"G07": (10.0, 0.0)},
                                                checks=("G01", "G12"))
    csv_path = scene.write_gcp_csv(tmp_path / "gcps.csv", ids, image, ground, roles)
    out = tmp_path / "res.gpkg"
    toolbox.run("rectify:estimate", {"INPUT": csv_path, "CRS": "EPSG:3003",
                                     "OUTPUT": tmp_path / "t.json", "RESIDUALS": out})
    renderer = check_styles(out, {"residuals": ("categorizedSymbol", "role")})["residuals"]
    found = set(gpd.read_file(out, layer="residuals")["role"])
    assert found == {"control", "check", "rejected"} and found <= categories(renderer)


@pytest.fixture(scope="module")
def tin_gpkg(tmp_path_factory):
    """A TIN of a cone-like surface (slopes from flat to about 60 degrees)."""
    folder = tmp_path_factory.mktemp("tin")
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 100, (300, 2)) + (1_688_000.0, 4_799_500.0)
    r = np.hypot(*(xy - xy.mean(axis=0)).T)
    z = 300.0 + 0.002 * r ** 2.2
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], z), crs="EPSG:3003").to_file(
        folder / "points.gpkg")
    out = folder / "tin.gpkg"
    toolbox.run("tin:delaunay", {"INPUT": folder / "points.gpkg", "OUTPUT": out})
    return out


def test_tin_triangles_graduated_on_slope(tin_gpkg):
    renderer = check_styles(tin_gpkg, {"triangles": ("graduatedSymbol", "slope_deg")})[
        "triangles"]
    ranges = [(float(r.get("lower")), float(r.get("upper"))) for r in renderer.find("ranges")]
    assert len(ranges) == 5 and ranges[0][0] == 0 and ranges[-1][1] == 90
    assert all(a[1] == b[0] for a, b in zip(ranges, ranges[1:]))  # contiguous
    slope = gpd.read_file(tin_gpkg, layer="triangles")["slope_deg"].to_numpy()
    classes = np.searchsorted([upper for _, upper in ranges], slope)
    assert len(np.unique(classes)) >= 3  # the surface spans several classes
    for symbol in renderer.find("symbols"):  # filled, no outline
        props = {p.get("k"): p.get("v") for p in symbol.find("layer").findall("prop")}
        assert props["outline_style"] == "no"


def test_other_formats_and_contours_unchanged(tmp_path, plane_dem):
    """FlatGeobuf has no style table (the run succeeds: carto:contours to .fgb failed with
    'cannot read an input ... file is not a database', writing its style with sqlite); contours
    keep their one style row (written by carto:contours, not a second time by the runner)."""
    fgb = toolbox.run("carto:contours", {"INPUT": plane_dem[0], "INTERVAL": 2.0,
                                         "OUTPUT": tmp_path / "c.fgb"})
    assert len(gpd.read_file(fgb["OUTPUT"])) > 0
    points = tmp_path / "p.gpkg"
    xy = np.random.default_rng(1).uniform(0, 50, (30, 2)) + (1_688_000.0, 4_799_500.0)
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], xy[:, 1] * 0.1),
                     crs="EPSG:3003").to_file(points)
    out = toolbox.run("tin:delaunay", {"INPUT": points, "OUTPUT": tmp_path / "tin.fgb"})
    assert len(gpd.read_file(out["OUTPUT"])) > 0
    contours = tmp_path / "c.gpkg"
    toolbox.run("carto:contours", {"INPUT": plane_dem[0], "INTERVAL": 2.0, "OUTPUT": contours})
    rows = read_layer_styles(contours)
    assert [(r["f_table_name"], r["useAsDefault"]) for r in rows] == [("contours", 1)]
    assert _xml(rows[0]["styleQML"]).find("renderer-v2").get("type") == "RuleRenderer"


def test_every_declared_style_is_written():
    """A style named in a spec is one the runner writes, or contours' (its algorithm's)."""
    declared = {layer["style"] for spec in spec_index().values()
                for p in spec["parameters"] for layer in p.get("layers", ()) if layer["style"]}
    assert declared == set(STYLES) | {"contours"}


QGIS_SCRIPT = r"""
import json, sys
from qgis.core import QgsApplication, QgsRenderContext, QgsVectorLayer
app = QgsApplication([], False); app.initQgis()
out = {}
for source in json.loads(sys.argv[1]):  # opened as a user would: the default style applies
    layer = QgsVectorLayer(source, "layer", "ogr")
    renderer = layer.renderer()
    out[source] = {"valid": layer.isValid(), "renderer": renderer.type(),
                   "symbol": renderer.symbols(QgsRenderContext())[0].color().name()}
    if renderer.type() == "graduatedSymbol":
        out[source]["class_of_12"] = renderer.rangeForValue(12.0).label()
    if renderer.type() == "categorizedSymbol":
        kept = renderer.categories()  # (a temporary list's symbols are freed at once)
        out[source]["error"] = kept[renderer.categoryIndexForValue("error")].symbol().color(
            ).name()
print("QGIS_LAYERS " + json.dumps(out), flush=True)
import os
os._exit(0)
"""


@pytest.mark.skipif(qgis_python() is None, reason="QGIS (python3-qgis) is not installed")
def test_qgis_opens_the_layers_styled(areas_gpkg, tin_gpkg, tmp_path):
    sources = [f"{areas_gpkg}|layername=areas", f"{areas_gpkg}|layername=errors_points",
               f"{tin_gpkg}|layername=triangles"]
    run = subprocess.run([qgis_python(), "-c", QGIS_SCRIPT, json.dumps(sources)],
                         capture_output=True, text=True, timeout=120,
                         env={"QT_QPA_PLATFORM": "offscreen", "PATH": "/usr/bin:/bin",
                              "HOME": str(tmp_path)})
    assert run.returncode == 0, run.stderr
    line = [t for t in run.stdout.splitlines() if t.startswith("QGIS_LAYERS ")][-1]
    got = json.loads(line.split(" ", 1)[1])
    areas, errors, triangles = (got[s] for s in sources)
    assert areas["valid"] and areas["renderer"] == "singleSymbol"
    assert areas["symbol"] == "#ffecaa"  # the light fill
    assert errors["renderer"] == "categorizedSymbol" and errors["error"] == "#e31a1c"
    assert triangles["renderer"] == "graduatedSymbol" and triangles["class_of_12"] == "10 - 20°"
