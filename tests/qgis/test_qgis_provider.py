"""The QGIS Processing provider, tested with the real QGIS (Debian's 3.22 here and in CI).

- the plugin's CLI helpers on their own (no QGIS needed);
- the provider loaded in PyQGIS: every toolbox spec became an algorithm with the right parameter
  types, optional and advanced flags;
- for one documented example of every algorithm group, the same run through the toolbox CLI,
  through ``processing.run`` and (for two of them) through ``qgis_process run``: the outputs hold
  identical values (rasters cell by cell, vector layers feature by feature).

The QGIS part is skipped, loudly, only where QGIS cannot be imported (.ci/run installs it).
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PLUGIN = ROOT / "qgis_plugin"
sys.path.insert(0, str(PLUGIN))
from photogrammetry_toolbox import toolbox_cli  # noqa: E402

SYSTEM_PYTHON = "/usr/bin/python3"
QGIS_TYPES = {"number": "number", "integer": "number", "boolean": "boolean", "enum": "enum",
              "crs": "crs", "extent": "extent", "file": "file", "vector": "source",
              "raster": "raster", "multiple": "multilayer", "field": "field",
              "output_raster": "rasterDestination", "output_vector": "fileDestination",
              "output_file": "fileDestination", "output_folder": "folderDestination",
              "folder": "file", "string": "string"}


def toolbox_executable() -> str:
    return str(Path(sys.executable).with_name("toolbox"))


def qgis_available() -> bool:
    if not os.path.exists(SYSTEM_PYTHON):
        return False
    done = subprocess.run([SYSTEM_PYTHON, "-c", "import qgis.core"], capture_output=True)
    return done.returncode == 0


needs_qgis = pytest.mark.skipif(
    not qgis_available(),
    reason="!!! QGIS NOT INSTALLED: the QGIS provider is NOT tested (apt-get install qgis "
           "python3-qgis qgis-providers; .ci/run does it) !!!")


# -- the plugin's helpers, no QGIS ----------------------------------------------------------------
def test_extent_orders_converted_both_ways():
    assert toolbox_cli.qgis_extent_to_toolbox("1,3,2,4 [EPSG:3003]") == "1,2,3,4 [EPSG:3003]"
    assert toolbox_cli.qgis_extent_to_toolbox("1,3,2,4") == "1,2,3,4"
    assert toolbox_cli.toolbox_extent_to_qgis("1,2,3,4 EPSG:3003") == "1,3,2,4 [EPSG:3003]"
    assert toolbox_cli.toolbox_extent_to_qgis("1,2,3,4 [EPSG:3003]") == "1,3,2,4 [EPSG:3003]"


def test_command_line_and_progress_lines():
    args = toolbox_cli.command_line("tb", "dem:idw", {"INPUT": "a.gpkg", "POWER": "2.0",
                                                       "MASK": None, "FLAG": True,
                                                       "LAYERS": ["a.tif", "b.tif"]})
    assert args == ["tb", "run", "dem:idw", "--progress", "json", "--overwrite", "--INPUT",
                    "a.gpkg", "--POWER", "2.0", "--FLAG", "true", "--LAYERS", "a.tif",
                    "--LAYERS", "b.tif"]
    assert toolbox_cli.parse_progress('{"type": "progress", "percent": 42.0}')["percent"] == 42
    assert toolbox_cli.parse_progress("plain text") is None
    assert toolbox_cli.qgis_id("dem:idw") == "dem_idw"


def test_executable_not_found_is_a_clear_message(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv(toolbox_cli.ENV_VARIABLE, raising=False)
    monkeypatch.setattr(toolbox_cli, "__file__", str(tmp_path / "x" / "y" / "toolbox_cli.py"))
    with pytest.raises(toolbox_cli.ToolboxNotFound, match="Processing > Options"):
        toolbox_cli.find_executable(str(tmp_path / "nothing"))


def test_dialog_help_is_clean_text_and_labels_are_short():
    raw = ("Grid with ``CELL_SIZE`` cells (see :func:`toolbox.raster.engine.process_raster` and "
           ":class:`~toolbox.io.grid.GridSpec`); the `TEMPLATE` wins, **never** silently.\n\n"
           "    Second paragraph,\n    wrapped.")
    assert toolbox_cli.clean_help(raw) == (
        "Grid with CELL_SIZE cells (see process_raster and GridSpec); the TEMPLATE wins, never "
        "silently.<br><br>Second paragraph, wrapped.")
    assert toolbox_cli.short_label("CELL_SIZE", "cell size, CRS units (not needed with "
                                   "TEMPLATE)") == "Cell size [CELL_SIZE]"
    assert toolbox_cli.short_label("POWER", "weight exponent p in 1/d^p (thesis eq. 45: 1)") \
        == "Weight exponent p in 1/d^p [POWER]"
    label = toolbox_cli.short_label("X", "a" * 30 + " " + "b" * 30)
    assert label.endswith("… [X]") and len(label) < 60


def test_kernels_are_compiled_once_per_version_in_the_background(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    fake = tmp_path / "toolbox"
    fake.write_text(f"#!/bin/sh\necho \"$@\" >> {tmp_path / 'calls.txt'}\n")
    fake.chmod(0o755)
    assert toolbox_cli.start_warmup(str(fake), "9.9") is True
    assert toolbox_cli.start_warmup(str(fake), "9.9") is False  # once per version
    import time

    calls = tmp_path / "calls.txt"
    for _ in range(300):  # the shell creates the file before echo writes into it
        if calls.exists() and calls.read_text().strip():
            break
        time.sleep(0.1)
    assert (tmp_path / "calls.txt").read_text().split() == ["-q", "warmup"]
    assert toolbox_cli.start_warmup(str(fake), "10.0") is True  # a new version compiles again


def test_specs_loaded_in_one_call_and_cached(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    specs = toolbox_cli.load_specs(toolbox_executable())
    import toolbox

    assert {s["id"] for s in specs} == {a.id for a in toolbox.algorithms()
                                        if a.__module__.startswith("algorithms.")}
    cached = list((tmp_path / "photogrammetry-toolbox" / "qgis").glob("specs-*.json"))
    assert len(cached) == 1
    calls = []
    monkeypatch.setattr(toolbox_cli, "_run", lambda args, timeout=120: calls.append(args) or
                        "toolbox, version " + toolbox.__version__)
    assert toolbox_cli.load_specs("tb") == specs and calls == [["tb", "--version"]]


# -- the real QGIS ----------------------------------------------------------------------------------
def group_cases() -> list[tuple[str, list[str]]]:
    """(algorithm id, CLI arguments) of the first documented example of every group."""
    sys.path.insert(0, str(ROOT / "tests" / "toolbox"))
    from test_docs_examples import COMMAND, documented_commands

    seen, cases = set(), []
    for _, command in documented_commands():
        args = shlex.split(COMMAND.sub(r"\1", command))
        if args[0] != "run" or "--scheduler" in command.lower():
            continue
        group = args[1].split(":")[0]
        if group not in seen:
            seen.add(group)
            cases.append((args[1], args[2:]))
    return cases


def _pairs(tokens: list[str]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    i = 0
    while i < len(tokens):
        name = tokens[i][2:].upper()
        if i + 1 < len(tokens) and not tokens[i + 1].startswith("--"):
            out.setdefault(name, []).append(tokens[i + 1])
            i += 2
        else:
            out.setdefault(name, []).append("true")
            i += 1
    return out


def prepared(spec: dict, tokens: list[str], folder: Path, cwd: Path):
    """CLI args and QGIS parameters of one case, destinations redirected into ``folder``."""
    values = _pairs([t for t in tokens if t != "--overwrite"])
    types = {p["name"]: p for p in spec["parameters"]}
    cli, qgis = {}, {}
    for name, items in values.items():
        if name not in types:  # a CLI option (--run-report, --quiet...), not a parameter
            continue
        p = types[name]
        kind = p["type"]
        if kind.startswith("output_"):
            items = [str(folder / Path(items[0]).name)]
        elif kind in ("vector", "raster", "file", "folder", "multiple") or (
                kind == "string" and (cwd / items[0]).exists()):  # a folder given as text
            items = [str(cwd / i) if not os.path.isabs(i.split("|")[0]) else i for i in items]
        cli[name] = items
        if kind == "enum":
            qgis[name] = list(p["options"]).index(items[0])
        elif kind == "extent":
            qgis[name] = toolbox_cli.toolbox_extent_to_qgis(items[0])
        elif kind == "multiple":
            qgis[name] = items
        else:
            qgis[name] = items[0]
    return cli, qgis


def same_outputs(a: Path, b: Path) -> None:
    """Identical values: rasters cell by cell, vector layers feature by feature, text files."""
    for fa in sorted(a.iterdir()):
        fb = b / fa.name
        assert fb.exists(), f"{fa.name} missing from the QGIS run"
        if fa.suffix.lower() in (".tif", ".tiff"):
            import rasterio

            with rasterio.open(fa) as ra, rasterio.open(fb) as rb:
                assert ra.crs == rb.crs and ra.transform == rb.transform
                assert np.array_equal(ra.read(), rb.read(), equal_nan=True)
        elif fa.suffix.lower() == ".gpkg":
            import pyogrio

            layers = [name for name, _ in pyogrio.list_layers(fa)]
            assert layers == [name for name, _ in pyogrio.list_layers(fb)]
            for layer in layers:
                da = pyogrio.read_dataframe(fa, layer=layer)
                db = pyogrio.read_dataframe(fb, layer=layer)
                assert list(da.columns) == list(db.columns) and len(da) == len(db)
                if "geometry" in da:
                    assert all(x.equals_exact(y, 1e-9) for x, y in
                               zip(da.geometry, db.geometry, strict=True) if x is not None)
        elif fa.suffix.lower() == ".json":
            assert json.loads(fa.read_text()).keys() == json.loads(fb.read_text()).keys()


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory):
    from toolbox.demo import run_demo

    base = tmp_path_factory.mktemp("qgis_demo")
    run_demo(base / "demo_out")
    shutil.copytree(ROOT / "examples", base / "examples")
    return base


@needs_qgis
def test_provider_in_pyqgis_and_processing_run_equals_cli(demo_out, tmp_path):
    import toolbox

    specs = {s["id"]: s for s in toolbox_cli.load_specs(toolbox_executable(), use_cache=False)}
    cases, runs = [], []
    for alg_id, tokens in group_cases():
        cli, qgis = prepared(specs[alg_id], tokens, tmp_path / "qgis" / alg_id.replace(":", "_"),
                             demo_out)
        (tmp_path / "qgis" / alg_id.replace(":", "_")).mkdir(parents=True)
        cli_dir = tmp_path / "cli" / alg_id.replace(":", "_")
        cli_dir.mkdir(parents=True)
        cli_args, _ = prepared(specs[alg_id], tokens, cli_dir, demo_out)
        cases.append({"id": alg_id, "qgis": qgis})
        runs.append((alg_id, cli_args, cli_dir))
    for alg_id, cli_args, _ in runs:
        toolbox.run(alg_id, {k: v if len(v) > 1 else v[0] for k, v in cli_args.items()},
                    overwrite=True)
    (tmp_path / "cases.json").write_text(json.dumps(cases))
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "cache"), QT_QPA_PLATFORM="offscreen",
               PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP="1")
    done = subprocess.run([SYSTEM_PYTHON, str(ROOT / "tests" / "qgis" / "qgis_check.py"),
                           str(PLUGIN), toolbox_executable(), str(tmp_path / "cases.json")],
                          capture_output=True, text=True, timeout=900, env=env, cwd=demo_out)
    line = [ln for ln in done.stdout.splitlines() if ln.startswith("QGIS_CHECK ")]
    assert line, f"PyQGIS check did not report:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    report = json.loads(line[0][len("QGIS_CHECK "):])
    assert report["problem"] is None
    # every spec became an algorithm with the right parameter types and flags
    assert set(report["algorithms"]) == {toolbox_cli.qgis_id(i) for i in specs}
    for alg_id, spec in specs.items():
        alg = report["algorithms"][toolbox_cli.qgis_id(alg_id)]
        assert alg["group"] == spec["group"] and alg["help"]
        assert not any(m in alg["help_text"] for m in ("``", ":func:", ":class:", ":mod:"))
        for p in spec["parameters"]:
            got = alg["parameters"][p["name"]]
            assert got["label"].endswith(f"[{p['name']}]")
            assert len(got["label"]) - len(p["name"]) - 3 <= 48  # a short first clause
            if p["type"] == "extent":
                assert "xmin, xmax, ymin, ymax" in got["help"]
            assert got["type"] == QGIS_TYPES.get(p["type"], "string"), (alg_id, p["name"])
            assert got["optional"] == bool(p.get("optional")), (alg_id, p["name"])
            assert got["advanced"] == bool(p.get("advanced")), (alg_id, p["name"])
    assert report["raster_formats"] == ["tif"] and report["vector_formats"] == ["gpkg"]
    failed = {k: v["error"] for k, v in report["runs"].items() if not v["ok"]}
    assert not failed, failed
    assert len(report["runs"]) == len(runs) >= 5
    for alg_id, _, cli_dir in runs:
        same_outputs(cli_dir, tmp_path / "qgis" / alg_id.replace(":", "_"))


@needs_qgis
def test_qgis_process_runs_the_same_algorithm(demo_out, tmp_path):
    """``qgis_process run`` (the Debian wrapper passes a flag 3.22 refuses: use the .bin), with
    the plugin enabled in a fresh profile, gives the CLI's values."""
    import toolbox

    binary = shutil.which("qgis_process.bin") or shutil.which("qgis_process")
    assert binary, "qgis_process is missing although PyQGIS is installed"
    env = dict(os.environ, HOME=str(tmp_path / "home"), QT_QPA_PLATFORM="offscreen",
               QGIS_PLUGINPATH=str(PLUGIN), PHOTOGRAMMETRY_TOOLBOX=toolbox_executable(),
               XDG_CACHE_HOME=str(tmp_path / "cache"), PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP="1")
    enable = subprocess.run([binary, "plugins", "enable", "photogrammetry_toolbox"],
                            capture_output=True, text=True, env=env, timeout=300)
    assert enable.returncode == 0, enable.stdout + enable.stderr
    specs = {s["id"]: s for s in toolbox_cli.load_specs(toolbox_executable(), use_cache=False)}
    for alg_id, tokens in group_cases()[:2]:
        name = alg_id.replace(":", "_")
        qdir, cdir = tmp_path / "qp" / name, tmp_path / "cli" / name
        qdir.mkdir(parents=True)
        cdir.mkdir(parents=True)
        _, qgis = prepared(specs[alg_id], tokens, qdir, demo_out)
        cli, _ = prepared(specs[alg_id], tokens, cdir, demo_out)
        toolbox.run(alg_id, {k: v if len(v) > 1 else v[0] for k, v in cli.items()})
        args = [binary, "run", f"{toolbox_cli.PROVIDER_ID}:{name}", "--"]
        args += [f"{k}={v}" for k, v in qgis.items()]
        done = subprocess.run(args, capture_output=True, text=True, env=env, timeout=600,
                              cwd=demo_out)
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        same_outputs(cdir, qdir)


