"""Mosaic benchmark: a least-cost seamline over a big overlap (time, peak memory), the same seam
next to OpenCV's DpSeamFinder and GraphCutSeamFinder on the same pair, and the mosaic of 6
orthos next to gdalwarp with -cutline and -cblend (the GDAL way), in one run.

    .venv/bin/python bench/mosaic_bench.py            # full size: 10000 x 10000 overlap, 6 x 5000²
    .venv/bin/python bench/mosaic_bench.py --small    # quick check: 2000² overlap, 6 x 1000²

Data: synthetic 3-band orthos of one ground texture (toolbox.demo.samples.mosaic.texture, 1 m
cells, EPSG:3003), written window by window. Every measurement runs in its own subprocess (this
script with ``--case``), so its peak memory (VmHWM) is its own; times are end to end through
``toolbox.run`` (read, trace footprints, route or mosaic, write). OpenCV's seam finders get the
two orthos as float32 images in memory, placed at their offsets (reading excluded), at a size
they handle (overlap at most OPENCV_MAX cells a side; our seam is timed at that size too).
gdalwarp warps each ortho into one output with its own cut polygon (``-cutline seams.gpkg
-cwhere source_id=k -cblend W``, alpha compositing), the cut polygons being the toolbox's.
Writes bench/results/mosaic.md.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, peak_rss_mb, run_measured

HERE = Path(__file__).resolve().parent
X0, Y0 = 1_688_000.0, 4_799_000.0
CRS = "EPSG:3003"
OPENCV_MAX = 1000
FEATHER = 20.0


def write_ortho(path: Path, x0: float, y0: float, cols: int, rows: int, gain: float = 1.0,
                offset: float = 0.0, alpha: bool = False, block: int = 1024) -> None:
    """A 1 m ortho of the shared texture with a bright 'building' every 250 m, by windows."""
    import rasterio
    from affine import Affine
    from rasterio.windows import Window

    from toolbox.demo.samples.mosaic import texture

    profile = {"driver": "GTiff", "width": cols, "height": rows, "count": 4 if alpha else 3,
               "dtype": "uint8", "crs": CRS, "transform": Affine(1, 0, X0 + x0, 0, -1, Y0 + y0 + rows),
               "tiled": True, "blockxsize": 512, "blockysize": 512, "compress": "deflate",
               "nodata": None if alpha else 0, "bigtiff": "if_safer"}
    with rasterio.open(path, "w", **profile) as dst:
        for r in range(0, rows, block):
            h = min(block, rows - r)
            ys = y0 + rows - (r + np.arange(h) + 0.5)
            xs = x0 + np.arange(cols) + 0.5
            gx, gy = np.meshgrid(xs, ys)
            img = texture(gx, gy)
            roof = ((gx % 250) < 30) & ((gy % 250) < 30)  # relief-displaced roofs differ per ortho
            shift = (gx + 7 * x0 / 1000) % 250 < 30
            img[:, roof & shift] = 245
            data = np.clip(np.rint(gain * img + offset), 1, 255).astype("uint8")
            if alpha:
                data = np.concatenate([data, np.full((1, h, cols), 255, "uint8")])
            dst.write(data, window=Window(0, r, cols, h))


def make_pair(work: Path, n: int) -> list[Path]:
    """Two orthos whose overlap is n x n cells (each 1.25 n wide)."""
    m = n // 4
    paths = [work / "pair_a.tif", work / "pair_b.tif"]
    write_ortho(paths[0], 0, 0, n + m, n)
    write_ortho(paths[1], m, 0, n + m, n, gain=1.05, offset=-4, alpha=True)
    return paths


def make_block(work: Path, n: int) -> list[Path]:
    """Six n x n orthos, 3 columns x 2 rows, overlapping by 30 % across and 20 % along."""
    paths = []
    for row in range(2):
        for col in range(3):
            p = work / f"block_{row}{col}.tif"
            write_ortho(p, col * int(0.7 * n), row * int(0.8 * n), n, n,
                        gain=1 + 0.03 * (col - row), offset=2 * col, alpha=(row + col) % 2 == 1)
            paths.append(p)
    return paths


def run_case(name: str, work: Path, n: int) -> dict:
    import toolbox

    if name == "seam":
        paths = sorted(work.glob("pair_*.tif"))
        toolbox.run("mosaic:seamlines", {"INPUT": [str(p) for p in paths], "METHOD": "voronoi",
                                         "OUTPUT": str(work / "warm.gpkg")}, overwrite=True)
        t0 = time.perf_counter()
        out = toolbox.run("mosaic:seamlines", {"INPUT": [str(p) for p in paths],
                                               "OUTPUT": str(work / f"seam_{n}.gpkg")},
                          overwrite=True)
        seconds = time.perf_counter() - t0
        return {"seconds": seconds, "peak_mb": peak_rss_mb(),
                "method": out["STATISTICS"]["seams"][0]["method"]}
    if name == "opencv":
        return opencv_case(work, n)
    if name == "mosaic":
        paths = sorted(work.glob("block_*.tif"))
        seams = toolbox.run("mosaic:seamlines", {"INPUT": [str(p) for p in paths],
                                                 "METHOD": "voronoi",
                                                 "OUTPUT": str(work / "out_seams.gpkg")},
                            overwrite=True)
        t0 = time.perf_counter()
        toolbox.run("mosaic:build", {"INPUT": [str(p) for p in paths],
                                     "CUTLINES": seams["OUTPUT"], "BLEND": "feather",
                                     "FEATHER_WIDTH": FEATHER, "OVERVIEWS": False,
                                     "OUTPUT": str(work / "out_mosaic.tif")}, overwrite=True)
        return {"seconds": time.perf_counter() - t0, "peak_mb": peak_rss_mb()}
    raise SystemExit(f"unknown case {name}")


def opencv_case(work: Path, n: int) -> dict:
    """Our least-cost seam and OpenCV's two seam finders on the same overlap (n x n)."""
    import cv2
    import rasterio

    import toolbox

    paths = sorted(work.glob("pair_*.tif"))
    out = {}
    # a warm-up run first (imports of scipy.ndimage, skimage, geopandas), as OpenCV is imported
    # before its finders are timed
    for k in range(2):
        t0 = time.perf_counter()
        toolbox.run("mosaic:seamlines", {"INPUT": [str(p) for p in paths],
                                         "OUTPUT": str(work / f"cv_seam{k}.gpkg")},
                    overwrite=True)
        out["toolbox_least_cost"] = time.perf_counter() - t0
    with rasterio.open(paths[0]) as a, rasterio.open(paths[1]) as b:
        images = [s.read([1, 2, 3]) for s in (a, b)]
        corners = [(0, 0), (round(b.bounds.left - a.bounds.left), 0)]
    images = [np.ascontiguousarray(np.transpose(i, (1, 2, 0))).astype("float32") for i in images]
    # as in OpenCV's stitching pipeline: images placed at their corners, masks 255 where valid
    for label, finder in (("opencv_dp_color", cv2.detail_DpSeamFinder("COLOR")),
                          ("opencv_graphcut_color", cv2.detail_GraphCutSeamFinder("COST_COLOR"))):
        masks = [cv2.UMat(np.full(i.shape[:2], 255, np.uint8)) for i in images]
        t0 = time.perf_counter()
        finder.find(images, corners, masks)
        out[label] = time.perf_counter() - t0
    out["peak_mb"] = peak_rss_mb()
    return out


