"""Start-up benchmark: what a batch script or a GUI pays on every call, cold and warm.

    .venv/bin/python bench/startup_bench.py            # 5 repeats per row
    .venv/bin/python bench/startup_bench.py --repeat 3

Rows (whole processes, wall time, median of the repeats; "cold" = a fresh per-user cache folder,
``XDG_CACHE_HOME`` and ``NUMBA_CACHE_DIR`` pointing at an empty temporary folder; "warm" = the same
folder on the next call):

- ``toolbox list``, ``toolbox help dem:idw``, ``toolbox help --all --json``: cold (the spec index
  is built by importing every algorithm) and warm (read from the index);
- ``toolbox run ID`` start-up for every algorithm: the CLI, the registry and the algorithm's module,
  up to the parameter check (run without parameters, it stops there with exit code 2);
- ``toolbox run vector:info`` / ``dem:nearest`` up to the moment ``process()`` would start (the
  runner's ``validate`` returns, inputs opened): a probe replaces ``validate`` and exits there;
- the first run of ``dem:nearest`` on 4,500 points (2 m cells), whole process, with a cold numba
  cache (every kernel compiled) and warm (kernels loaded from the cache).

Writes the markdown table to bench/results/startup.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PY = sys.executable
X0, Y0 = 1_687_000.0, 4_798_500.0

# validate -> report the time, then stop before process() (os._exit: no teardown in the timing)
PROBE = """
import os, sys, time
import toolbox.runner as runner
_validate = runner.validate
def validate(*args, **kwargs):
    values = _validate(*args, **kwargs)
    sys.stdout.flush()
    os._exit(0)
runner.validate = validate
from toolbox.cli import main
main(sys.argv[1:])
"""


def timed(cmd: list[str], env: dict[str, str]) -> tuple[tuple[float, float], int, str]:
    """((wall s, CPU s of the child: user + system), exit code, stderr). CPU time hardly moves
    when other work shares the machine; wall time does."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return (wall, cpu), proc.returncode, proc.stderr


def median_warm(cmd: list[str], env: dict[str, str], repeat: int) -> tuple[float, float]:
    walls, cpus = [], []
    for _ in range(repeat):
        (wall, cpu), code, err = timed(cmd, env)
        if code not in (0, 2):
            raise RuntimeError(f"{' '.join(cmd)} failed: {err[-500:]}")
        walls.append(wall)
        cpus.append(cpu)
    return statistics.median(walls), statistics.median(cpus)


def cold_env(folder: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["XDG_CACHE_HOME"] = str(folder)
    env["NUMBA_CACHE_DIR"] = str(folder / "numba")
    return env


def make_points(path: Path, n: int = 4500) -> None:
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(7)
    x = rng.uniform(X0, X0 + 300.0, n)
    y = rng.uniform(Y0, Y0 + 300.0, n)
    z = 300.0 + 0.05 * (x - X0) + 10.0 * np.sin((y - Y0) / 40.0)
    gpd.GeoDataFrame(geometry=shapely.points(x, y, z), crs="EPSG:3003").to_file(path, layer="pts")


def algorithm_ids() -> list[str]:
    out = subprocess.run([PY, "-m", "toolbox.cli", "list", "--json"], capture_output=True,
                         text=True, check=True, cwd=ROOT).stdout
    return [a["id"] for a in json.loads(out)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    note = load_note()
    rows: list[tuple[str, str, tuple[float, float]]] = []
    toolbox = [PY, "-m", "toolbox.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        # list / help: cold (fresh cache folder) then warm
        for name, cmd in [("toolbox list", ["list"]), ("toolbox help dem:idw", ["help", "dem:idw"]),
                          ("toolbox help --all --json", ["help", "--all", "--json"])]:
            env = cold_env(work / f"cache-{len(rows)}")
            cold, code, err = timed(toolbox + cmd, env)
            assert code == 0, err
            rows.append((name, "cold (index built)", cold))
            rows.append((name, "warm", median_warm(toolbox + cmd, env, args.repeat)))
        env = cold_env(work / "cache-run")
        timed(toolbox + ["list"], env)
        starts = {}
        for alg in algorithm_ids():
            starts[alg] = median_warm(toolbox + ["run", alg], env, args.repeat)
        for alg, seconds in starts.items():
            rows.append((f"toolbox run {alg}", "start-up to the parameter check", seconds))
        points = work / "points.gpkg"
        make_points(points)
        probe = [PY, "-c", PROBE]
        for alg, params in [("vector:info", ["--INPUT", str(points), "--OUTPUT",
                                             str(work / "info.json")]),
                            ("dem:nearest", ["--INPUT", str(points), "--CELL_SIZE", "2",
                                             "--OUTPUT", str(work / "dem.tif")])]:
            rows.append((f"toolbox run {alg}", "start-up to process() (inputs opened)",
                         median_warm(probe + ["run", alg, *params], env, args.repeat)))
        # numba: the newcomer's first run (cold kernel cache), then the next one (warm)
        env = cold_env(work / "cache-numba")
        timed(toolbox + ["list"], env)
        nearest = toolbox + ["run", "dem:nearest", "--INPUT", str(points), "--CELL_SIZE", "2",
                             "--OUTPUT", str(work / "n.tif"), "--overwrite"]
        cold, code, err = timed(nearest, env)
        assert code == 0, err
        rows.append(("dem:nearest, 4,500 points, whole run", "cold numba cache (compiles)", cold))
        rows.append(("dem:nearest, 4,500 points, whole run", "warm numba cache",
                     median_warm(nearest, env, args.repeat)))
    lines = ["## Start-up (`bench/startup_bench.py`)", "", f"{machine_facts()}; {note}.", "",
             "| what | case | wall s | CPU s |", "|---|---|---:|---:|"]
    lines += [f"| {what} | {case} | {wall:.3f} | {cpu:.3f} |" for what, case, (wall, cpu) in rows]
    text = "\n".join(lines) + "\n"
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "startup.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
