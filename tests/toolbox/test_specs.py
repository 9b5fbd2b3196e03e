"""Specs complete enough for a GUI: declared layers match what the algorithms write (on the demo's
outputs), parameter flags, `help --all --json`, `run --progress json`, deprecated names, help texts
that speak to users."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import pyogrio
import pytest

import toolbox
from toolbox.errors import ParameterError
from toolbox.parameters import (
    ADVANCED_NAMES,
    Layer,
    Number,
    Output,
    OutputVector,
    Parameter,
    VectorLayer,
)
from toolbox.registry import algorithms, get

# pyogrio dtypes of each declared field type
FIELD_DTYPES = {"string": {"object", "str"}, "integer": {"int64", "int32", "int16"},
                "real": {"float64", "float32"}, "boolean": {"bool"},
                "date": {"datetime64[ms]", "object"}, "datetime": {"datetime64[ms]", "object"},
                "json": {"object"}}


def builtin() -> list:
    return [a for a in algorithms() if a.__module__.startswith("algorithms.")]


def layer_name_of(value: str) -> str:
    """The layer a parameter value names: ``path|layername=x`` -> x; a file -> its first layer;
    any other value (an OPERATION) -> itself."""
    if "|layername=" in value:
        return value.split("|layername=", 1)[1].split("|", 1)[0]
    if value.endswith((".gpkg", ".shp", ".geojson", ".fgb")):
        return pyogrio.list_layers(value)[0][0]
    return value


def resolve(template: str, parameters: dict) -> str:
    for name, value in parameters.items():
        if f"{{{name}}}" in template:
            template = template.replace(f"{{{name}}}", layer_name_of(str(value)))
    return template


def check_layers(path: str, declared: list[Layer], parameters: dict) -> list[str]:
    """Problems of the layers written against the declared ones. ``layer_styles`` (QGIS's styles
    table) is always allowed; a declared name with ``*`` stands for layers named after the data
    (one per code: their geometry type varies, only the listed fields are checked)."""
    import fnmatch

    problems = []
    written = {name: geometry for name, geometry in pyogrio.list_layers(path)
               if name != "layer_styles"}
    expected = {resolve(layer.name, parameters): layer for layer in declared}
    patterns = {name: layer for name, layer in expected.items() if "*" in name}
    for name in sorted(set(written) - set(expected)):
        pattern = next((p for p in patterns if fnmatch.fnmatch(name, p)), None)
        if pattern is None:
            problems.append(f"layer {name} written but not declared")
            continue
        info = pyogrio.read_info(path, layer=name)
        for field in patterns[pattern].fields:
            if field.name not in info["fields"]:
                problems.append(f"layer {name}: declared field {field.name} not written")
    for name, layer in expected.items():
        if "*" in name:
            continue
        if name not in written:
            if not layer.optional:
                problems.append(f"declared layer {name} not written")
            continue
        geometry = "Unknown" if layer.geometry_type == "Geometry" else layer.geometry_type
        if written[name] != geometry:
            problems.append(f"layer {name}: written {written[name]}, declared {geometry}")
        info = pyogrio.read_info(path, layer=name)
        dtypes = dict(zip(info["fields"], map(str, info["dtypes"]), strict=True))
        for field in layer.fields:
            field_name = resolve(field.name, parameters)
            if field_name not in dtypes:
                problems.append(f"layer {name}: declared field {field_name} not written")
            elif dtypes[field_name] not in FIELD_DTYPES[field.type]:
                problems.append(f"layer {name}: field {field_name} is {dtypes[field_name]}, "
                                f"declared {field.type}")
    return problems


def test_written_layers_match_the_declarations(demo_run):
    out, _ = demo_run
    checked, problems = set(), []
    for report_path in sorted((out / "reports").glob("*.json")):
        report = json.loads(report_path.read_text())
        alg = get(report["algorithm"])
        for dest in alg.destinations():
            path = report["outputs"].get(dest.name)
            if isinstance(dest, OutputVector) and path:
                problems += [f"{alg.id} {dest.name}: {p}"
                             for p in check_layers(path, dest.layers, report["parameters"])]
                checked.add(alg.id)
    assert not problems, "\n".join(problems)
    vector_writers = {a.id for a in builtin() for d in a.destinations()
                      if isinstance(d, OutputVector)}
    assert vector_writers <= checked, f"not covered by the demo: {vector_writers - checked}"
    for alg in builtin():
        for dest in alg.destinations():
            if isinstance(dest, OutputVector):
                assert dest.layers, f"{alg.id} {dest.name} declares no layers"


def test_layer_declarations_refuse_unknown_types():
    with pytest.raises(ValueError, match="geometry type 'Polygone'"):
        Layer("a", "Polygone")
    with pytest.raises(ValueError, match="type 'float'"):
        Layer("a", "Point Z", [("h", "float")])
    assert Layer("t", None, [("n", "integer")]).describe()["fields"][0] == {
        "name": "n", "type": "integer", "description": ""}


def test_value_outputs_are_typed():
    assert Output("STATS", "x", "dict").type_name == "json"
    with pytest.raises(ValueError, match="not one of"):
        Output("STATS", "x", "table")
    for alg in algorithms():
        for out in alg.spec()["outputs"]:
            assert out["type"] in {"number", "integer", "string", "boolean", "json", "file",
                                   "output_vector", "output_raster", "output_file",
                                   "output_folder"}, alg.id


def test_optional_is_separate_from_default():
    with_default = Number("A", "a", default=2.0)
    assert (with_default.optional, with_default.required) == (False, False)
    may_be_empty = Number("B", "b", optional=True)
    assert (may_be_empty.optional, may_be_empty.required) == (True, False)
    assert Number("C", "c").required
    assert Number("TILE_SIZE", "t", default=512).advanced and not Number("D", "d").advanced
    assert not Number("WORKERS", "w", advanced=False).advanced  # the central rule can be overridden


def test_every_parameter_is_described_and_execution_settings_are_advanced():
    for alg in builtin():
        for p in alg.parameters:
            assert p.description.strip(), f"{alg.id} {p.name} has no description"
            if p.name in ADVANCED_NAMES:
                assert p.advanced, f"{alg.id} {p.name}"


def test_help_all_json_has_every_spec():
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "help", "--all", "--json"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["toolbox_version"] == toolbox.__version__
    ids = [s["id"] for s in doc["algorithms"]]
    assert ids == sorted(ids) and set(ids) == {a.id for a in builtin()}
    keys = {"name", "type", "description", "help", "default", "optional", "required", "advanced",
            "hidden", "expected"}
    for spec in doc["algorithms"]:
        assert {"id", "display_name", "group", "group_id", "short_help", "help", "parameters",
                "outputs"} <= set(spec)
        for p in spec["parameters"]:
            assert keys <= set(p), (spec["id"], p["name"])
    idw = next(s for s in doc["algorithms"] if s["id"] == "dem:idw")
    params = {p["name"]: p for p in idw["parameters"]}
    assert params["TILE_SIZE"]["advanced"] and not params["CELL_SIZE"]["advanced"]
    assert params["Z_FIELD"]["parent"] == "INPUT" and params["INPUT"]["geometry_types"] == ["point"]
    assert "mean" in params["DUPLICATES"]["options"]
    delaunay = next(s for s in doc["algorithms"] if s["id"] == "tin:delaunay")
    layers = delaunay["outputs"][0]["layers"]
    assert [x["name"] for x in layers] == ["triangles", "nodes", "edges"]
    assert layers[0]["geometry_type"] == "Polygon Z" and layers[2]["optional"]


def test_help_texts_speak_to_users():
    for alg in algorithms():
        text = json.dumps(alg.spec())
        for internal in ("shared/docs", "domain.md", "../", "shared/seeds"):
            assert internal not in text, f"{alg.id} help cites {internal}"
    for method in ("dem:plane", "dem:quadratic", "dem:cubic"):
        help_text = get(method).help_text()
        assert "Householder" not in help_text and "Cholesky" in help_text


def test_deprecated_name_is_accepted_with_a_warning(tmp_path):
    import geopandas as gpd
    import shapely

    lines = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"h": [300.0, 310.0]}, geometry=[
        shapely.LineString([(1_688_000, 4_799_500), (1_688_100, 4_799_500)]),
        shapely.LineString([(1_688_000, 4_799_550), (1_688_100, 4_799_560)])],
        crs="EPSG:3003").to_file(lines)  # inside EPSG:3003's area of use (Siena)
    params = {"BREAKLINES": str(lines), "BREAKLINE_Z_FIELD": "h", "OUTPUT": tmp_path / "t.gpkg"}
    with pytest.warns(DeprecationWarning, match="BREAKLINE_Z_FIELD is now called "
                                                "BREAKLINES_Z_FIELD"):
        values = toolbox.validate("tin:delaunay", params)
    assert values["BREAKLINES_Z_FIELD"] == "h"
    with warnings.catch_warnings(), pytest.raises(ParameterError, match="give only"):
        warnings.simplefilter("ignore")
        toolbox.validate("tin:delaunay", params | {"BREAKLINES_Z_FIELD": "h"})


def test_deprecated_name_clash_is_a_spec_error():
    from toolbox.algorithm import Algorithm

    class Clash(Algorithm):
        id = "testing:clash"
        display_name = group = short_help = "x"
        parameters = [Parameter("A", "a", deprecated_names=["B"]), Parameter("B", "b")]

    with pytest.raises(TypeError, match="declared twice"):
        Clash.check_spec()


def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def test_progress_json_lines(plane_dem, tmp_path):
    out = tmp_path / "hs.tif"
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "raster:hillshade",
                           "--progress", "json", "--INPUT", str(plane_dem[0]), "--OUTPUT",
                           str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    events = json_lines(proc.stderr)  # every stderr line is one JSON object
    progress = [e["percent"] for e in events if e["type"] == "progress"]
    assert progress[0] == 0.0 and progress[-1] == 100.0 and progress == sorted(progress)
    assert events[-1] == {"type": "result", "outputs": {"OUTPUT": str(out)}}
    assert json.loads(proc.stdout) == {"OUTPUT": str(out)}


def test_progress_json_reports_errors(plane_dem, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "raster:hillshade",
                           "--progress", "json", "--INPUT", str(plane_dem[0]), "--Z_FACTOR", "-2",
                           "--OUTPUT", str(tmp_path / "hs.tif")],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    error = json.loads(lines[0])
    assert error["type"] == "message" and error["level"] == "error"
    assert "Z_FACTOR" in error["text"]
    assert lines[-1].startswith("toolbox: error:")  # the usual one-line summary closes the stream


def test_vector_layer_flags_pass_through():
    layer = VectorLayer("INPUT", "points", geometry_types=["point"], help="longer text",
                        hidden=True)
    described = layer.describe()
    assert described["help"] == "longer text" and described["hidden"]
    assert described["geometry_types"] == ["point"]
