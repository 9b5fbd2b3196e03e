"""Benchmark: rectification (estimation and windowed warping) against OpenCV and scikit-image.

Run standalone: ``.venv/bin/python bench/rectify_bench.py [--no-big] [--keep]``. Writes
``bench/results/rectify.md``.

1. Estimation from 1,000 control points (homography): ours (DLT start + Gauss-Newton, full
   statistics; with data snooping; with RANSAC) vs ``cv2.findHomography`` (least squares +
   Levenberg-Marquardt; RANSAC) and scikit-image ``ProjectiveTransform`` (DLT).
2. Rectifying a 12 Mpx RGB photo (4000 x 3000) with the same output grid and interpolation:
   - in memory: our windowed kernel (the ``rectify:image`` path and the generic coordinate-map
     + ``cv2.remap`` path) vs one ``cv2.warpPerspective`` of the whole image; both get and give
     band-sequential arrays (rasterio's layout), OpenCV also without the layout conversion;
   - file to file: ``rectify:image`` vs a script that reads the whole photo with rasterio,
     warps it with ``cv2.warpPerspective`` and writes the same tiled DEFLATE GeoTIFF (RGB +
     alpha, no overviews in either), in this process; and, whole process both (``toolbox
     run`` against the command, interleaved, median of 3, CPU time too), vs ``gdalwarp -order
     3`` from 25 GCPs of the homography (when GDAL's command line is installed; its cubic
     polynomial approximates the homography, ours is exact).
3. A 16644 x 16644 RGB scan (the Siena scans' size), generated window by window as a tiled
   GeoTIFF: ``rectify:image`` in a subprocess, peak RSS measured (the child's ``VmHWM`` and
   psutil polling); the files are deleted afterwards.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from benchlib import best_of, load_note, machine_facts, write_results

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.algorithms.rectify.rectify_scene import apply, camera_homography  # noqa: E402

RESULTS = ROOT / "bench" / "results" / "rectify.md"

warnings.filterwarnings("ignore", message=".*no geotransform.*")
TILTS = (0.03, -0.02, 0.05)  # the benchmark camera's omega, phi, kappa (rad)



# -- 1. estimation ------------------------------------------------------------------------------
def bench_estimation() -> list[dict]:
    import cv2
    from skimage.transform import ProjectiveTransform

    from toolbox.terrain.points import local_origin
    from toolbox.transforms.plane import HomographyTransform
    from toolbox.transforms.robust import data_snooping, ransac

    rng = np.random.default_rng(1)
    g2p = camera_homography(16644, 16644, 0.014, 303.55, 1140.0, TILTS)
    image = rng.uniform(100, 16500, (1000, 2))
    ground = apply(np.linalg.inv(g2p), image) + rng.normal(0, 0.05, (1000, 2))
    ground_blunders = ground.copy()
    bad = rng.choice(1000, 10, replace=False)
    ground_blunders[bad] += rng.uniform(2, 5, (10, 2))
    origin = local_origin(ground)
    dst, dst_b = ground - origin, ground_blunders - origin
    src32, dst32, dstb32 = image.astype("float32"), dst.astype("float32"), dst_b.astype("float32")

    def ours():
        return HomographyTransform.estimate(image, dst)

    rows = []
    t_ours = best_of(ours, 20)
    t_cv = best_of(lambda: cv2.findHomography(src32, dst32, 0), 20)
    if hasattr(ProjectiveTransform, "from_estimate"):  # scikit-image >= 0.26
        t_sk = best_of(lambda: ProjectiveTransform.from_estimate(image, dst), 20)
    else:  # pragma: no cover
        t_sk = best_of(lambda: ProjectiveTransform().estimate(image, dst), 20)
    t_snoop = best_of(lambda: data_snooping(HomographyTransform, image, dst_b, sigma=0.05), 3)
    t_ransac = best_of(lambda: ransac(HomographyTransform, image, dst_b, 0.3), 5)
    t_cvr = best_of(lambda: cv2.findHomography(src32, dstb32, cv2.RANSAC, 0.3), 5)
    snoop = data_snooping(HomographyTransform, image, dst_b, sigma=0.05)
    found = {r.index for r in snoop.rejections}
    rows.append({"case": "LSQ homography, 1,000 points (ours: + residuals, sigma0, redundancy "
                         "numbers)", "ours": t_ours, "peer": t_cv, "peer_name":
                 "cv2.findHomography(0)", "extra": f"skimage ProjectiveTransform {t_sk * 1e3:.2f} ms"})
    rows.append({"case": "RANSAC + LSQ refit, 1,000 points, 10 blunders", "ours": t_ransac,
                 "peer": t_cvr, "peer_name": "cv2.findHomography(RANSAC)", "extra": ""})
    rows.append({"case": f"data snooping, 1,000 points, 10 blunders ({len(snoop.rejections)} "
                         f"rejected, {len(found & set(bad))}/10 blunders found)",
                 "ours": t_snoop, "peer": None, "peer_name": "-", "extra": ""})
    return rows


# -- 2. 12 Mpx in memory and file to file -------------------------------------------------------
def synthetic_rgb(width: int, height: int, seed: int = 0) -> np.ndarray:
    """(3, h, w) uint8 photo-like texture (blurred noise + gradients)."""
    import cv2

    rng = np.random.default_rng(seed)
    small = rng.integers(0, 255, (height // 8 + 1, width // 8 + 1, 3), dtype=np.uint8)
    big = cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
    noise = rng.integers(0, 24, (height, width, 3), dtype=np.uint8)
    return np.moveaxis(cv2.add(big, noise), -1, 0).copy()


def scene_12mpx():
    """Photo size, pixel -> ground homography and output grid of the 12 Mpx case."""
    from toolbox.io.grid import GridSpec
    from toolbox.transforms.rectification import default_cell_size, footprint

    width, height = 4000, 3000
    g2p = camera_homography(width, height, 0.006, 50.0, 600.0, tilts=(0.12, -0.08, 0.3))
    p2g = np.linalg.inv(g2p)
    p2g /= p2g[2, 2]
    corners = footprint(p2g, width, height)
    cell = default_cell_size(p2g, width, height)
    grid = GridSpec.from_bounds((*corners.min(axis=0), *corners.max(axis=0)), cell, "EPSG:3003")
    return width, height, p2g, grid


def opencv_matrix(p2g, grid):
    """``cv2.warpPerspective`` matrix (source pixel -> output pixel, OpenCV centre convention)
    equivalent to our conventions (source centres at +0.5, output cell centres)."""
    t = grid.transform
    ground_to_out = np.array([[1 / t.a, 0, -t.c / t.a], [0, 1 / t.e, -t.f / t.e], [0, 0, 1]])
    half = np.array([[1, 0, 0.5], [0, 1, 0.5], [0, 0, 1]])
    return np.linalg.inv(half) @ ground_to_out @ p2g @ half


def bench_memory(data: np.ndarray) -> list[dict]:
    import cv2

    from toolbox.raster.homography import HomographyMap
    from toolbox.raster.tile import iter_tiles
    from toolbox.raster.warp import OutputLayout, warp_window

    width, height, p2g, grid = scene_12mpx()
    cmap = HomographyMap(np.linalg.inv(p2g), grid.transform,
                         front=tuple(apply(p2g, [[width / 2, height / 2]])[0]))
    layout = OutputLayout([1, 2, 3], None, False, True, None, "uint8")
    windows = [t.window for t in iter_tiles(grid, 2048)]
    matrix = opencv_matrix(p2g, grid)
    flags = {"nearest": cv2.INTER_NEAREST, "bilinear": cv2.INTER_LINEAR,
             "cubic": cv2.INTER_CUBIC, "lanczos": cv2.INTER_LANCZOS4}
    interleaved = cv2.merge(list(data))

    def read(bands, win):
        r0, c0 = int(win.row_off), int(win.col_off)
        return data[:, r0:r0 + int(win.height), c0:c0 + int(win.width)].copy()

    def ours(method, fast=True):
        out = np.empty((4, grid.height, grid.width), np.uint8)
        for window in windows:
            for part, arr in warp_window(read, (width, height), cmap, window, layout, method,
                                         fast=fast):
                r0, c0 = int(part.row_off), int(part.col_off)
                out[:, r0:r0 + arr.shape[1], c0:c0 + arr.shape[2]] = arr
        return out

    def peer(method, convert=True):
        src = cv2.merge(list(data)) if convert else interleaved
        res = cv2.warpPerspective(src, matrix, (grid.width, grid.height), flags=flags[method])
        return np.stack(cv2.split(res)) if convert else res

    rows = []
    mpx = grid.width * grid.height / 1e6
    for method in ("nearest", "bilinear", "cubic", "lanczos"):
        t_ours = best_of(lambda m=method: ours(m), 3)
        t_generic = best_of(lambda m=method: ours(m, False), 2)
        t_peer = best_of(lambda m=method: peer(m), 3)
        t_raw = best_of(lambda m=method: peer(m, False), 3)
        ref = peer(method)
        got = ours(method)
        inside = got[3] > 0
        inner = cv2.erode(inside.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        diff = np.abs(got[:3].astype(int) - ref.astype(int))[:, inner]
        differ = float((diff > 1).mean())
        rows.append({"case": f"12 Mpx RGB -> {grid.width} x {grid.height} ({mpx:.1f} Mpx) in "
                             f"memory, {method}", "ours": t_ours, "peer": t_peer,
                     "peer_name": "cv2.warpPerspective (+ band layout)",
                     "extra": f"generic remap path {t_generic:.3f} s "
                              f"({t_generic / t_peer:.2f}x); warpPerspective alone "
                              f"{t_raw:.3f} s; inside the footprint {differ:.2%} of values "
                              f"differ by > 1 (1/32 px coordinate rounding)"})
    return rows


def bench_files(data: np.ndarray, folder: Path) -> list[dict]:
    import cv2
    import rasterio

    import toolbox
    from toolbox.io.raster import geotiff_profile
    from toolbox.raster.warp import OutputLayout, photometric_options

    width, height, p2g, grid = scene_12mpx()
    src_path = folder / "photo12.tif"
    with rasterio.open(src_path, "w", **geotiff_profile(width, height, 3, "uint8", None, None,
                                                        photometric="RGB")) as dst:
        dst.write(data)
    tjson = folder / "t12.json"
    import json

    tjson.write_text(json.dumps({"format": "toolbox.rectify.transform", "version": 1,
                                 "model": "homography", "image_units": "pixels",
                                 "image_to_ground": p2g.tolist(), "crs": None, "points": []}))
    x0, y0, x1, y1 = grid.bounds
    matrix = opencv_matrix(p2g, grid)
    layout = OutputLayout([1, 2, 3], None, False, True, None, "uint8")

    def ours(method):
        toolbox.run("rectify:image", {"INPUT": src_path, "TRANSFORM": tjson,
                                      "CELL_SIZE": grid.transform.a,
                                      "EXTENT": f"{x0},{y0},{x1},{y1}", "RESAMPLING": method,
                                      "OVERVIEWS": False, "OUTPUT": folder / "ours.tif"},
                    overwrite=True)

    def peer(method):
        flags = {"bilinear": cv2.INTER_LINEAR, "cubic": cv2.INTER_CUBIC}
        with rasterio.open(src_path) as src:
            rgba = cv2.merge([*src.read(), np.full((height, width), 255, np.uint8)])
        res = cv2.warpPerspective(rgba, matrix, (grid.width, grid.height), flags=flags[method])
        profile = geotiff_profile(grid.width, grid.height, 4, "uint8", grid.crs, grid.transform,
                                  None, num_threads="ALL_CPUS", **photometric_options(layout))
        with rasterio.open(folder / "peer.tif", "w", **profile) as dst:
            dst.write(np.stack(cv2.split(res)))

    rows = []
    for method in ("bilinear", "cubic"):
        t_ours = best_of(lambda m=method: ours(m), 2)
        t_peer = best_of(lambda m=method: peer(m), 2)
        rows.append({"case": f"12 Mpx RGB GeoTIFF -> GeoTIFF (RGB + alpha, DEFLATE), {method}",
                     "ours": t_ours, "peer": t_peer,
                     "peer_name": "rasterio read + cv2.warpPerspective + rasterio write",
                     "extra": f"output {grid.width} x {grid.height}; in this process"})
        gdal = gdalwarp_order3(src_path, p2g, width, height, grid, method, folder)
        if gdal is not None:
            ours_cmd = [str(Path(sys.executable).with_name("toolbox")), "run", "rectify:image",
                        "--overwrite", "--INPUT", str(src_path), "--TRANSFORM", str(tjson),
                        "--CELL_SIZE", repr(grid.transform.a), "--EXTENT", f"{x0},{y0},{x1},{y1}",
                        "--RESAMPLING", method, "--OVERVIEWS", "false",
                        "--OUTPUT", str(folder / "ours_cli.tif")]
            (w_ours, c_ours), (w_gdal, c_gdal) = whole_process_pair(ours_cmd, gdal, 3)
            rows.append({"case": f"12 Mpx RGB GeoTIFF -> GeoTIFF (RGB + alpha, DEFLATE, 512 "
                                 f"tiles), {method}, whole process both",
                         "ours": w_ours, "peer": w_gdal,
                         "peer_name": "gdalwarp -order 3 (25 GCPs, -multi, ALL_CPUS)",
                         "extra": f"`toolbox run` vs the gdalwarp command, interleaved, median of "
                                  f"3; CPU {c_ours:.2f} s vs {c_gdal:.2f} s; gdalwarp's cubic "
                                  "polynomial approximates the homography, ours is exact"})
    return rows


def whole_process_pair(cmd_a: list[str], cmd_b: list[str],
                       rounds: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """Median (wall s, CPU s) of two commands run alternately ``rounds`` times (after one
    warm-up run of each: file cache), CPU from the children's rusage."""
    import resource
    import statistics

    def run(cmd):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)

    run(cmd_a)
    run(cmd_b)
    a, b = [], []
    for _ in range(rounds):
        a.append(run(cmd_a))
        b.append(run(cmd_b))
    return tuple(tuple(statistics.median(x) for x in zip(*r)) for r in (a, b))


