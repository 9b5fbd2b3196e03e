"""Benchmark: orientation:fiducials on full-size scans (16644 x 16644 px), time, CPU time, peak
memory and the share of the scan read.

    .venv/bin/python bench/fiducials_bench.py [--size 16644] [--repeat 5]

Two scans are rendered strip by strip (:func:`toolbox.demo.samples.scans.render_big_scan`) into
a temporary folder under /tmp, deleted afterwards: an 8-bit scan with Wild RC8 marks (277 MB
of pixels) and a 16-bit scan with Zeiss RMK TOP marks turned by 90 degrees (554 MB). Each is
measured by ``toolbox run orientation:fiducials`` in a child process (ORIENTATION=auto: the
eight scan orientations tried), the runs interleaved (8-bit, 16-bit, 8-bit, ...): median wall
and CPU time, the child's peak resident memory (:func:`benchlib.run_measured`), the pixels
read (the run's STATISTICS) and the marks' error against the rendered truth. A baseline run
on a 2400 x 2400 scan gives the memory the process needs whatever the scan size.
Results go to bench/results/fiducials.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, run_measured, write_results

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

CASES = {  # name -> dtype, family, orientation (G), pixel mm
    "8-bit, wild_rc8": ("uint8", "wild_rc8", None),
    "16-bit, zeiss_rmk_top, turned 90": ("uint16", "zeiss_rmk_top",
                                         np.array([[0.0, -1.0], [1.0, 0.0]])),
}
PIXEL = 0.014  # mm: 16644 px cover 233 mm


def child_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_case(project: Path, family: str, out: Path, *extra: str) -> dict:
    toolbox = str(Path(sys.executable).parent / "toolbox")
    cpu0 = child_cpu()
    seconds, peak, code, err = run_measured([toolbox, "-q", "run", "orientation:fiducials",
                                             "--PROJECT", str(project), "--FAMILY", family,
                                             "--OUTPUT", str(out), "--overwrite", *extra])
    if code != 0:
        raise RuntimeError(f"orientation:fiducials failed: {err[-2000:]}")
    return {"seconds": seconds, "cpu": child_cpu() - cpu0, "peak_mb": peak}


def accuracy(out: Path, centres: dict) -> tuple[float, int, float]:
    """(RMS px of the marks found against the truth, marks found, share of pixels read)."""
    doc = json.loads(out.read_text())
    entry = doc["photos"][0]
    error = [np.hypot(r["col_px"] - centres[r["mark"]][0], r["row_px"] - centres[r["mark"]][1])
             for r in entry["residuals"]]
    stats = doc["statistics"]
    return (float(np.sqrt(np.mean(np.square(error)))), len(error),
            stats["pixels_read"] / stats["pixels_in_scans"])


def main() -> None:
    from toolbox.demo.samples import scans as sc
    from toolbox.matching.marks import default_size

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=16644)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    note = load_note()
    load = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="fiducials_bench_", dir="/tmp") as tmp:
        work = Path(tmp)
        sc.render_scan(work / "small.tif")
        small_project = sc.project_yaml(work / "small.yaml", {"small": "small.tif"})
        cases = {}
        for name, (dtype, family, g) in CASES.items():
            path = work / f"{dtype}.tif"
            scan = sc.render_big_scan(path, args.size, PIXEL, dtype, family,
                                      *default_size(family), orientation=g)
            project = sc.project_yaml(work / f"{dtype}.yaml", {"big": path.name}, PIXEL)
            cases[name] = (scan, project, family, path.stat().st_size)
        runs = {name: [] for name in cases}
        baseline = [run_case(small_project, "cross", work / "small.json", "--MARK_SIZE",
                             str(sc.MARK), "--LINE_WIDTH", str(sc.LINE)) for _ in range(2)]
        for _ in range(args.repeat):
            for name, (scan, project, family, _) in cases.items():
                runs[name].append(run_case(project, family, work / "out.json"))
                runs[name][-1]["check"] = accuracy(work / "out.json", scan.centres)
    base_mb = max(b["peak_mb"] for b in baseline)
    lines = ["## Fiducial marks (issue 27): full-size scans read in windows "
             "(`bench/fiducials_bench.py`)", "",
             f"{machine_facts()}; load average {load[0]:.1f} / {load[1]:.1f} at the start; "
             f"{note}.", "",
             f"Scans of {args.size} x {args.size} px at {PIXEL * 1000:g} µm, tiled (512 px) "
             "uncompressed GeoTIFF, rendered strip by strip into /tmp and deleted afterwards; "
             "8 marks (4 corner, 4 side, one off-axis), turned 0.8 degrees with affinity, blur "
             "and noise. `toolbox run orientation:fiducials` (ORIENTATION=auto: 8 scan "
             f"orientations tried) in a child process; {args.repeat} interleaved runs per scan, "
             "medians. Peak memory: the child's VmHWM. Baseline: the same run on a 2400 x 2400 "
             f"px scan peaks at {base_mb:.0f} MB (imports, OpenCV, GDAL).", "",
             "| scan | file | wall s | CPU s | peak MB | above baseline MB | pixels read | "
             "marks found | RMS vs truth px |", "|---|---|---|---|---|---|---|---|---|"]
    for name, rs in runs.items():
        rms, found, share = rs[-1]["check"]
        peak = statistics.median(r["peak_mb"] for r in rs)
        lines.append(
            f"| {name} | {cases[name][3] / 1e6:.0f} MB | "
            f"{statistics.median(r['seconds'] for r in rs):.2f} | "
            f"{statistics.median(r['cpu'] for r in rs):.2f} | {peak:.0f} | "
            f"{peak - base_mb:.0f} | {100 * share:.1f} % | {found} / 8 | {rms:.3f} |")
    lines += ["", "Every run: " + "; ".join(
        f"{name}: " + ", ".join(f"{r['seconds']:.1f} s / {r['peak_mb']:.0f} MB" for r in rs)
        for name, rs in runs.items()), ""]
    write_results(HERE / "results" / "fiducials.md", lines)


if __name__ == "__main__":
    main()