def measure(name: str, work: Path, n: int) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--case", name, "--work", str(work),
                           "--n", str(n)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"case {name} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def gdalwarp_mosaic(work: Path) -> dict | None:
    """The GDAL way: one gdalwarp per ortho into one output, each with its cut polygon."""
    exe = shutil.which("gdalwarp")
    if exe is None:
        return None
    import rasterio

    paths = sorted(work.glob("block_*.tif"))
    with rasterio.open(work / "out_mosaic.tif") as m:
        bounds, res = m.bounds, m.res[0]
    target = work / "gdal_mosaic.tif"
    target.unlink(missing_ok=True)
    total, peak = 0.0, 0.0
    for k, p in enumerate(paths):
        create = [] if k else ["-dstalpha", "-te", *map(str, bounds), "-tr", str(res), str(res),
                               "-co", "TILED=YES", "-co", "COMPRESS=DEFLATE"]
        cmd = [exe, "-q", "-cutline", str(work / "out_seams.gpkg"), "-cl", "cut_polygons",
               "-cwhere", f"source_id={k + 1}", "-cblend", str(FEATHER), *create,
               "-wo", "NUM_THREADS=2", str(p), str(target)]
        seconds, mb, code, err = run_measured(cmd)
        if code != 0:
            return {"error": f"{p.name}: {err[-300:]}"}
        total += seconds
        peak = max(peak, mb)
    return {"seconds": total, "peak_mb": peak}


