"""Benchmark: tie-point extraction and matching (orientation:tiepoints), time and peak memory.

    .venv/bin/python bench/tiepoints_bench.py [--scans 3] [--size 3000] [--block-size 16644]
        [--drones 100 [--drone-photos DIR]] [--detectors sift,akaze,orb]
        [--colmap-python /path/to/venv/bin/python] [--no-real]

Workloads, each run as ``toolbox run orientation:tiepoints --IMAGES folder`` in a child process
(wall time and the child's peak resident memory, :func:`benchlib.run_measured`):

- ``--block-size``: a block of 6 scans of that size (16644: the issue's target), rendered window
  by window from a deterministic multi-scale ground (:func:`ground_window`) into a temporary
  folder under /tmp, deleted afterwards; the tie points are checked against the TRUE scan
  geometry (:func:`ground_disagreement`);

- ``--scans`` synthetic scans of ``--size`` x ``--size`` px (8-bit, tiled GeoTIFF): crops of one
  multi-scale noise "terrain", 60 % forward overlap, each turned by up to 1 degree and noised;
  no cameras, so every pair is tried on thumbnails first (the worst case);
- ``--drones``: that many 20 Mpx nadir drone photos (:func:`drone_layout`), pairs chosen from
  a GNSS log (``--POSITIONS``), at a reduced detection level and with the defaults; checked
  against the TRUE geometry (:func:`drone_disagreement`); pycolmap on the same pairs;
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


def _uniform(i: np.ndarray, j: np.ndarray, salt: int) -> np.ndarray:
    """Deterministic uniform noise in [-1, 1) of integer lattice coordinates (a 64-bit hash):
    the same ground cell gets the same value whichever window asks for it."""
    with np.errstate(over="ignore"):
        h = (i.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) ^ \
            (j.astype(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F)) ^ np.uint64(salt * 7919 + 1)
        h ^= h >> np.uint64(29)
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(32)
    return (h >> np.uint64(40)).astype(np.float32) * np.float32(2.0 / 2 ** 24) - np.float32(1.0)


#: (lattice spacing in ground pixels, weight) of the multi-scale ground texture
GROUND_SCALES = ((1, 0.35), (3, 0.6), (8, 1.0), (24, 1.2), (80, 1.0))


def ground_window(x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """Grey ground (float32, about 128 ± 30) of ground pixels [x0, x0 + w) x [y0, y0 + h):
    lattice noise at several scales, each upsampled by a cubic (deterministic per cell, so
    overlapping scans see the same ground)."""
    import cv2

    out = np.zeros((h, w), np.float32)
    for s, weight in GROUND_SCALES:
        if s == 1:
            out += weight * _uniform(np.arange(x0, x0 + w)[None, :], np.arange(y0, y0 + h)[:, None],
                                     s)
            continue
        i0, j0 = x0 // s - 2, y0 // s - 2
        ni, nj = (x0 + w) // s + 3 - i0, (y0 + h) // s + 3 - j0
        lattice = _uniform(np.arange(i0, i0 + ni)[None, :], np.arange(j0, j0 + nj)[:, None], s)
        up = cv2.resize(lattice, (ni * s, nj * s), interpolation=cv2.INTER_CUBIC)
        ox, oy = x0 - i0 * s, y0 - j0 * s
        out += weight * up[oy:oy + h, ox:ox + w]
    return 128.0 + 30.0 * out


def write_big_scan(path: Path, size: int, origin: tuple[float, float], angle_deg: float,
                   seed: int, rows_per_window: int = 512, height: int | None = None) -> Path:
    """A ``size`` (wide) x ``height`` (default ``size``) 8-bit scan (tiled, uncompressed GeoTIFF
    without georeferencing) of the ground, turned by ``angle_deg`` about its centre, whose
    centre sees ground pixel ``origin + (size, height) / 2``; rendered window by window (bounded
    memory), with sensor noise."""
    import warnings

    import cv2
    import rasterio
    from rasterio.windows import Window

    width, height = size, height or size
    half = np.array([width / 2.0, height / 2.0])
    rng = np.random.default_rng(seed)
    a = np.radians(angle_deg)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    centre = np.array(origin, dtype="float64") + half
    profile = {"driver": "GTiff", "width": width, "height": height, "count": 1,
               "dtype": "uint8", "tiled": True, "blockxsize": 512, "blockysize": 512,
               "BIGTIFF": "IF_SAFER"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as dst:
            for r0 in range(0, height, rows_per_window):
                rows = min(rows_per_window, height - r0)
                # scan pixel (c, r) (OpenCV centres) -> ground: rot·((c, r) - half) + centre
                corners = np.array([[0, r0], [width, r0], [0, r0 + rows], [width, r0 + rows]],
                                   dtype="float64") - half
                ground = corners @ rot.T + centre
                gx0, gy0 = np.floor(ground.min(axis=0)).astype(int) - 3
                gx1, gy1 = np.ceil(ground.max(axis=0)).astype(int) + 3
                patch = ground_window(gx0, gy0, gx1 - gx0, gy1 - gy0)
                t = centre - rot @ (half - [0.0, r0]) - [gx0, gy0]
                m = np.column_stack([rot, t])
                out = cv2.warpAffine(patch, m, (width, rows),
                                     flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
                out += rng.normal(0.0, 3.0, out.shape).astype(np.float32)
                dst.write(np.clip(out, 0, 255).astype(np.uint8)[None],
                          window=Window(0, r0, width, rows))
    return path


def drone_layout(n: int = 100, width: int = 5472, height: int = 3648, seed: int = 0
                 ) -> dict[str, tuple[tuple[float, float], float]]:
    """Photo name -> (ground origin, angle) of ``n`` nadir drone photos in a serpentine grid:
    80 % forward overlap along the columns, 60 % side overlap, every other line flown back."""
    rng = np.random.default_rng(seed)
    lines = int(np.ceil(np.sqrt(n)))
    layout = {}
    for k in range(n):
        line, pos = divmod(k, lines)
        if line % 2:
            pos = lines - 1 - pos
        angle = (180.0 if line % 2 else 0.0) + rng.uniform(-3.0, 3.0)
        layout[f"drone_{k + 1:03d}"] = ((line * 0.4 * width, pos * 0.2 * height), angle)
    return layout


def drone_disagreement(measurements: Path, width: int = 5472, height: int = 3648,
                       n: int = 100) -> np.ndarray:
    """As :func:`ground_disagreement`, for the photos of :func:`drone_layout`."""
    layout = drone_layout(n, width, height)
    with open(measurements, newline="") as f:
        rows = list(csv.DictReader(f))
    half = np.array([width / 2.0, height / 2.0])
    by_point: dict[str, list[np.ndarray]] = {}
    for r in rows:
        origin, angle = layout[r["photo"]]
        a = np.radians(angle)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        pix = np.array([float(r["col_px"]), float(r["row_px"])]) - 0.5 - half
        by_point.setdefault(r["point_id"], []).append(rot @ pix + np.array(origin) + half)
    return np.array([np.hypot(*(np.array(g) - np.mean(g, axis=0)).T).max()
                     for g in by_point.values()])


def block_layout(size: int, strips: int = 2, per_strip: int = 3, seed: int = 0
                 ) -> dict[str, tuple[tuple[float, float], float]]:
    """Scan name -> (ground origin, angle in degrees) of a block: 60 % forward and 30 % side
    overlap, the second strip flown back (turned 180 degrees), each turned by up to 1 degree."""
    rng = np.random.default_rng(seed)
    layout = {}
    for s in range(strips):
        for k in range(per_strip):
            x = (k if s % 2 == 0 else per_strip - 1 - k) * 0.4 * size
            angle = (180.0 if s % 2 else 0.0) + rng.uniform(-1.0, 1.0)
            layout[f"scan_{s + 1}_{k + 1}"] = ((x, s * 0.7 * size), angle)
    return layout


def make_block_scans(folder: Path, size: int, seed: int = 0) -> list[Path]:
    """The scans of :func:`block_layout`, written to ``folder``."""
    return [write_big_scan(folder / f"{name}.tif", size, origin, angle, seed + k)
            for k, (name, (origin, angle)) in enumerate(block_layout(size, seed=seed).items())]


def ground_disagreement(measurements: Path, size: int, seed: int = 0) -> np.ndarray:
    """Per tie point, the largest distance (ground = scan pixels) of its observations, mapped
    to the ground through the TRUE scan geometry, from their mean: 0 for a perfect point."""
    layout = block_layout(size, seed=seed)
    with open(measurements, newline="") as f:
        rows = list(csv.DictReader(f))
    by_point: dict[str, list[np.ndarray]] = {}
    for r in rows:
        origin, angle = layout[r["photo"]]
        a = np.radians(angle)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        scan = np.array([float(r["col_px"]), float(r["row_px"])]) - 0.5 - size / 2.0
        by_point.setdefault(r["point_id"], []).append(
            rot @ scan + np.array(origin) + size / 2.0)
    worst = []
    for g in by_point.values():
        g = np.array(g)
        worst.append(np.hypot(*(g - g.mean(axis=0)).T).max())
    return np.array(worst)


def run_tiepoints(args: list[str], work: Path, tag: str, timeout: float | None = None) -> dict:
    out = work / f"{tag}.csv"
    pairs = work / f"{tag}_pairs.csv"
    report = work / f"{tag}.json"
    cmd = [sys.executable, "-m", "toolbox", "run", "orientation:tiepoints", *args, "--OUTPUT",
           str(out), "--PAIRS", str(pairs), "--REPORT", str(report), "--overwrite"]
    before = child_cpu()
    seconds, peak, code, err = run_measured(cmd, timeout=timeout)
    cpu = child_cpu() - before
    if code != 0:
        return {"error": err.strip().splitlines()[-1] if err.strip() else f"exit {code}",
                "seconds": seconds, "peak_mb": peak, "cpu": cpu}
    stats = json.loads(report.read_text())["statistics"]
    with open(pairs, newline="") as f:
        verified = sum(int(r["verified"]) for r in csv.DictReader(f))
    return {"seconds": seconds, "peak_mb": peak, "verified": verified, "cpu": cpu,
            "points": stats["points"], "pairs": stats["pairs_tied"],
            "candidates": stats["pairs_candidate"], "max_px": stats["max_reprojection_px"]}


def child_cpu() -> float:
    """CPU seconds (user + system, every thread) of this process's finished children."""
    import resource

    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


