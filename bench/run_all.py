"""Run every benchmark (bench/*_bench.py, each with a main()) one after the other, then gather
their markdown results (bench/results/*.md) into bench/RESULTS.md.

    .venv/bin/python bench/run_all.py            # all
    .venv/bin/python bench/run_all.py dem tin    # some

Benchmarks compare the toolbox with the peers a user would otherwise run (gdal_grid, scipy,
OpenCV, Triangle, GRASS where installed) in one run on one machine, and report ratios.
"""

from __future__ import annotations

import datetime as dt
import importlib.util
import os
import platform
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def machine_facts() -> str:
    import numpy as np

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{dt.date.today().isoformat()}, {os.cpu_count()} cores ({cpu}), Python "
            f"{platform.python_version()}, numpy {np.__version__}")


def main(selected: list[str]) -> None:
    sys.path.insert(0, str(HERE.parent))
    for script in sorted(HERE.glob("*_bench.py")):
        domain = script.stem.removesuffix("_bench")
        if selected and domain not in selected:
            continue
        print(f"== {domain}", flush=True)
        spec = importlib.util.spec_from_file_location(f"bench_{domain}", script)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.main()
    parts = ["# Benchmark results", "",
             "Written by `bench/run_all.py` (`make bench`); one section per domain, each measured in "
             "one run side by side with its peers.", "", f"Last full run: {machine_facts()}.", ""]
    for result in sorted((HERE / "results").glob("*.md")):
        parts += [result.read_text().strip(), ""]
    (HERE / "RESULTS.md").write_text("\n".join(parts))
    print(f"wrote {HERE / 'RESULTS.md'}")


if __name__ == "__main__":
    main(sys.argv[1:])
