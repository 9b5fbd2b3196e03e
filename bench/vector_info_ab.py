"""``toolbox run vector:info`` of two source trees, whole process, interleaved A/B against
``gdalinfo --version`` and ``ogrinfo -so -al``: medians of wall and CPU (user + system) seconds.

    .venv/bin/python bench/vector_info_ab.py --old /path/to/old/tree --new . [--runs 21]
        [--input file.gpkg]

Each tree is put first on ``PYTHONPATH`` (a tree's own ``..._meta`` folder beside it, holding
the package's metadata pointing at it, is added when present) and given its own user cache
folder under ``--work`` (warmed by a first round that is not counted). The default input is the start-up
row's file (10,000 PointZ, ``round3_bench.startup_points``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _env(tree: Path, cache: Path) -> dict[str, str]:
    """The environment of a run of ``tree``: its own user cache folder (the spec index is one
    file per virtual environment: two trees run in turn from one would rebuild it each time)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    meta = tree.with_name(tree.name + "_meta")
    env["PYTHONPATH"] = os.pathsep.join(str(p) for p in (tree, meta) if p.exists())
    env["XDG_CACHE_HOME"] = str(cache)
    return env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True)
    parser.add_argument("--new", type=Path, required=True)
    parser.add_argument("--runs", type=int, default=21)
    parser.add_argument("--input", type=Path)
    parser.add_argument("--work", type=Path, default=Path("/tmp/vector_info_ab"))
    args = parser.parse_args()
    if args.input is None:
        from round3_bench import startup_points

        args.work.mkdir(parents=True, exist_ok=True)
        args.input = startup_points(args.work)
    run = [sys.executable, "-m", "toolbox", "run", "vector:info", "--INPUT", str(args.input),
           "--progress", "none"]
    cases = {"gdalinfo --version": (["gdalinfo", "--version"], None),
             "ogrinfo -so -al": (["ogrinfo", "-so", "-al", str(args.input)], None),
             "vector:info, old": (run, _env(args.old.resolve(), args.work / "cache_old")),
             "vector:info, new": (run, _env(args.new.resolve(), args.work / "cache_new"))}
    times: dict[str, tuple[list[float], list[float]]] = {k: ([], []) for k in cases}
    for _ in range(args.runs + 1):  # the first round warms the caches, not counted
        for name, (cmd, env) in cases.items():
            start = time.perf_counter()
            proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL, cwd=args.work)
            _, status, usage = os.wait4(proc.pid, 0)
            if status:
                raise SystemExit(f"{name} failed ({status})")
            times[name][0].append(time.perf_counter() - start)
            times[name][1].append(usage.ru_utime + usage.ru_stime)
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load "
          f"{os.getloadavg()[0]:.1f}, {args.runs} rounds interleaved, {args.input}")
    print("| what | wall s | CPU s |\n|---|---:|---:|")
    for name, (wall, cpu) in times.items():
        print(f"| {name} | {statistics.median(wall[1:]):.3f} | {statistics.median(cpu[1:]):.3f} |")


if __name__ == "__main__":
    main()