COLMAP_SCRIPT = """
import sys, sqlite3, pycolmap
db, images, out, size, features, pairs = sys.argv[1:7]
opts = pycolmap.FeatureExtractionOptions()
if int(size) > 0:
    opts.max_image_size = int(size)
if int(features) > 0:
    opts.sift.max_num_features = int(features)
pycolmap.extract_features(db, images, extraction_options=opts)
if pairs == "-":
    pycolmap.match_exhaustive(db)
else:
    pycolmap.match_image_pairs(db, pairing_options=pycolmap.ImportedPairingOptions(
        match_list_path=pairs))
con = sqlite3.connect(db)
rows = con.execute("select rows from two_view_geometries where rows > 0").fetchall()
open(out, "w").write(f"{sum(r[0] for r in rows)} {len(rows)} {pycolmap.__version__}")
"""


def run_colmap(python: str, images: Path, work: Path, max_size: int = 0, features: int = 0,
               pairs: list[tuple[str, str]] | None = None, timeout: float | None = None) -> dict:
    """pycolmap's SIFT extraction (its defaults, or ``max_size`` px and ``features`` per
    image) and matching (exhaustive, or the image ``pairs`` given: file names) with its own
    geometric verification, in a child process: time, CPU, peak memory, verified matches."""
    script = work / "colmap_run.py"
    script.write_text(COLMAP_SCRIPT)
    db, out = work / "colmap.db", work / "colmap.txt"
    db.unlink(missing_ok=True)
    listed = "-"
    if pairs is not None:
        listed = str(work / "colmap_pairs.txt")
        Path(listed).write_text("".join(f"{a} {b}\n" for a, b in pairs))
    before = child_cpu()
    seconds, peak, code, err = run_measured([python, str(script), str(db), str(images),
                                             str(out), str(max_size), str(features), listed],
                                            timeout=timeout)
    cpu = child_cpu() - before
    if code != 0:
        return {"error": (err.strip().splitlines() or ["failed"])[-1], "seconds": seconds,
                "cpu": cpu}
    verified, n_pairs, version = out.read_text().split()
    return {"seconds": seconds, "peak_mb": peak, "verified": int(verified), "pairs": int(n_pairs),
            "version": version, "cpu": cpu}


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
    cpu = f"{r['cpu']:.0f}" if r.get("cpu") is not None else ""
    if "error" in r:
        return f"| {name} | failed: {r['error']} ({r.get('seconds', 0):.0f} s) | {cpu} | | | | | |"
    max_px = "" if r.get("max_px") is None else f"{r['max_px']:.2f}"
    return (f"| {name} | {r['seconds']:.1f} | {cpu} | {r.get('peak_mb', float('nan')):.0f} | "
            f"{r['verified']:,} | {r.get('points', '')} | {r.get('pairs', '')} | {max_px} |")