def gdalwarp_order3(src_path: Path, p2g: np.ndarray, width: int, height: int, grid, method: str,
                    folder: Path) -> list[str] | None:
    """The ``gdalwarp -order 3`` command onto the same grid and file layout (tiled 512, DEFLATE,
    predictor 2, alpha), from a VRT of the photo with 5 x 5 GCPs of the homography (written
    here); None without GDAL's command line."""
    gdal_translate, gdalwarp = shutil.which("gdal_translate"), shutil.which("gdalwarp")
    if gdal_translate is None or gdalwarp is None:
        return None
    cols, rows = np.meshgrid(np.linspace(0, width, 5), np.linspace(0, height, 5))
    pixels = np.column_stack([cols.ravel(), rows.ravel()])
    ground = apply(p2g, pixels)
    gcps = [a for (c, r), (x, y) in zip(pixels, ground, strict=True)
            for a in ("-gcp", f"{c}", f"{r}", f"{x}", f"{y}")]
    vrt = folder / "gcps.vrt"
    subprocess.run([gdal_translate, "-q", "-of", "VRT", *gcps, str(src_path), str(vrt)],
                   check=True)
    x0, y0, x1, y1 = grid.bounds
    return [gdalwarp, "-q", "-overwrite", "-order", "3", "-r", method, "-multi",
            "-wo", "NUM_THREADS=ALL_CPUS", "-te", *map(str, (x0, y0, x1, y1)),
            "-ts", str(grid.width), str(grid.height), "-dstalpha", "-co", "TILED=YES",
            "-co", "BLOCKXSIZE=512", "-co", "BLOCKYSIZE=512", "-co", "COMPRESS=DEFLATE",
            "-co", "PREDICTOR=2", "-co", "NUM_THREADS=ALL_CPUS", str(vrt),
            str(folder / "gdal.tif")]


