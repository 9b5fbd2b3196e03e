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
- the first run of every algorithm with numba kernels on a small input, whole process, with a
  cold numba cache (every kernel it meets compiled: a newcomer's first run; target < 3 s) and
  warm (kernels loaded from the cache): ``dem:*`` on the 4,500 points (2 m cells, 150 x 150),
  the others on the demo's sample data with the demo pipeline's parameters (``toolbox demo``);
- ``toolbox warmup`` (compiles every kernel into the per-user cache; ``make venv`` runs it) from
  a cold cache, then ``dem:nearest`` and ``ortho:photo`` after it.

Writes the markdown table to bench/results/startup.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
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
    # Python may write its bytecode caches, as on a user's machine (without them every run
    # compiles the toolbox's sources again)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
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


#: the small input of the dem:* first-run rows (the others use the demo's sample data)
FIRST_RUN_INPUT = {alg: "4,500 points, 150 x 150 cells" for alg in (
    "dem:nearest", "dem:idw", "dem:plane", "dem:quadratic", "dem:cubic", "dem:tin_linear")} | {
    "dem:cross_validate": "4,500 points, every method"}
#: algorithms with numba kernels; the others' first runs are their warm runs. The demo steps
#: give the parameters of those not gridding the bench's points (tin:to_raster reads the TIN
#: that tin:delaunay wrote before it).
DEMO_STEPS = {"tin:delaunay": "tin_delaunay", "tin:to_raster": "tin_to_raster",
              "ortho:photo": "ortho_photo", "orientation:monoplot": "monoplot"}


def demo_inputs(work: Path, points: Path) -> dict[str, str]:
    """The demo's sample data under ``work/demo`` (its variables) and the bench's points."""
    from toolbox.demo.samples import make_samples

    variables = {k: str(v) for k, v in make_samples(work / "demo" / "data").items()}
    return variables | {"out": str(work / "demo"), "points": str(points), "work": str(work)}


def first_runs(variables: dict[str, str]) -> list[tuple[str, dict]]:
    """(algorithm id, parameters) of every first-run row, in running order."""
    from toolbox.demo import demo_pipeline_doc

    grid = {"INPUT": "${points}", "CELL_SIZE": 2}
    runs = [(f"dem:{m}", grid | {"OUTPUT": f"${{work}}/{m}.tif"})
            for m in ("nearest", "idw", "plane", "quadratic", "cubic", "tin_linear")]
    runs.append(("dem:cross_validate", {"INPUT": "${points}",
                                        "OUTPUT": "${work}/cross_validation.json"}))
    steps = {step["name"]: step for step in demo_pipeline_doc()["steps"]}
    outputs: dict[str, str] = {}
    for alg in ("orientation:monoplot", "tin:delaunay", "tin:to_raster", "ortho:photo"):
        step = steps[DEMO_STEPS[alg]]
        assert step["algorithm"] == alg, step
        runs.append((alg, step["params"]))
    resolved = []
    for alg, params in runs:
        values = {k: substitute(v, variables | outputs) for k, v in params.items()}
        step = DEMO_STEPS.get(alg)
        if step and "OUTPUT" in values:
            outputs[f"{step}.OUTPUT"] = values["OUTPUT"]
        resolved.append((alg, values))
    return resolved


def substitute(value, variables: dict[str, str]):
    """``${name}`` / ``${step.OUTPUT}`` replaced (as ``toolbox batch`` does), recursively."""
    if isinstance(value, list):
        return [substitute(v, variables) for v in value]
    if not isinstance(value, str):
        return value
    return re.sub(r"\$\{([^}]+)\}", lambda m: variables[m.group(1)], value)


def cli_args(params: dict) -> list[str]:
    """``toolbox run`` options of a parameter dict (a list repeats the option)."""
    args: list[str] = []
    for key, value in params.items():
        for item in value if isinstance(value, list) else [value]:
            args += [f"--{key}", str(item).lower() if isinstance(item, bool) else str(item)]
    return args


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
        # numba: the newcomer's first run of each algorithm (cold kernel cache), then warm
        variables = demo_inputs(work, points)
        for alg, params in first_runs(variables):
            env = cold_env(work / f"cache-{alg.replace(':', '-')}")
            timed(toolbox + ["list"], env)
            cmd = toolbox + ["run", alg, *cli_args(params), "--overwrite"]
            cold, code, err = timed(cmd, env)
            assert code == 0, f"{alg}: {err[-800:]}"
            what = f"{alg}, first run ({FIRST_RUN_INPUT.get(alg, 'demo sample data')})"
            rows.append((what, "cold numba cache (compiles)", cold))
            rows.append((what, "warm numba cache", median_warm(cmd, env, args.repeat)))
        env = cold_env(work / "cache-warmup")
        warm_up, code, err = timed(toolbox + ["warmup"], env)
        assert code == 0, err[-800:]
        rows.append(("toolbox warmup", "cold numba cache (compiles every kernel)", warm_up))
        for alg, params in first_runs(variables):
            if alg in ("dem:nearest", "ortho:photo"):
                cmd = toolbox + ["run", alg, *cli_args(params), "--overwrite"]
                first, code, err = timed(cmd, env)
                assert code == 0, f"{alg}: {err[-800:]}"
                rows.append((f"{alg}, first run after toolbox warmup", "whole run", first))
    lines = ["## Start-up (`bench/startup_bench.py`)", "", f"{machine_facts()}; {note}.", "",
             "| what | case | wall s | CPU s |", "|---|---|---:|---:|"]
    lines += [f"| {what} | {case} | {wall:.3f} | {cpu:.3f} |" for what, case, (wall, cpu) in rows]
    text = "\n".join(lines) + "\n"
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "startup.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