HEADER = ["| run | seconds | CPU s | peak MB | verified matches | tie points | pairs tied | "
          "max error px |", "|---|---:|---:|---:|---:|---:|---:|---:|"]


def block_section(size: int, detectors: list[str], colmap: str | None, say) -> list[str]:
    """6 scans of ``size`` px rendered to a temporary folder under /tmp (deleted after)."""
    import time

    lines = [f"Block of 6 synthetic scans, {size} x {size} px each (8-bit, tiled uncompressed "
             f"GeoTIFF, {6 * size * size / 1e9:.2f} GB on disk; 2 strips x 3, 60 % forward / 30 % "
             "side overlap, second strip flown back, each turned up to 1 degree), folder mode "
             "(no cameras: all 15 pairs tried on thumbnails first); detection level 3000 px. "
             "Max error = largest distance of a tie point's observations, mapped to the ground "
             "through the TRUE scan geometry, from their mean (scan pixels).", ""]
    with tempfile.TemporaryDirectory(dir="/tmp") as tmp:
        work = Path(tmp)
        scans = work / "scans"
        scans.mkdir()
        t0 = time.perf_counter()
        make_block_scans(scans, size)
        lines += [f"(rendering the scans, not timed below: {time.perf_counter() - t0:.0f} s)", "",
                  *HEADER]
        say(lines[-3])
        for d in detectors:
            r = run_tiepoints(["--IMAGES", str(scans), "--DETECTOR", d], work, f"block_{d}")
            if "error" not in r:
                r["max_px"] = float(ground_disagreement(work / f"block_{d}.csv", size).max())
            lines.append(row(f"toolbox {d}", r))
            say(lines[-1])
        if colmap:
            r = run_colmap(colmap, scans, work)
            lines.append(row(f"pycolmap {r.get('version', '')} SIFT (extract + exhaustive "
                             "match, its defaults: images downscaled to 3200 px, 8192 features)",
                             r))
            say(lines[-1])
    return lines