@needs_qgis
def test_qgis_process_says_when_the_toolbox_is_not_configured(tmp_path):
    """The plugin enabled in a fresh profile, copied away from the checkout (whose .venv it would
    find), no toolbox on PATH and a wrong PHOTOGRAMMETRY_TOOLBOX: ``qgis_process run`` prints
    the provider's message naming what it tried and where to set the path."""
    binary = shutil.which("qgis_process.bin") or shutil.which("qgis_process")
    plugins = tmp_path / "plugins"
    shutil.copytree(PLUGIN / "photogrammetry_toolbox", plugins / "photogrammetry_toolbox")
    env = {"HOME": str(tmp_path / "home"), "PATH": "/usr/bin:/bin", "QT_QPA_PLATFORM": "offscreen",
           "QGIS_PLUGINPATH": str(plugins), "PHOTOGRAMMETRY_TOOLBOX": str(tmp_path / "no" / "tb"),
           "XDG_CACHE_HOME": str(tmp_path / "cache"), "PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP": "1"}
    enable = subprocess.run([binary, "plugins", "enable", "photogrammetry_toolbox"],
                            capture_output=True, text=True, env=env, timeout=300)
    assert enable.returncode == 0, enable.stdout + enable.stderr
    done = subprocess.run([binary, "run", f"{toolbox_cli.PROVIDER_ID}:dem_idw"],
                          capture_output=True, text=True, env=env, timeout=300)
    said = done.stdout + done.stderr
    assert done.returncode != 0
    assert "executable was not found" in said and str(tmp_path / "no" / "tb") in said, said
    assert "Processing > Options > Providers" in said and "PHOTOGRAMMETRY_TOOLBOX" in said


