"""The command line, through a subprocess as a user runs it."""

from __future__ import annotations

import json

import pytest
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
from toolbox.cli import console  # the console script's entry point
with contextlib.redirect_stdout(io.StringIO()) as out:
    try:
        code = console()
    except SystemExit as exc:
        code = exc.code
print(json.dumps({"out": out.getvalue(), "code": code, "modules": sorted(sys.modules)}))
"""


def test_start_up_commands_import_only_what_they_need(tmp_path):
    """`--version` needs neither the registry nor the runner; `list` and `help` read the cached
    spec index without click, logging, the registry, the spec classes, the runner, the package
    metadata or urllib.request (http, ssl).
    Checked by the modules loaded, not by a timing."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}

    def probe(*args: str) -> tuple[str, set[str]]:
        proc = subprocess.run([sys.executable, "-c", START_UP_PROBE, json.dumps(args)],
                              capture_output=True, text=True, env=env, cwd=tmp_path, check=True)
        result = json.loads(proc.stdout.strip().splitlines()[-1])
        assert result["code"] in (0, None), result
        return result["out"], set(result["modules"])

    out, modules = probe("--version")
    assert out == "toolbox, version 0.1.0\n"
    assert not modules & {"toolbox.registry", "toolbox.runner", "toolbox.algorithm", "click",
                          "importlib.metadata", "numpy", "logging", "toolbox.cli.terminal"}
    out, modules = probe("list")  # builds the spec index in this cache folder: click's command
    assert "click" in modules and "dem:idw" in out
    heavy = {"toolbox.algorithm", "toolbox.parameters", "toolbox.runner", "urllib.request",
             "numpy", "http.client", "importlib.metadata", "click", "logging", "toolbox.registry"}
    for args in (("list",), ("help", "dem:idw", "--json"), ("help", "--all", "--json")):
        out, modules = probe(*args)
        assert "dem:idw" in out
        assert not modules & heavy, (args, modules & heavy)


CLICK_APP = "import sys; from toolbox.cli import main; main(sys.argv[1:], prog_name='toolbox')"


@pytest.mark.parametrize(("args", "code"), [
    (("--version",), 0), (("list",), 0), (("list", "--json"), 0), (("help", "dem:idw"), 0),
    (("help", "--json", "dem:hillshade"), 0), (("help", "raster:hillshade"), 0),  # an alias
    (("help", "--all"), 0), (("help", "--all", "--json"), 0),
    (("help", "dem:hilshade"), 2), (("help",), 2), (("help", "dem:idw", "--all"), 2),
    (("list", "--jsn"), 2)])
def test_quick_answers_are_the_click_commands_answers(args, code, tmp_path):
    """The console script answers the plain `list` / `help` forms from a fresh index, without
    click: the same stdout, stderr and exit code as the click application (which the stale or
    missing index, the other forms and the errors go to)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}

    def run(*cmd: str, given: tuple[str, ...] = args) -> tuple[int, str, str]:
        proc = subprocess.run([sys.executable, *cmd, *given], capture_output=True, text=True,
                              env=env, cwd=tmp_path, timeout=300)
        return proc.returncode, proc.stdout, proc.stderr

    cold = run("-m", "toolbox.cli")  # no index yet: the click application
    assert run("-m", "toolbox.cli", given=("list",))[0] == 0  # builds the index
    assert list(tmp_path.glob("photogrammetry-toolbox/specs-*"))
    quick = run("-m", "toolbox.cli")
    clicked = run("-c", CLICK_APP)
    assert cold == quick == clicked
    assert quick[0] == code


def test_a_stale_or_damaged_index_is_rebuilt(tmp_path):
    """A spec index that no longer matches the sources, or that cannot be read, is not used: the
    click application rebuilds it (same answer)."""
    import os
    import subprocess
    import sys

    from toolbox import spec_cache

    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    fresh = subprocess.run([sys.executable, "-m", "toolbox.cli", "list", "--json"], env=env,
                           capture_output=True, text=True, cwd=tmp_path, check=True)
    index = next(tmp_path.glob("photogrammetry-toolbox/specs-*"))
    index.write_bytes(b"\x00 not an index")
    assert spec_cache.read_index(index, "anything") is None
    again = subprocess.run([sys.executable, "-m", "toolbox.cli", "list", "--json"], env=env,
                           capture_output=True, text=True, cwd=tmp_path, check=True)
    assert again.stdout == fresh.stdout and again.stderr == ""
    assert index.read_bytes() != b"\x00 not an index"


def test_a_reader_that_leaves_early_is_no_error(tmp_path):
    """``toolbox list | head -1``: the pipe closes under the listing; no 'internal error'."""
    import subprocess
    import sys
    from pathlib import Path

    toolbox_exe = Path(sys.executable).with_name("toolbox")
    done = subprocess.run(f"'{toolbox_exe}' list | head -1", shell=True, capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert done.stdout.strip() and done.stderr == ""
