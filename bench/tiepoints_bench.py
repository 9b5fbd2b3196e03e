"""Benchmark: tie-point extraction and matching (orientation:tiepoints), time and peak memory.

    .venv/bin/python bench/tiepoints_bench.py [--scans 3] [--size 3000] [--detectors sift,akaze,orb]
        [--colmap-python /path/to/venv/bin/python]

Workloads, each run as ``toolbox run orientation:tiepoints --IMAGES folder`` in a child process
(wall time and the child's peak resident memory, :func:`benchlib.run_measured`):

- ``--scans`` synthetic scans of ``--size`` x ``--size`` px (8-bit, tiled GeoTIFF): crops of one
  multi-scale noise "terrain", 60 % forward overlap, each turned by up to 1 degree and noised;
  no cameras, so every pair is tried on thumbnails first (the worst case);
- the four NGI aerial frames of Orthority's test data (when present), with their published
  orientations: the tie points' largest reprojection residual after intersection measures
  quality independently of the matcher.

Each detector (SIFT, AKAZE, ORB) is run on the same photos: time, verified matches, tie points.
With ``--colmap-python`` (a Python where ``import pycolmap`` works), pycolmap's SIFT
extraction and exhaustive matching run on the same scans (time, verified matches).
Results go to bench/results/tiepoints.md.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, run_measured

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


def make_scans(folder: Path, n: int, size: int, seed: int = 0) -> list[Path]:
    """``n`` overlapping crops (60 % forward overlap) of one multi-scale noise terrain."""
    import cv2

    from toolbox.photogrammetry.synthetic import write_photo

    rng = np.random.default_rng(seed)
    step = int(0.4 * size)
    width = size + step * (n - 1) + 64
    height = size + 64
    ground = np.zeros((height, width), np.float32)
    for scale, weight in ((2, 0.6), (6, 1.0), (20, 1.2), (60, 1.0)):
        small = rng.normal(0, 1, (height // scale + 2, width // scale + 2)).astype(np.float32)
        ground += weight * cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)[
            :height, :width]
    ground = 128 + 40 * ground / ground.std()
    paths = []
    for k in range(n):
        x0 = 32 + k * step
        angle = rng.uniform(-1.0, 1.0)
        m = cv2.getRotationMatrix2D((x0 + size / 2, 32 + size / 2), angle, 1.0)
        m[:, 2] -= [x0, 32]
        crop = cv2.warpAffine(ground, m, (size, size), flags=cv2.INTER_LINEAR)
        crop = np.clip(crop + rng.normal(0, 3, crop.shape), 0, 255).astype(np.uint8)
        paths.append(write_photo(folder / f"scan{k + 1:02d}.tif", crop))
        del crop
    return paths


def run_tiepoints(args: list[str], work: Path, tag: str) -> dict:
    out = work / f"{tag}.csv"
    pairs = work / f"{tag}_pairs.csv"
    report = work / f"{tag}.json"
    cmd = [sys.executable, "-m", "toolbox", "run", "orientation:tiepoints", *args, "--OUTPUT",
           str(out), "--PAIRS", str(pairs), "--REPORT", str(report), "--overwrite"]
    seconds, peak, code, err = run_measured(cmd)
    if code != 0:
        return {"error": err.strip().splitlines()[-1] if err.strip() else f"exit {code}",
                "seconds": seconds, "peak_mb": peak}
    stats = json.loads(report.read_text())["statistics"]
    with open(pairs, newline="") as f:
        verified = sum(int(r["verified"]) for r in csv.DictReader(f))
    return {"seconds": seconds, "peak_mb": peak, "verified": verified,
            "points": stats["points"], "pairs": stats["pairs_tied"],
            "max_px": stats["max_reprojection_px"]}


COLMAP_SCRIPT = """
import sys, sqlite3, pycolmap
db, images, out = sys.argv[1], sys.argv[2], sys.argv[3]
pycolmap.extract_features(db, images)
pycolmap.match_exhaustive(db)
con = sqlite3.connect(db)
rows = con.execute("select rows from two_view_geometries where rows > 0").fetchall()
open(out, "w").write(f"{sum(r[0] for r in rows)} {len(rows)} {pycolmap.__version__}")
"""


def run_colmap(python: str, images: Path, work: Path) -> dict:
    """pycolmap's default SIFT extraction and exhaustive matching (with its own geometric
    verification) in a child process: time, peak memory, verified matches."""
    script = work / "colmap_run.py"
    script.write_text(COLMAP_SCRIPT)
    db, out = work / "colmap.db", work / "colmap.txt"
    db.unlink(missing_ok=True)
    seconds, peak, code, err = run_measured([python, str(script), str(db), str(images),
                                             str(out)])
    if code != 0:
        return {"error": (err.strip().splitlines() or ["failed"])[-1]}
    verified, pairs, version = out.read_text().split()
    return {"seconds": seconds, "peak_mb": peak, "verified": int(verified), "pairs": int(pairs),
            "version": version}


def ngi_project(folder: Path) -> Path | None:
    sys.path.insert(0, str(HERE.parent / "tests"))
    from conftest import orthority_data_folder

    data = orthority_data_folder()
    if data is None:
        return None
    sys.path.insert(0, str(HERE.parent / "tests" / "algorithms" / "orientation"))
    from test_tiepoints_real import ngi_project as make

    return make(data, folder)


def row(name: str, r: dict) -> str:
    if "error" in r:
        return f"| {name} | failed: {r['error']} | | | | | |"
    max_px = "" if r.get("max_px") is None else f"{r['max_px']:.2f}"
    return (f"| {name} | {r['seconds']:.1f} | {r.get('peak_mb', float('nan')):.0f} | "
            f"{r['verified']:,} | {r.get('points', '')} | {r.get('pairs', '')} | {max_px} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=3)
    parser.add_argument("--size", type=int, default=3000)
    parser.add_argument("--detectors", default="sift,akaze,orb")
    parser.add_argument("--colmap-python", default=None)
    parser.add_argument("--output", default=str(HERE / "results" / "tiepoints.md"))
    args = parser.parse_args()
    import cv2

    lines = ["## Tie points (issue 27): extraction and matching", "",
             f"Machine: {machine_facts(f'OpenCV {cv2.__version__}')}; {load_note()}.", ""]
    from toolbox.matching.features import available

    detectors = [d.strip() for d in args.detectors.split(",") if d.strip()]
    missing = [d for d in detectors if not available(d)]
    detectors = [d for d in detectors if available(d)]
    if missing:
        lines += [f"Not run: {', '.join(missing)} (not in OpenCV {cv2.__version__}'s main "
                  "modules).", ""]
    header = ["| run | seconds | peak MB | verified matches | tie points | pairs tied | "
              "max reprojection px |", "|---|---:|---:|---:|---:|---:|---:|"]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        scans = work / "scans"
        scans.mkdir()
        make_scans(scans, args.scans, args.size)
        lines += [f"Synthetic scans: {args.scans} x {args.size} x {args.size} px (8-bit), "
                  "folder mode (no cameras: all pairs on thumbnails first), detection level "
                  "3000 px.", "", *header]
        for d in detectors:
            r = run_tiepoints(["--IMAGES", str(scans), "--DETECTOR", d], work, f"scan_{d}")
            lines.append(row(f"toolbox {d}", r))
            print(lines[-1], flush=True)
        if args.colmap_python:
            r = run_colmap(args.colmap_python, scans, work)
            lines.append(row(f"pycolmap {r.get('version', '')} SIFT (extract + exhaustive "
                             "match, its defaults)", r))
            print(lines[-1], flush=True)
        project = ngi_project(work)
        if project is not None:
            lines += ["", "NGI aerial frames (Orthority test data, 4 x 640 x 1152 px, published "
                      "orientations; max reprojection = largest residual of a tie point "
                      "intersected with them).", "", *header]
            for d in detectors:
                r = run_tiepoints(["--PROJECT", str(project), "--TERRAIN_HEIGHT", "300",
                                   "--DETECTOR", d], work, f"ngi_{d}")
                lines.append(row(f"toolbox {d}", r))
                print(lines[-1], flush=True)
                r = run_tiepoints(["--PROJECT", str(project), "--TERRAIN_HEIGHT", "300",
                                   "--DETECTOR", d, "--REFINE", "false"], work, f"ngi_{d}_raw")
                lines.append(row(f"toolbox {d}, no refinement", r))
                print(lines[-1], flush=True)
    Path(args.output).write_text("\n".join(lines) + "\n")
    print(f"written {args.output}")


if __name__ == "__main__":
    main()
