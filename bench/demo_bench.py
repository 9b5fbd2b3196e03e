"""`make demo` from nothing: ``toolbox demo`` into an empty folder, timed as a whole process.

    .venv/bin/python bench/demo_bench.py            # the per-user numba cache as it is
    .venv/bin/python bench/demo_bench.py --cold     # an empty numba cache: every kernel compiled

"From nothing" is an empty output folder after ``make venv`` (which runs ``toolbox warmup``, so
the kernels are in the per-user cache); ``--cold`` also empties that cache (a run without
``make venv``'s warmup). Reported: wall time, the CPU time of the process and its children
(user + system), and the machine's load average around the run, since on a shared machine the
wall time measures the neighbours too. The target is 3 minutes. Writes bench/results/demo.md.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOOLBOX = Path(sys.executable).with_name("toolbox")
TARGET_S = 180.0


def run_demo(cold: bool) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ)
        if cold:
            env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "numba")
            env["XDG_CACHE_HOME"] = str(Path(tmp) / "cache")
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        done = subprocess.run([str(TOOLBOX), "demo", "--out", str(Path(tmp) / "demo_out")],
                              capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        load1 = os.getloadavg()[0]
    if done.returncode != 0:
        raise SystemExit(f"toolbox demo failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"cache": "cold (empty numba cache)" if cold else "warm (after make venv)",
            "wall_s": wall, "cpu_s": cpu, "load": (load0, load1), "cores": os.cpu_count()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cold", action="store_true", help="empty numba cache")
    args = parser.parse_args()
    row = run_demo(args.cold)
    line = (f"| toolbox demo, empty folder, {row['cache']} | {row['wall_s']:.1f} | "
            f"{row['cpu_s']:.1f} | {row['load'][0]:.1f} / {row['load'][1]:.1f} | "
            f"{row['cores']} |")
    print(line)
    out = ROOT / "bench" / "results" / "demo.md"
    header = ("# `make demo` from nothing\n\nWhole `toolbox demo` process into an empty folder "
              f"(target {TARGET_S:.0f} s). CPU = user + system of the process and its "
              "children; load = the 1-minute load average before / after (a shared machine's "
              "wall time includes its neighbours').\n\n"
              "| run | wall s | CPU s | load | cores |\n|---|---|---|---|---|\n")
    text = out.read_text() if out.exists() else header
    out.write_text(text + line + "\n")


if __name__ == "__main__":
    main()