def drone_positions(path: Path, n: int, width: int = 5472, height: int = 3648,
                    noise: float = 150.0, seed: int = 1) -> Path:
    """A GNSS log of the photos of :func:`drone_layout`: photo, x, y (ground pixels, y up) of
    each photo's centre with ``noise`` ground pixels of error (a drone's GNSS: a few metres at
    a few centimetres a pixel)."""
    rng = np.random.default_rng(seed)
    lines = ["photo,x,y"]
    for name, (origin, _) in drone_layout(n, width, height).items():
        x, y = np.array(origin) + [width / 2.0, height / 2.0] + rng.normal(0.0, noise, 2)
        lines.append(f"{name},{x:.1f},{-y:.1f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def render_drones(folder: Path, n: int) -> float:
    """Render the missing photos of :func:`drone_layout` into ``folder``; seconds spent."""
    import time

    t0 = time.perf_counter()
    for k, (name, (origin, angle)) in enumerate(drone_layout(n).items()):
        target = folder / f"{name}.tif"
        if not target.exists():
            part = folder / f"{name}.part.tif"
            write_big_scan(part, 5472, origin, angle, k, height=3648)
            part.rename(target)
    return time.perf_counter() - t0


#: the drone runs: (label, extra tiepoints arguments); the POSITIONS log is always given
DRONE_RUNS = (
    ("neighbours from the GNSS log, detection level 2000 px, 4000 features",
     ["--MAX_SIZE", "2000", "--MAX_FEATURES", "4000"]),
    ("neighbours from the GNSS log, defaults (3000 px, 10,000 features)", []),
)


def drone_section(n: int, detectors: list[str], say, timeout: float = 1800.0,
                  photos_dir: Path | None = None, colmap: str | None = None,
                  colmap_timeout: float = 1200.0) -> list[str]:
    """``n`` synthetic nadir drone photos of 5472 x 3648 px (20 Mpx), rendered (not timed) into
    ``photos_dir`` (kept) or a temporary folder under /tmp (deleted after), matched with pairs
    chosen from a GNSS log (``--POSITIONS``: about 8 neighbours a photo); with ``colmap``,
    pycolmap on the same photos and the same pairs."""
    lines = [f"{n} synthetic drone photos, 5472 x 3648 px (20 Mpx, 8-bit grey, tiled "
             "uncompressed GeoTIFF): a serpentine grid, 80 % forward / 60 % side overlap, every "
             "other line flown back, each turned up to 3 degrees. Pairs from a GNSS log (photo "
             "centres with 150 ground px of noise): each photo's 8 nearest plus the Delaunay "
             f"edges, instead of all {n * (n - 1) // 2} pairs. Max error as above (photo "
             "pixels); CPU s = user + system seconds of the run's process (every thread).", ""]
    with tempfile.TemporaryDirectory(dir="/tmp") as tmp:
        work = Path(tmp)
        photos = photos_dir or work / "photos"
        photos.mkdir(parents=True, exist_ok=True)
        rendered = render_drones(photos, n)
        log = drone_positions(work / "gnss.csv", n)
        lines += [f"(rendering the photos, not timed below: {rendered:.0f} s)", "", *HEADER]
        say(lines[-3])
        pair_list = None
        for d in detectors:
            for label, extra in DRONE_RUNS:
                tag = f"drone_{d}_{len(extra)}"
                r = run_tiepoints(["--IMAGES", str(photos), "--POSITIONS", str(log),
                                   "--DETECTOR", d, *extra], work, tag, timeout)
                if "error" not in r:
                    r["max_px"] = float(drone_disagreement(work / f"{tag}.csv", n=n).max())
                    if pair_list is None:
                        with open(work / f"{tag}_pairs.csv", newline="") as f:
                            pair_list = [(f"{p['photo_a']}.tif", f"{p['photo_b']}.tif")
                                         for p in csv.DictReader(f)]
                lines.append(row(f"toolbox {d}, {label} ({r.get('candidates', '?')} pairs)", r))
                say(lines[-1])
        if colmap and pair_list is not None:
            r = run_colmap(colmap, photos, work, 2000, 4000, pair_list, colmap_timeout)
            lines.append(row(f"pycolmap {r.get('version', '')} SIFT, 2000 px, 4000 features, "
                             f"the same {len(pair_list)} pairs", r))
            say(lines[-1])
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=3, help="small synthetic scans (0: none)")
    parser.add_argument("--size", type=int, default=3000)
    parser.add_argument("--block-size", type=int, default=0,
                        help="also a block of 6 scans of this size (16644: the issue's target)")
    parser.add_argument("--drones", type=int, default=0,
                        help="also this many 20 Mpx drone photos (100: the issue's target)")
    parser.add_argument("--drone-photos", default=None,
                        help="folder for the drone photos (rendered where missing, kept)")
    parser.add_argument("--detectors", default="sift,akaze,orb")
    parser.add_argument("--colmap-python", default=None)
    parser.add_argument("--no-real", action="store_true", help="skip the NGI frames")
    parser.add_argument("--output", default=str(HERE / "results" / "tiepoints.md"))
    args = parser.parse_args()
    import cv2

    def say(line: str) -> None:
        print(line, flush=True)

    lines = ["## Tie points (issue 27): extraction and matching", "",
             f"Machine: {machine_facts(f'OpenCV {cv2.__version__}')}; {load_note()}.", ""]
    from toolbox.matching.features import available

    detectors = [d.strip() for d in args.detectors.split(",") if d.strip()]
    missing = [d for d in detectors if not available(d)]
    detectors = [d for d in detectors if available(d)]
    if missing:
        lines += [f"Not run: {', '.join(missing)} (not in OpenCV {cv2.__version__}'s main "
                  "modules).", ""]
    if args.block_size:
        lines += block_section(args.block_size, detectors, args.colmap_python, say) + [""]
    if args.drones:
        lines += drone_section(args.drones, detectors, say,
                               photos_dir=Path(args.drone_photos) if args.drone_photos else None,
                               colmap=args.colmap_python) + [""]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if args.scans:
            scans = work / "scans"
            scans.mkdir()
            make_scans(scans, args.scans, args.size)
            lines += [f"Synthetic scans: {args.scans} x {args.size} x {args.size} px (8-bit), "
                      "folder mode (no cameras: all pairs on thumbnails first), detection level "
                      "3000 px.", "", *HEADER]
            for d in detectors:
                r = run_tiepoints(["--IMAGES", str(scans), "--DETECTOR", d], work, f"scan_{d}")
                lines.append(row(f"toolbox {d}", r))
                say(lines[-1])
            if args.colmap_python:
                r = run_colmap(args.colmap_python, scans, work)
                lines.append(row(f"pycolmap {r.get('version', '')} SIFT (extract + exhaustive "
                                 "match, its defaults)", r))
                say(lines[-1])
        project = None if args.no_real else ngi_project(work)
        if project is not None:
            lines += ["", "NGI aerial frames (Orthority test data, 4 x 640 x 1152 px, published "
                      "orientations; max error = largest reprojection residual of a tie point "
                      "intersected with them).", "", *HEADER]
            for d in detectors:
                r = run_tiepoints(["--PROJECT", str(project), "--TERRAIN_HEIGHT", "430",
                                   "--DETECTOR", d], work, f"ngi_{d}")
                lines.append(row(f"toolbox {d}", r))
                say(lines[-1])
                r = run_tiepoints(["--PROJECT", str(project), "--TERRAIN_HEIGHT", "430",
                                   "--DETECTOR", d, "--REFINE", "false"], work, f"ngi_{d}_raw")
                lines.append(row(f"toolbox {d}, no refinement", r))
                say(lines[-1])
    Path(args.output).write_text("\n".join(lines) + "\n")
    print(f"written {args.output}")


if __name__ == "__main__":
    main()
