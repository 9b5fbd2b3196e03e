"""The command line, through a subprocess as a user runs it."""

from __future__ import annotations

import json

from conftest import run_cli


def test_list_grouped_and_json():
    text = run_cli("list")
    assert text.returncode == 0
    assert "DEM terrain\n  dem:aspect" in text.stdout
    data = json.loads(run_cli("list", "--json").stdout)
    assert {"id": "vector:info"}.items() <= next(a for a in data if a["id"] == "vector:info").items()


def test_help_text_and_json():
    text = run_cli("help", "dem:hillshade")
    assert text.returncode == 0
    assert "--AZIMUTH <number >= 0 and <= 360>  optional (default: 315.0)" in text.stdout
    spec = json.loads(run_cli("help", "dem:hillshade", "--json").stdout)
    azimuth = next(p for p in spec["parameters"] if p["name"] == "AZIMUTH")
    assert (azimuth["min"], azimuth["max"], azimuth["default"]) == (0, 360, 315.0)
    assert spec["outputs"][0]["name"] == "OUTPUT"


def test_run_prints_outputs_as_json(plane_dem, tmp_path):
    out = tmp_path / "hs.tif"
    proc = run_cli("run", "dem:hillshade", "--INPUT", plane_dem[0], f"--OUTPUT={out}",
                   "--ALTITUDE", "30", "--run-report", tmp_path / "r.json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == {"OUTPUT": str(out)}
    assert json.loads((tmp_path / "r.json").read_text())["parameters"]["ALTITUDE"] == 30
    assert proc.stderr == ""  # not a terminal: no progress bar


def test_user_errors_are_one_line_exit_2(plane_dem, tmp_path):
    cases = [
        (("run", "dem:hillshade", "--INPUT", plane_dem[0], "--Z_FACTOR", "-2",
          "--OUTPUT", tmp_path / "a.tif"), "Z_FACTOR must be > 0, got '-2'"),
        (("run", "dem:hillshade", "--INPUT", tmp_path / "missing.tif",
          "--OUTPUT", tmp_path / "a.tif"), "INPUT file"),
        (("run", "vector:info", "--INPUT", plane_dem[0]), "INPUT cannot read"),
        (("run", "nope:nothing"), "no algorithm 'nope:nothing'"),
        (("help", "dem:hilshade"), "did you mean dem:hillshade"),
    ]
    for args, fragment in cases:
        proc = run_cli(*args)
        assert proc.returncode == 2, (args, proc.stderr)
        assert fragment in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_existing_output_refused_then_overwritten(plane_dem, tmp_path):
    out = tmp_path / "hs.tif"
    args = ("run", "dem:hillshade", "--INPUT", plane_dem[0], "--OUTPUT", out)
    assert run_cli(*args).returncode == 0
    proc = run_cli(*args)
    assert proc.returncode == 2 and "--overwrite" in proc.stderr
    assert run_cli(*args, "--overwrite").returncode == 0


def test_lowercase_parameter_names_accepted(plane_dem, tmp_path):
    proc = run_cli("run", "dem:hillshade", "--input", plane_dem[0], "--output",
                   tmp_path / "x.tif", "--overviews", "false")
    assert proc.returncode == 0, proc.stderr


START_UP_PROBE = """
import contextlib, io, json, sys
sys.argv = ["toolbox", *json.loads(sys.argv[1])]
from toolbox.cli import main
with contextlib.redirect_stdout(io.StringIO()) as out:
    try:
        main()
    except SystemExit:
        pass
print(json.dumps({"out": out.getvalue(), "modules": sorted(sys.modules)}))
"""


def test_start_up_commands_import_only_what_they_need(tmp_path):
    """`--version` needs neither the registry nor the runner; `list` and `help` read the cached
    spec index without importing the spec classes, the runner, the package metadata or
    urllib.request (http, ssl).
    Checked by the modules loaded, not by a timing."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}

    def probe(*args: str) -> tuple[str, set[str]]:
        proc = subprocess.run([sys.executable, "-c", START_UP_PROBE, json.dumps(args)],
                              capture_output=True, text=True, env=env, cwd=tmp_path, check=True)
        result = json.loads(proc.stdout.strip().splitlines()[-1])
        return result["out"], set(result["modules"])

    out, modules = probe("--version")
    assert "0.1" in out or "version" in out
    assert not modules & {"toolbox.registry", "toolbox.runner", "toolbox.algorithm",
                          "importlib.metadata", "numpy", "logging", "toolbox.cli.terminal"}
    probe("list")  # builds the spec index in this cache folder
    heavy = {"toolbox.algorithm", "toolbox.parameters", "toolbox.runner", "urllib.request",
             "numpy", "http.client", "importlib.metadata"}
    for args in (("list",), ("help", "dem:idw", "--json")):
        out, modules = probe(*args)
        assert "dem:idw" in out
        assert not modules & heavy, (args, modules & heavy)


def test_a_reader_that_leaves_early_is_no_error(tmp_path):
    """``toolbox list | head -1``: the pipe closes under the listing; no 'internal error'."""
    import subprocess
    import sys
    from pathlib import Path

    toolbox_exe = Path(sys.executable).with_name("toolbox")
    done = subprocess.run(f"'{toolbox_exe}' list | head -1", shell=True, capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert done.stdout.strip() and done.stderr == ""