def main(small: bool) -> str:
    import cv2
    import rasterio
    import skimage

    n_seam, n_ortho = (2000, 1000) if small else (10000, 5000)
    n_cv = min(OPENCV_MAX, n_seam)
    note = load_note()
    with tempfile.TemporaryDirectory(prefix="mosaic_bench_") as tmp:
        work = Path(tmp)
        big, cvw, blk = work / "big", work / "cv", work / "block"
        for d in (big, cvw, blk):
            d.mkdir()
        t0 = time.perf_counter()
        make_pair(big, n_seam)
        make_pair(cvw, n_cv)
        make_block(blk, n_ortho)
        generate = time.perf_counter() - t0
        seam = measure("seam", big, n_seam)
        cv = measure("opencv", cvw, n_cv)
        mosaic = measure("mosaic", blk, n_ortho)
        gdal = gdalwarp_mosaic(blk)
    lines = [
        "## Mosaics (`bench/mosaic_bench.py`)", "",
        machine_facts(f"OpenCV {cv2.__version__}", f"scikit-image {skimage.__version__}",
                      f"GDAL {rasterio.__gdal_version__}"), "",
        note, f"(synthetic data generated in {generate:.1f} s)", "",
        "| task | size | tool | time (s) | peak memory (MB) |",
        "|---|---|---|---:|---:|",
        f"| least-cost seamline (overview + corridor) | {n_seam} x {n_seam} overlap | "
        f"mosaic:seamlines | {seam['seconds']:.1f} | {seam['peak_mb']:.0f} |",
        f"| seam on one pair | {n_cv} x {n_cv} overlap | mosaic:seamlines least_cost (end to "
        f"end: read, footprints, route, write; after a warm-up) | {cv['toolbox_least_cost']:.2f} | |",
        f"| | | OpenCV DpSeamFinder COLOR | {cv['opencv_dp_color']:.2f} | |",
        f"| | | OpenCV GraphCutSeamFinder COST_COLOR | {cv['opencv_graphcut_color']:.2f} | "
        f"{cv['peak_mb']:.0f} (whole case) |",
        f"| mosaic, feather {FEATHER:g} m | 6 orthos of {n_ortho} x {n_ortho} | mosaic:build | "
        f"{mosaic['seconds']:.1f} | {mosaic['peak_mb']:.0f} |",
    ]
    if gdal is None:
        lines.append("| | | gdalwarp: not installed | | |")
    elif "error" in gdal:
        lines.append(f"| | | gdalwarp failed: {gdal['error']} | | |")
    else:
        lines.append(f"| | | gdalwarp -cutline -cblend (6 runs) | {gdal['seconds']:.1f} | "
                     f"{gdal['peak_mb']:.0f} |")
    text = "\n".join(lines) + "\n"
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / ("mosaic_small.md" if small else "mosaic.md")).write_text(text)
    return text


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case")
    parser.add_argument("--work")
    parser.add_argument("--n", type=int, default=0)
    parser.add_argument("--small", action="store_true")
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_case(args.case, Path(args.work), args.n)))
    else:
        print(main(args.small))
