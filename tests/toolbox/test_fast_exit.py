"""The ``toolbox`` script ends its process without the interpreter's teardown
(:func:`toolbox.cli.script`, :func:`~toolbox.cli.exit_now`): exit status, exit functions,
logging and standard streams as with a normal exit; a profiler still gets to write its report."""

from __future__ import annotations

import os
import subprocess
import sys

SCRIPT = """
import atexit, sys
atexit.register(lambda: print("exit function ran", flush=True))
sys.argv = ["toolbox", *sys.argv[1:]]
from toolbox.cli import script
script()
"""


def run_script(tmp_path, *args, env=None):
    script = tmp_path / "entry.py"
    script.write_text(SCRIPT)
    return subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300, env=os.environ | (env or {}))


def points_file(tmp_path):
    import geopandas as gpd
    from shapely.geometry import Point

    path = tmp_path / "points.gpkg"
    gpd.GeoDataFrame({"z": [1.0, 2.0]}, geometry=[Point(0, 0), Point(1, 1)],
                     crs="EPSG:3003").to_file(path)
    return path


def test_success_keeps_status_output_and_exit_functions(tmp_path):
    proc = run_script(tmp_path, "run", "vector:info", "--INPUT", str(points_file(tmp_path)),
                      "--OUTPUT", str(tmp_path / "info.json"))
    assert proc.returncode == 0, proc.stderr
    assert "exit function ran" in proc.stdout
    assert (tmp_path / "info.json").read_text().strip().endswith("}")


def test_user_error_keeps_status_and_one_line(tmp_path):
    proc = run_script(tmp_path, "run", "vector:info", "--INPUT", str(tmp_path / "none.gpkg"))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "INPUT" in proc.stderr
    assert "exit function ran" in proc.stdout


def test_normal_exit_under_a_profiler(tmp_path):
    """cProfile writes its file after the script returns: the fast exit steps aside."""
    script = tmp_path / "entry.py"
    script.write_text(SCRIPT)
    stats = tmp_path / "run.prof"
    proc = subprocess.run([sys.executable, "-m", "cProfile", "-o", str(stats), str(script),
                           "run", "vector:info", "--INPUT", str(points_file(tmp_path))],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert stats.stat().st_size > 1000


def test_exit_now_steps_aside_when_asked(monkeypatch):
    """TOOLBOX_FULL_EXIT (and a tracer: pytest's coverage or a debugger) keep the normal exit:
    exit_now returns instead of ending the process."""
    from toolbox.cli import exit_now

    monkeypatch.setenv("TOOLBOX_FULL_EXIT", "1")
    assert exit_now(0) is None
    monkeypatch.delenv("TOOLBOX_FULL_EXIT")
    previous = sys.gettrace()
    sys.settrace(lambda *a: None)
    try:
        assert exit_now(0) is None
    finally:
        sys.settrace(previous)