# -- 3. the 16644 x 16644 scan ------------------------------------------------------------------
# peak RSS: VmHWM of the child's own address space (ru_maxrss is not usable: Linux carries the
# parent's high-water mark across fork/exec into the child's ru_maxrss)
BIG_SCRIPT = r"""
import sys, time, warnings
warnings.filterwarnings("ignore")
sys.path.insert(0, {root!r})
import toolbox
from toolbox.feedback import Feedback
feedback = Feedback()
t0 = time.perf_counter()
out = toolbox.run("rectify:image", {{"INPUT": {src!r}, "TRANSFORM": {tjson!r},
                  "RESAMPLING": "bilinear", "OUTPUT": {out!r}}}, overwrite=True,
                  feedback=feedback)
elapsed = time.perf_counter() - t0
print("overviews_s", feedback.timings.get("overviews", 0.0))
s = out["STATISTICS"]
hwm = [line.split()[1] for line in open("/proc/self/status") if line.startswith("VmHWM")][0]
print(elapsed, s["width"], s["height"], s["cell_size"], hwm)
"""


def make_big_scan(path: Path, size: int = 16644) -> float:
    """Write a size x size RGB tiled GeoTIFF window by window; returns seconds."""
    import cv2
    import rasterio
    from affine import Affine

    from toolbox.io.grid import GridSpec
    from toolbox.io.raster import geotiff_profile
    from toolbox.raster.tile import iter_tiles

    t0 = time.perf_counter()
    rng = np.random.default_rng(2)
    base = rng.integers(0, 255, (size // 64 + 2, size // 64 + 2, 3), dtype=np.uint8)
    profile = geotiff_profile(size, size, 3, "uint8", None, None, photometric="RGB",
                              num_threads="ALL_CPUS", zlevel=1)
    with rasterio.open(path, "w", **profile) as dst:
        for tile in iter_tiles(GridSpec(Affine.identity(), size, size), 2048):
            w = tile.window
            c0, r0, cw, ch = int(w.col_off), int(w.row_off), int(w.width), int(w.height)
            small = base[r0 // 64:(r0 + ch) // 64 + 2, c0 // 64:(c0 + cw) // 64 + 2]
            big = cv2.resize(small, (small.shape[1] * 64, small.shape[0] * 64),
                             interpolation=cv2.INTER_LINEAR)
            big = big[r0 % 64:r0 % 64 + ch, c0 % 64:c0 % 64 + cw]
            noise = rng.integers(0, 16, big.shape, dtype=np.uint8)
            dst.write(np.moveaxis(cv2.add(big, noise), -1, 0), window=w)
    return time.perf_counter() - t0


def bench_big(folder: Path) -> dict:
    import json

    from toolbox.extras import require

    psutil = require("psutil", "bench", "the benchmarks")
    size = 16644
    src = folder / "scan16644.tif"
    t_make = make_big_scan(src, size)
    g2p = camera_homography(size, size, 0.014, 303.55, 1140.0, TILTS)
    p2g = np.linalg.inv(g2p)
    tjson = folder / "t_big.json"
    tjson.write_text(json.dumps({"format": "toolbox.rectify.transform", "version": 1,
                                 "model": "homography", "image_units": "pixels",
                                 "image_to_ground": (p2g / p2g[2, 2]).tolist(),
                                 "crs": "EPSG:3003", "points": []}))
    out = folder / "scan_rectified.tif"
    script = BIG_SCRIPT.format(root=str(ROOT), src=str(src), tjson=str(tjson), out=str(out))
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    ps = psutil.Process(proc.pid)
    peak_polled = 0
    while proc.poll() is None:
        try:
            peak_polled = max(peak_polled, ps.memory_info().rss)
        except psutil.NoSuchProcess:
            break
        time.sleep(0.05)
    stdout, stderr = proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"big rectification failed: {stderr[-2000:]}")
    elapsed, width, height, cell, hwm_kb = stdout.split()[-5:]
    overviews_s = float(stdout.split("overviews_s")[1].split()[0])
    result = {"make_s": t_make, "elapsed_s": float(elapsed), "overviews_s": overviews_s,
              "width": int(width),
              "height": int(height), "cell": float(cell),
              "peak_rss_mb": int(hwm_kb) / 1024.0, "peak_polled_mb": peak_polled / 2**20,
              "input_mb": src.stat().st_size / 2**20, "output_mb": out.stat().st_size / 2**20}
    for path in (src, out, tjson):
        path.unlink(missing_ok=True)
    return result


# -- report -------------------------------------------------------------------------------------
def machine_lines(load: str) -> list[str]:
    import cv2
    import rasterio
    import skimage

    return [f"- machine: {machine_facts()}",
            f"- OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), rasterio "
            f"{rasterio.__version__} / GDAL {rasterio.__gdal_version__}, scikit-image "
            f"{skimage.__version__}",
            f"- {load}; OPENBLAS_NUM_THREADS="
            f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}"]


def fmt(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    return f"{seconds * 1e3:.2f} ms" if seconds < 1 else f"{seconds:.2f} s"


def estimation_single_thread_blas() -> list[dict]:
    """The estimation rows again in a subprocess with OPENBLAS_NUM_THREADS=1 (small SVDs and
    least squares suffer badly from BLAS threads on a busy 2-core machine)."""
    import json

    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, __file__, "--estimation-json"], env=env,
                          capture_output=True, text=True, check=True)
    rows = json.loads(proc.stdout.strip().splitlines()[-1])
    for row in rows:
        row["case"] += " [BLAS 1 thread]"
    return rows


def main(argv: list[str] | None = None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-big", action="store_true", help="skip the 16644 x 16644 case")
    parser.add_argument("--estimation-json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args([] if argv is None else argv)  # run_all.py calls main()
    if args.estimation_json:
        import json

        print(json.dumps(bench_estimation()))
        return ""
    load = load_note()
    folder = Path(tempfile.mkdtemp(prefix="rectify_bench_", dir=os.environ.get("BENCH_TMP")))
    try:
        rows = bench_estimation() + estimation_single_thread_blas()
        data = synthetic_rgb(4000, 3000)
        rows += bench_memory(data)
        rows += bench_files(data, folder)
        big = None if args.no_big else bench_big(folder)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    lines = ["## Rectification (issue 4): estimation and warping", "", *machine_lines(load), "",
             "| case | ours | peer | peer time | ratio (ours / peer) | notes |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        ratio = f"{r['ours'] / r['peer']:.2f}" if r["peer"] else "-"
        lines.append(f"| {r['case']} | {fmt(r['ours'])} | {r['peer_name']} | {fmt(r['peer'])} | "
                     f"{ratio} | {r['extra']} |")
    lines.append("")
    if big is not None:
        lines += ["### 16644 x 16644 RGB scan (bounded memory)", "",
                  "| input | output | wall time | peak RSS (VmHWM) | peak RSS (polled, 20 Hz) | "
                  "target |", "|---|---|---|---|---|---|",
                  f"| {16644} x {16644} RGB tiled GeoTIFF, {big['input_mb']:.0f} MB on disk "
                  f"(written in {big['make_s']:.0f} s) | {big['width']} x {big['height']} RGBA, "
                  f"cell {big['cell']:g} m, {big['output_mb']:.0f} MB, with overviews | "
                  f"{big['elapsed_s']:.1f} s (of which overviews {big['overviews_s']:.0f} s) | "
                  f"{big['peak_rss_mb']:.0f} MB | "
                  f"{big['peak_polled_mb']:.0f} MB | < 1536 MB |", "",
                  "For comparison, holding that scan and its output in memory (as one "
                  f"`cv2.warpPerspective` call needs) takes {16644 ** 2 * 3 / 2**20:.0f} MB + "
                  f"{big['width'] * big['height'] * 4 / 2**20:.0f} MB.", ""]
    # duplicate-ok: every bench script closes with its method note and write_results
    lines += ["Ratios below 1 mean ours is faster. The in-memory rows give both sides "
              "band-sequential arrays as rasterio reads and writes them (OpenCV then needs "
              "`cv2.merge`/`cv2.split`); the file rows write the same tiled DEFLATE GeoTIFF "
              "(RGB + alpha), without overviews on either side. The rows marked [BLAS 1 thread] "
              "ran with OPENBLAS_NUM_THREADS=1: on a busy 2-core machine OpenBLAS threads make "
              "small SVDs and least-squares solves up to ~100x slower.", ""]
    return write_results(RESULTS, lines)


if __name__ == "__main__":
    main(sys.argv[1:])
