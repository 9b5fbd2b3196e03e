"""Mosaic benchmark: a least-cost seamline over a big overlap (time, peak memory), the same seam
next to OpenCV's DpSeamFinder and GraphCutSeamFinder on the same pair, and the mosaic of 6
orthos next to gdalwarp with -cutline and -cblend (the GDAL way), in one run.

    .venv/bin/python bench/mosaic_bench.py            # full size: 10000 x 10000 overlap, 6 x 5000²
    .venv/bin/python bench/mosaic_bench.py --small    # quick check: 2000² overlap, 6 x 1000²
    .venv/bin/python bench/mosaic_bench.py --seam-only  # only the one-seam comparison section

Data: synthetic 3-band orthos of one ground texture (toolbox.demo.samples.mosaic.texture, 1 m
cells, EPSG:3003), written window by window. Every measurement runs in its own subprocess (this
script with ``--case``), so its peak memory (VmHWM) is its own; times are end to end through
``toolbox.run`` (read, trace footprints, route or mosaic, write). OpenCV's seam finders get the
two orthos as float32 images in memory, placed at their offsets, at a size they handle (overlap
at most OPENCV_MAX cells a side). The one-seam comparison (:func:`seam_compare_case`) times, in
one process, interleaved, REPEATS times each: (a) the kernels on the same arrays (ours: cost
surface + centre term + route over the overlap; DpSeamFinder COLOR: its own cost + route over
the two placed images), (b) end to end (ours: ``toolbox.run`` of mosaic:seamlines, reading,
footprints, route, split, seamlines, GeoPackage; OpenCV: reading both GeoTIFFs with their masks
+ DpSeamFinder, nothing written). Seam quality is measured on the overlap for each result (see
:func:`seam_quality`).
gdalwarp warps each ortho into one output with its own cut polygon (``-cutline seams.gpkg
-cwhere source_id=k -cblend W``, alpha compositing), the cut polygons being the toolbox's.
Writes bench/results/mosaic.md (``--small``: mosaic_small.md): its generated parts only,
between their marker comments (``<!-- mosaic_bench: seam_times (generated: ...) -->`` to
``<!-- /mosaic_bench: seam_times (end; ...) -->``); the notes written there after a sitting,
outside the markers (under an end marker), are kept.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, peak_rss_mb, rewrite_generated, run_measured

HERE = Path(__file__).resolve().parent
X0, Y0 = 1_688_000.0, 4_799_000.0
CRS = "EPSG:3003"
OPENCV_MAX = 1000
REPEATS = 7
BUILDING_HEIGHT = 10.0  # metres, of the bench's buildings in the HEIGHTS raster
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


def buildings_on(x0: float, y0: float, cols: int, rows: int) -> np.ndarray:
    """The bench's building squares (30 m every 250 m, :func:`write_ortho`) on a 1 m grid whose
    top-left corner is (x0, y0 + rows) in local coordinates: the truth the seam should avoid."""
    gx = x0 + np.arange(cols) + 0.5
    gy = y0 + rows - (np.arange(rows) + 0.5)
    return ((gy[:, None] % 250) < 30) & ((gx[None, :] % 250) < 30)


def write_heights(path: Path, n: int) -> None:
    """DSM - DEM over the pair: BUILDING_HEIGHT on the buildings, 0 elsewhere (float32)."""
    import rasterio
    from affine import Affine

    cols = n + 2 * (n // 4)
    data = np.where(buildings_on(0, 0, cols, n), BUILDING_HEIGHT, 0.0).astype("float32")
    with rasterio.open(path, "w", driver="GTiff", width=cols, height=n, count=1,
                       dtype="float32", crs=CRS, transform=Affine(1, 0, X0, 0, -1, Y0 + n)) as dst:
        dst.write(data, 1)


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
    if name == "seam_compare":
        return seam_compare_case(work, n)
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


def seam_quality(owner_a: np.ndarray, a: np.ndarray, b: np.ndarray, cost: np.ndarray,
                 buildings: np.ndarray) -> dict:
    """Quality of a seam given as the cells ``owner_a`` (rows, cols) of the overlap that take
    ortho a (the others take b): over the seam's cell edges (4-neighbours of different owners),
    ``colour``: the mean over edges of |a - b| (mean of bands, grey levels, average of the two
    cells), what a viewer sees as a seam and what DpSeamFinder COLOR minimises; ``cost``: the
    mean of our cost surface (the two cells' mean); ``edges``: the seam's length in cell edges;
    ``on_buildings``: edges with a building cell on either side (known from the generator)."""
    pairs = []
    d = np.abs(a - b).mean(axis=0)
    fit = np.abs(a - balanced(a, b)).mean(axis=0)
    for sl_p, sl_q in (((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
                       ((slice(None, -1), slice(None)), (slice(1, None), slice(None)))):
        cut = owner_a[sl_p] != owner_a[sl_q]
        pairs.append((d[sl_p][cut], d[sl_q][cut], fit[sl_p][cut], fit[sl_q][cut],
                      cost[sl_p][cut], cost[sl_q][cut], buildings[sl_p][cut] | buildings[sl_q][cut]))
    dp, dq, fp, fq, cp, cq, on = (np.concatenate(x) for x in zip(*pairs, strict=True))
    return {"edges": int(dp.size), "colour": float(np.mean(0.5 * (dp + dq))),
            "balanced": float(np.mean(0.5 * (fp + fq))),
            "cost": float(np.mean(0.5 * (cp + cq))), "on_buildings": int(on.sum())}


def balanced(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``b`` with a least-squares gain and offset per band mapping it onto ``a`` over the
    overlap (what mosaic:build's balancing removes before anyone sees the seam)."""
    out = np.empty_like(b)
    for k in range(len(b)):
        x, y = b[k].ravel().astype("float64"), a[k].ravel().astype("float64")
        gain = np.cov(x, y)[0, 1] / np.var(x, ddof=1)
        out[k] = gain * b[k] + (y.mean() - gain * x.mean())
    return out


def path_owner(path: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The cells of ortho a (west of the path, the path itself included) of an 8-connected path
    from the top row to the bottom one (a barrier for 4-connected regions)."""
    from scipy import ndimage

    on = np.zeros(shape, bool)
    on[path[:, 0], path[:, 1]] = True
    regions, _ = ndimage.label(~on)
    west = np.setdiff1d(np.unique(regions[:, 0]), [0])
    return np.isin(regions, west) | on


def our_kernel(a: np.ndarray, b: np.ndarray, n: int, heights: np.ndarray | None = None):
    """Our routing kernel on the n x n overlap arrays: cost surface (+ centre term, + height
    term with HEIGHTS), route between the Voronoi seam's ends; returns (path, cost)."""
    from affine import Affine

    from toolbox.mosaic.seams import CostWeights, add_centre, cost_surface, route

    m = n // 4
    w = CostWeights()
    cost = cost_surface(a, b, w)
    centres = ((n + m) / 2, n / 2), (m + (n + m) / 2, n / 2)  # the footprint centres
    add_centre(cost, Affine(1, 0, m, 0, -1, n), *centres, w.centre)
    if heights is not None:
        cost += w.height * np.clip(heights - w.height_threshold, 0, None)
    return route(cost, (0, n // 2), (n - 1, n // 2)), cost


def read_pair(paths: list[Path]) -> tuple[list, list, list]:
    """What an OpenCV user reads: both orthos as (rows, cols, 3) float32 images, their masks
    (255 = valid) and their corners."""
    import rasterio

    images, masks, corners = [], [], []
    for p in paths:
        with rasterio.open(p) as src:
            images.append(np.ascontiguousarray(np.transpose(src.read([1, 2, 3]), (1, 2, 0)),
                                               dtype="float32"))
            masks.append(src.dataset_mask())
            corners.append((round(src.bounds.left - X0), 0))
    return images, masks, corners


def write_dp_polygons(paths: list[Path], masks: list, out: Path) -> None:
    """DpSeamFinder's masks (255 = the ortho's part, in each ortho's own frame) traced to
    polygons (rasterio.features.shapes) and written as one GeoPackage layer (pyogrio)."""
    import geopandas as gpd
    import rasterio
    import shapely
    from rasterio.features import shapes

    geoms = []
    for path, mask in zip(paths, masks, strict=True):
        part = mask.get() > 0
        with rasterio.open(path) as src:
            transform, crs = src.transform, src.crs
        polys = [shapely.geometry.shape(g) for g, v in shapes(part.astype("uint8"), mask=part,
                                                               transform=transform) if v]
        geoms.append(shapely.MultiPolygon(polys))
    frame = gpd.GeoDataFrame({"source": [p.stem for p in paths]}, geometry=geoms, crs=crs)
    out.unlink(missing_ok=True)
    frame.to_file(out, layer="cut_polygons", driver="GPKG")


def seam_compare_case(work: Path, n: int) -> dict:
    """The one-seam comparison (module docstring): timings interleaved, quality of each seam."""
    import cv2
    import geopandas as gpd
    from rasterio.features import rasterize

    import toolbox

    m = n // 4
    paths = sorted(work.glob("pair_*.tif"))
    write_heights(work / "heights.tif", n)
    images, masks, corners = read_pair(paths)
    a = np.ascontiguousarray(np.transpose(images[0][:, m:m + n], (2, 0, 1)))
    b = np.ascontiguousarray(np.transpose(images[1][:, :n], (2, 0, 1)))
    buildings = buildings_on(m, 0, n, n)
    heights = np.where(buildings, BUILDING_HEIGHT, 0.0)
    params = {"INPUT": [str(p) for p in paths], "OUTPUT": str(work / "e2e.gpkg")}

    def ours():
        return our_kernel(a, b, n)

    def dp(imgs=images, msks=masks):
        found = [cv2.UMat(k) for k in msks]
        cv2.detail_DpSeamFinder("COLOR").find(imgs, corners, found)
        return found

    def ours_e2e():
        toolbox.run("mosaic:seamlines", params, overwrite=True)

    def dp_e2e():
        return dp(*read_pair(paths)[:2])

    def dp_e2e_written():
        """What a user of OpenCV's seams must add for a deliverable like ours: each ortho's
        mask traced to its cut polygon and written to a GeoPackage."""
        write_dp_polygons(paths, dp(*read_pair(paths)[:2]), work / "dp_cut.gpkg")

    tasks = {"kernel_ours": ours, "kernel_dp": dp, "e2e_ours": ours_e2e, "e2e_dp": dp_e2e,
             "e2e_dp_written": dp_e2e_written}
    for task in tasks.values():  # warm-up: imports, compiled kernels, OpenCV's first call
        task()
    times = {k: {"wall": [], "cpu": []} for k in tasks}
    load = [os.getloadavg()[0]]
    for _ in range(REPEATS):
        for name, task in tasks.items():
            w0, c0 = time.perf_counter(), time.process_time()
            task()
            times[name]["wall"].append(time.perf_counter() - w0)
            times[name]["cpu"].append(time.process_time() - c0)
    load.append(os.getloadavg()[0])
    # quality, all measured on the same overlap and cost surface (ours, without heights)
    path, cost = ours()
    exact = route_exact(cost, (0, n // 2), (n - 1, n // 2))
    found = [k.get() for k in dp()]
    frame = gpd.read_file(work / "e2e.gpkg", layer="cut_polygons")
    poly_a = frame.geometry[list(frame["source"]).index("pair_a")]
    from affine import Affine

    grid = Affine(1, 0, X0 + m, 0, -1, Y0 + n)
    e2e_a = rasterize([poly_a], out_shape=(n, n), transform=grid, dtype="uint8") > 0
    height_params = {**params, "HEIGHTS": str(work / "heights.tif"),
                     "OUTPUT": str(work / "e2e_heights.gpkg")}
    toolbox.run("mosaic:seamlines", height_params, overwrite=True)
    frame = gpd.read_file(work / "e2e_heights.gpkg", layer="cut_polygons")
    poly_h = frame.geometry[list(frame["source"]).index("pair_a")]
    e2e_h = rasterize([poly_h], out_shape=(n, n), transform=grid, dtype="uint8") > 0
    gc = [cv2.UMat(k) for k in masks]
    w0, c0 = time.perf_counter(), time.process_time()
    cv2.detail_GraphCutSeamFinder("COST_COLOR").find(images, corners, gc)
    graphcut = {"wall": time.perf_counter() - w0, "cpu": time.process_time() - c0}
    owner = {"kernel_ours": path_owner(path, (n, n)),
             "kernel_ours_heights": path_owner(our_kernel(a, b, n, heights)[0], (n, n)),
             "exact_optimum": path_owner(exact, (n, n)),
             "kernel_dp": found[0][:, m:m + n] > 0,
             "graphcut": gc[0].get()[:, m:m + n] > 0,
             "e2e_ours": e2e_a, "e2e_ours_heights": e2e_h}
    from toolbox.mosaic.route import path_cost

    return {"times": times, "graphcut": graphcut, "load": load, "peak_mb": peak_rss_mb(),
            "path_cost": path_cost(cost, path), "exact_cost": path_cost(cost, exact),
            "quality": {k: seam_quality(v, a, b, cost, buildings) for k, v in owner.items()}}


def route_exact(cost: np.ndarray, start, end) -> np.ndarray:
    """The exact optimum by scikit-image's MCP_Geometric (the library our route is tested on)."""
    from skimage.graph import MCP_Geometric

    mcp = MCP_Geometric(cost, fully_connected=True)
    mcp.find_costs([start], [end])
    return np.asarray(mcp.traceback(end))


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


def seam_section(cv: dict, n: int) -> dict[str, list[str]]:
    """The markdown of the one-seam comparison, in two parts: ``seam_times`` (heading and
    table) and ``seam_quality`` (table and path cost); notes written under the timings' table,
    between the two, are kept by a rerun (:func:`benchlib.rewrite_generated`)."""
    t, q = cv["times"], cv["quality"]

    def med(name, kind):
        return float(np.median(t[name][kind]))

    def ratio(ours, peer, kind):
        return med(peer, kind) / med(ours, kind)

    lines = [
        f"### One seam, {n} x {n} overlap, next to OpenCV (in one process, interleaved, "
        f"medians of {REPEATS})", "",
        f"Load average (1 min) {cv['load'][0]:.1f} before, {cv['load'][1]:.1f} after, on "
        f"{os.cpu_count()} cores: wall times are stretched by other work, CPU times less so.", "",
        "| what | tool | includes | wall (s) | CPU (s) | ratio peer/ours wall, CPU |",
        "|---|---|---|---:|---:|---:|",
        f"| (a) kernel on the same arrays | ours | cost surface + centre term + route "
        f"(overlap {n} x {n}, coarse-to-fine) | {med('kernel_ours', 'wall'):.3f} | "
        f"{med('kernel_ours', 'cpu'):.3f} | |",
        f"| | OpenCV DpSeamFinder COLOR | its cost + route on the two placed images and masks "
        f"| {med('kernel_dp', 'wall'):.3f} | {med('kernel_dp', 'cpu'):.3f} | "
        f"{ratio('kernel_ours', 'kernel_dp', 'wall'):.2f}x, "
        f"{ratio('kernel_ours', 'kernel_dp', 'cpu'):.2f}x |",
        f"| (b) end to end | ours: `toolbox.run(\"mosaic:seamlines\")` | read, footprints, "
        f"Voronoi, cost, route, split, seamlines, GeoPackage written | "
        f"{med('e2e_ours', 'wall'):.3f} | {med('e2e_ours', 'cpu'):.3f} | |",
        f"| | OpenCV DpSeamFinder COLOR | read both GeoTIFFs and masks (rasterio) + find; "
        f"nothing written | {med('e2e_dp', 'wall'):.3f} | {med('e2e_dp', 'cpu'):.3f} | "
        f"{ratio('e2e_ours', 'e2e_dp', 'wall'):.2f}x, {ratio('e2e_ours', 'e2e_dp', 'cpu'):.2f}x |",
        f"| | OpenCV DpSeamFinder COLOR + its masks traced to cut polygons (rasterio "
        f"`shapes`) and written to a GeoPackage (geopandas) | the same + what a deliverable "
        f"needs | {med('e2e_dp_written', 'wall'):.3f} | {med('e2e_dp_written', 'cpu'):.3f} | "
        f"{ratio('e2e_ours', 'e2e_dp_written', 'wall'):.2f}x, "
        f"{ratio('e2e_ours', 'e2e_dp_written', 'cpu'):.2f}x |",
        f"| once | OpenCV GraphCutSeamFinder COST_COLOR | find on the placed images | "
        f"{cv['graphcut']['wall']:.2f} | {cv['graphcut']['cpu']:.2f} | |",
    ]
    quality = [
        "Seam quality on the overlap (each seam as the cells it gives to ortho a; per seam cell "
        "edge: colour = mean |a - b| of the two cells, grey levels, DpSeamFinder's own "
        "criterion; balanced = the same after a least-squares gain/offset of b onto a, what "
        "remains after mosaic:build's balancing; cost = our cost surface; buildings from the "
        "generator's truth):", "",
        "| seam | edges | mean colour difference | balanced | balanced, summed along the "
        "seam | mean cost (ours) | edges on buildings |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    names = {"kernel_ours": "ours, kernel", "exact_optimum": "exact optimum of our cost "
             "(scikit-image MCP_Geometric)", "e2e_ours": "ours, end to end (cut polygons)",
             "kernel_dp": "OpenCV DpSeamFinder COLOR", "graphcut": "OpenCV GraphCut COST_COLOR",
             "kernel_ours_heights": "ours, kernel, with heights (DSM - DEM)",
             "e2e_ours_heights": "ours, end to end, HEIGHTS given"}
    for key, label in names.items():
        r = q[key]
        quality.append(f"| {label} | {r['edges']} | {r['colour']:.2f} | {r['balanced']:.3f} | "
                       f"{r['balanced'] * r['edges']:.0f} | {r['cost']:.4f} | "
                       f"{r['on_buildings']} |")
    quality += ["", f"Our route's path cost {cv['path_cost']:.4f} against the exact optimum's "
              f"{cv['exact_cost']:.4f} (x {cv['path_cost'] / cv['exact_cost']:.6f}). Our seams "
              "must end where the Voronoi seam meets the footprint edges (here inside a building "
              "square at the overlap's south edge); OpenCV's may end anywhere on the overlap's "
              "border."]
    return {"seam_times": lines, "seam_quality": quality}


#: the marker tag of this bench's generated parts in its results file; the parts, in order:
#: the full run's ``summary`` (facts, table), ``seam_times`` and ``seam_quality``
TAG = "mosaic_bench"
PARTS = ("summary", "seam_times", "seam_quality")


def rewrite_results(old: str, parts: dict[str, list[str]]) -> str:
    """The results file's text ``old`` with the generated ``parts`` rewritten between their
    markers and everything else (the notes written after a sitting, under a table or between
    sections) kept as it is (:func:`benchlib.rewrite_generated`)."""
    return rewrite_generated(old, TAG, parts)


def main(small: bool, seam_only: bool = False) -> str:
    import cv2
    import rasterio
    import skimage

    n_seam, n_ortho = (2000, 1000) if small else (10000, 5000)
    n_cv = min(OPENCV_MAX, n_seam)
    note = load_note()
    target = HERE / "results" / ("mosaic_small.md" if small else "mosaic.md")
    title = "## Mosaics, small sizes (`bench/mosaic_bench.py --small`)" if small else \
        "## Mosaics (`bench/mosaic_bench.py`)"
    old = target.read_text() if target.exists() else title + "\n"
    rewrite_results(old, dict.fromkeys(PARTS, []))  # broken markers: refused before measuring
    with tempfile.TemporaryDirectory(prefix="mosaic_bench_") as tmp:
        work = Path(tmp)
        big, cvw, blk = work / "big", work / "cv", work / "block"
        for d in (big, cvw, blk):
            d.mkdir()
        t0 = time.perf_counter()
        make_pair(cvw, n_cv)
        if not seam_only:
            make_pair(big, n_seam)
            make_block(blk, n_ortho)
        generate = time.perf_counter() - t0
        cv = measure("seam_compare", cvw, n_cv)
        if not seam_only:
            seam = measure("seam", big, n_seam)
            mosaic = measure("mosaic", blk, n_ortho)
            gdal = gdalwarp_mosaic(blk)
    facts = machine_facts(f"OpenCV {cv2.__version__}", f"scikit-image {skimage.__version__}",
                          f"GDAL {rasterio.__gdal_version__}")
    parts = seam_section(cv, n_cv)
    old = target.read_text() if target.exists() else old  # notes written during the run too
    if seam_only:
        parts["seam_times"] = [facts, "", note, "", *parts["seam_times"]]
        text = rewrite_results(old, parts)
        (HERE / "results").mkdir(exist_ok=True)
        target.write_text(text)
        return text
    lines = [
        facts, "",
        note, f"(synthetic data generated in {generate:.1f} s)", "",
        "| task | size | tool | time (s) | peak memory (MB) |",
        "|---|---|---|---:|---:|",
        f"| least-cost seamline (overview + corridor) | {n_seam} x {n_seam} overlap | "
        f"mosaic:seamlines | {seam['seconds']:.1f} | {seam['peak_mb']:.0f} |",
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
    text = rewrite_results(old, {"summary": lines, **parts})
    (HERE / "results").mkdir(exist_ok=True)
    target.write_text(text)
    return text


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case")
    parser.add_argument("--work")
    parser.add_argument("--n", type=int, default=0)
    parser.add_argument("--small", action="store_true")
    parser.add_argument("--seam-only", action="store_true",
                        help="only the one-seam comparison (its section of the results file)")
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_case(args.case, Path(args.work), args.n)))
    else:
        print(main(args.small, args.seam_only))
