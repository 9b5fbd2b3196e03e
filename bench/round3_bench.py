"""Speed round three (#31): before/after and product/peer timings measured side by side in one
sitting, interleaved (A B A B ...), medians of ``--runs`` (default 5), each run its own process.

    .venv/bin/python bench/round3_bench.py read      --work /tmp/r3   # 1M-point read in tin:delaunay
    .venv/bin/python bench/round3_bench.py idw       --work /tmp/r3   # dem:idw duplicate check
    .venv/bin/python bench/round3_bench.py tinwrite  --work /tmp/r3   # tin:delaunay to GeoPackage
    .venv/bin/python bench/round3_bench.py contours  --work /tmp/r3   # carto:contours vs gdal_contour
    .venv/bin/python bench/round3_bench.py startup                    # --version / list / help

``--before PYTHON`` adds the same cases run by another interpreter (a checkout of the previous
main with its own venv) to get before/after ratios in the same sitting. A case's time is the
whole process's wall time, or the in-process seconds it prints as its last stdout line
(``{"seconds": ...}``). Prints a markdown table; the machine's load is stated with it.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from benchlib import load_note, machine_facts  # noqa: E402


def run_once(cmd: list[str], env: dict | None = None) -> float:
    """Seconds of one run: the in-process figure the command prints, else the wall time."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-2000:]}")
    lines = proc.stdout.strip().splitlines()
    if lines and lines[-1].startswith('{"seconds"'):
        return float(json.loads(lines[-1])["seconds"])
    return wall


def interleaved(cases: dict[str, list[str]], runs: int, env: dict | None = None
                ) -> dict[str, list[float]]:
    """Every case once per round, ``runs`` rounds (after one untimed warm-up round)."""
    times: dict[str, list[float]] = {name: [] for name in cases}
    for round_ in range(runs + 1):
        for name, cmd in cases.items():
            seconds = run_once(cmd, env)
            if round_:
                times[name].append(seconds)
    return times


def table(times: dict[str, list[float]], reference: str, header: str) -> str:
    ref = statistics.median(times[reference])
    rows = [f"| {header} | median s | min-max s | {reference} / this |", "|---|---:|---:|---:|"]
    for name, values in times.items():
        med = statistics.median(values)
        rows.append(f"| {name} | {med:.3f} | {min(values):.3f}-{max(values):.3f} | "
                    f"{ref / med:.2f}x |")
    return "\n".join(rows)


def in_process(python: str, code: str) -> list[str]:
    """A command timing ``code``'s last statement block; ``code`` sets ``seconds``."""
    return [python, "-c", code + "\nimport json; print(json.dumps({'seconds': seconds}))"]


# -- sections --------------------------------------------------------------------------------------
def points_file(work: Path, n: int) -> Path:
    folder = work / f"points_{n}"
    if not (folder / "points.gpkg").exists():
        import tin_bench

        folder.mkdir(parents=True, exist_ok=True)
        tin_bench.make_data(folder, n)
    return folder / "points.gpkg"


READ_GENERAL = """
import time
t0 = time.perf_counter()
from toolbox.io.vector import points_xyz, read_vector
frame = read_vector({path!r}, name="INPUT")
frame = frame[frame.geometry.notna() & ~frame.geometry.is_empty]
xyz = points_xyz(frame, None, name="INPUT")
seconds = time.perf_counter() - t0
"""
READ_FAST = """
import time
t0 = time.perf_counter()
from toolbox.io.vector import read_points_xyz
xyz = read_points_xyz({path!r}, None, name="INPUT")
seconds = time.perf_counter() - t0
"""


def section_read(args) -> str:
    path = points_file(args.work, 1_000_000)
    py = sys.executable
    cases = {"general reader (tin:delaunay before: GeoDataFrame + points_xyz)":
             in_process(py, READ_GENERAL.format(path=str(path))),
             "fast reader (dem:idw, and tin:delaunay now)":
             in_process(py, READ_FAST.format(path=str(path)))}
    times = interleaved(cases, args.runs)
    return ("1,000,000 PointZ in a GeoPackage, read to an (N, 3) array, in process (imports "
            "included)\n\n" + table(times, next(iter(cases)), "reader"))


SECTIONS = {"read": section_read}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("section", choices=sorted(SECTIONS))
    parser.add_argument("--work", type=Path, default=Path("/tmp/round3_bench"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--before", help="python of the previous version (before/after rows)")
    args = parser.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    head = f"{machine_facts()}. {load_note()}; load average {os.getloadavg()[0]:.1f}."
    body = SECTIONS[args.section](args)
    print(f"### {args.section}\n\n{head}\n\n{body}\n")


if __name__ == "__main__":
    main()