LOAD_SCRIPT = r"""
import json, os, sys
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, sys.argv[1])
sys.path.insert(0, "/usr/share/qgis/python/plugins")
from qgis.core import QgsApplication, QgsProcessingContext, QgsProject
app = QgsApplication([], False); app.initQgis()
from photogrammetry_toolbox.algorithm import ToolboxAlgorithm
spec = {"id": "attribution:apply", "display_name": "x", "group": "g", "parameters": [],
        "outputs": [], "short_help": "", "help": ""}
alg = ToolboxAlgorithm(spec, "toolbox")
context = QgsProcessingContext(); context.setProject(QgsProject.instance())
alg._load_layers({"name": "OUTPUT"}, sys.argv[2], context)
print("LOADED " + json.dumps(sorted(context.layersToLoadOnCompletion())), flush=True)
os._exit(0)
"""


@needs_qgis
def test_layer_styles_table_is_not_loaded_as_a_layer(tmp_path):
    """A GeoPackage with a ``layer_styles`` table (attribution:apply's): on completion the
    provider loads its coded layers, not the styles table (QGIS reads it as the styles)."""
    import toolbox
    from toolbox.demo.samples import restitution

    files = restitution.make(tmp_path, {})
    out = tmp_path / "coded.gpkg"
    toolbox.run("attribution:apply", {
        "INPUT": [files["restitution_model_12"], files["restitution_model_13"]],
        "PARAMETERS": files["restitution_parameters"], "CODES": files["restitution_codes"],
        "COLOURS": files["restitution_colours"], "CRS": "EPSG:3003", "OUTPUT": out})
    script = tmp_path / "load.py"
    script.write_text(LOAD_SCRIPT)
    done = subprocess.run([SYSTEM_PYTHON, str(script), str(PLUGIN), str(out)],
                          capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, HOME=str(tmp_path), QT_QPA_PLATFORM="offscreen"))
    line = [ln for ln in done.stdout.splitlines() if ln.startswith("LOADED ")]
    assert line, done.stdout[-2000:] + done.stderr[-2000:]
    loaded = {p.rsplit("layername=", 1)[1] for p in json.loads(line[0][len("LOADED "):])}
    import pyogrio

    in_file = {name for name, _ in pyogrio.list_layers(out)}
    assert "layer_styles" in in_file and "FAB01002" in loaded
    assert loaded == in_file - {"layer_styles"}
