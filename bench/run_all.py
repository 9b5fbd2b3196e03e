"""Run every benchmark (bench/*_bench.py, each with a main()) one after the other, then gather
their markdown results (bench/results/*.md) into bench/RESULTS.md.

    .venv/bin/python bench/run_all.py            # all
    .venv/bin/python bench/run_all.py dem tin    # some

Each benchmark runs in its own process. Benchmarks compare the toolbox with the peers a user
would otherwise run (gdal_grid, scipy, OpenCV, Triangle, GRASS where installed) in one run on one
machine, and report ratios.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from benchlib import machine_facts

HERE = Path(__file__).resolve().parent


def main(selected: list[str]) -> None:
    collect_only = selected == ["--collect"]  # rewrite RESULTS.md from bench/results/ only
    for script in [] if collect_only else sorted(HERE.glob("*_bench.py")):
        domain = script.stem.removesuffix("_bench")
        if selected and domain not in selected:
            continue
        print(f"== {domain}", flush=True)
        # each benchmark in a fresh interpreter: no memory high-water mark or warm cache of
        # one benchmark leaks into the next
        subprocess.run([sys.executable, str(script)], check=True, cwd=HERE.parent)
    parts = ["# Benchmark results", "",
             "Written by `bench/run_all.py` (`make bench`); one section per domain, each measured in "
             "one run side by side with its peers. Each section names its own date and machine "
             "load: sections measured while other work ran on both cores say so, and only their "
             "ratios (toolbox and peer side by side, in one run) are meaningful.", "",
             f"Collected: {machine_facts()}.", ""]
    for result in sorted((HERE / "results").glob("*.md")):
        parts += [result.read_text().strip(), ""]
    (HERE / "RESULTS.md").write_text("\n".join(parts))
    print(f"wrote {HERE / 'RESULTS.md'}")


if __name__ == "__main__":
    main(sys.argv[1:])
