"""The 5 % rule of the house issue (#26): a few bench rows, whole process, for two checkouts of
the toolbox side by side in one interleaved sitting.

    .venv/bin/python bench/house_bench.py --prepare WORK
    .venv/bin/python bench/house_bench.py --work WORK --before PYTHON_A --after PYTHON_B [--repeat 5]
        [--only "COG false|TILE_SIZE 1024|hillshade"]   # rows whose name holds one of these

``--prepare`` writes the inputs with this checkout: 100,000 points (dem_bench's analytic surface
over its 2 km square, EPSG:3003), a 2 m DEM of 2200 x 2200 cells (ortho_bench's hills), the
12 Mpx rectify photo and homography of rectify_bench, ortho_bench's 4000 px photo, DEM and
project. Each row then runs ``PYTHON -m toolbox.cli run ...`` in a fresh process for the
checkout whose interpreter (a venv of its own: the registry of older checkouts reads its
algorithms from the package's entry points) is given; the two checkouts alternate run by run,
after one warm-up run each (numba's caches filled). Wall seconds and CPU seconds (user + system
of the child and its threads, from ``os.wait4``) are reported as medians, with the load average
before and after the sitting. Writes bench/results/house_sitting.md (bench/results/house.md
holds the sittings of the round and their reading).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

RESULTS = HERE / "results" / "house_sitting.md"  # (house.md: the sittings and their reading)


def prepare(work: Path) -> None:
    """The inputs of every row, written with this checkout."""
    import dem_bench
    import numpy as np
    import ortho_bench
    import rasterio
    import rectify_bench

    from toolbox.io.raster import geotiff_profile
    from toolbox.photogrammetry.synthetic import hills_dem
    from toolbox.raster.writer import write_raster

    work.mkdir(parents=True, exist_ok=True)
    dem_bench.make_data(work, 100_000)
    z, transform = hills_dem(ortho_bench.BOUNDS, cell=2.0, relief=200.0, base=250.0, seed=3)
    write_raster(work / "dem2m.tif", z.astype("float32"), transform, ortho_bench.CRS,
                 nodata=-9999.0)
    ortho_bench.write_inputs(work, 4000)
    width, height, p2g, grid = rectify_bench.scene_12mpx()
    with rasterio.open(work / "photo12.tif", "w", **geotiff_profile(
            width, height, 3, "uint8", None, None, photometric="RGB")) as dst:
        dst.write(rectify_bench.synthetic_rgb(width, height))
    (work / "t12.json").write_text(json.dumps({
        "format": "toolbox.rectify.transform", "version": 1, "model": "homography",
        "image_units": "pixels", "image_to_ground": np.asarray(p2g).tolist(), "crs": None,
        "points": []}))
    (work / "rectify_grid.json").write_text(json.dumps(
        {"cell": grid.transform.a, "bounds": list(grid.bounds)}))


def commands(work: Path) -> dict[str, list[str]]:
    """Row name -> ``toolbox run`` arguments (the same for both checkouts)."""
    import ortho_bench

    rect = json.loads((work / "rectify_grid.json").read_text())
    out = work / "out"
    x0, y0, x1, y1 = ortho_bench.BOUNDS
    return {
        "dem:idw 100k points -> 632 x 632": [
            "dem:idw", "--INPUT", str(work / "points.gpkg"), "--Z_FIELD", "z",
            "--CELL_SIZE", str(2000.0 / 632), "--NEIGHBOURS", "12", "--POWER", "2",
            "--RADIUS", "12", "--OVERVIEWS", "false", "--OUTPUT", str(out / "idw.tif")],
        "dem:hillshade 2200 x 2200": [
            "dem:hillshade", "--INPUT", str(work / "dem2m.tif"), "--OVERVIEWS", "false",
            "--OUTPUT", str(out / "hillshade.tif")],
        "carto:contours 2200 x 2200, 10 m": [
            "carto:contours", "--INPUT", str(work / "dem2m.tif"), "--INTERVAL", "10",
            "--OUTPUT", str(out / "contours.gpkg")],
        "carto:contours 2200 x 2200, 10 m, TILE_SIZE 1024": [
            "carto:contours", "--INPUT", str(work / "dem2m.tif"), "--INTERVAL", "10",
            "--TILE_SIZE", "1024", "--OUTPUT", str(out / "contours.gpkg")],
        "rectify:image 12 Mpx RGB, bilinear": [
            "rectify:image", "--INPUT", str(work / "photo12.tif"), "--TRANSFORM",
            str(work / "t12.json"), "--CELL_SIZE", repr(rect["cell"]), "--EXTENT",
            ",".join(map(repr, rect["bounds"])), "--RESAMPLING", "bilinear",
            "--OVERVIEWS", "false", "--OUTPUT", str(out / "rectified.tif")],
        "rectify:image 12 Mpx RGB, bilinear, COG false": [
            "rectify:image", "--INPUT", str(work / "photo12.tif"), "--TRANSFORM",
            str(work / "t12.json"), "--CELL_SIZE", repr(rect["cell"]), "--EXTENT",
            ",".join(map(repr, rect["bounds"])), "--RESAMPLING", "bilinear", "--COG", "false",
            "--OVERVIEWS", "false", "--OUTPUT", str(out / "rectified.tif")],
        "ortho:photo 4000 px photo, 1 m": [
            "ortho:photo", "--INPUT", str(work / "photo4000.tif"), "--PROJECT",
            str(work / "project4000.yaml"), "--DEM", str(work / "dem.tif"), "--CELL_SIZE", "1",
            "--EXTENT", f"{x0},{y0},{x1},{y1}", "--OVERVIEWS", "false",
            "--OUTPUT", str(out / "ortho.tif")],
    }


def run_once(python: str, args: list[str], env: dict) -> tuple[float, float]:
    """(wall s, CPU s) of one ``python -m toolbox.cli run --overwrite ...`` process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([python, "-m", "toolbox.cli", "run", "--overwrite", *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    stderr = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{python} {args[0]} failed ({proc.returncode}): "
                           f"{stderr.decode(errors='replace')[-800:]}")
    return wall, usage.ru_utime + usage.ru_stime


def sitting(work: Path, pythons: dict[str, str], repeat: int, only: str | None = None
            ) -> list[str]:
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "0"}
    env.pop("PYTHONPATH", None)
    (work / "out").mkdir(exist_ok=True)
    load_before = Path("/proc/loadavg").read_text().split()[:3]
    rows = []
    for name, args in commands(work).items():
        if only is not None and not any(part in name for part in only.split("|")):
            continue
        times: dict[str, list[tuple[float, float]]] = {k: [] for k in pythons}
        for python in pythons.values():  # warm-up: numba caches, page cache
            run_once(python, args, env)
        for _ in range(repeat):
            for label, python in pythons.items():
                times[label].append(run_once(python, args, env))
        med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
               for k, v in times.items()}
        a, b = list(pythons)
        rows.append((name, med[a], med[b], Path("/proc/loadavg").read_text().split()[0]))
        print(name, med, flush=True)
    load_after = Path("/proc/loadavg").read_text().split()[:3]
    a, b = list(pythons)
    lines = ["| row | wall before | wall after | CPU before | CPU after | CPU after / before "
             "| load (1 min) |", "|---|---|---|---|---|---|---|"]
    for name, ma, mb, load in rows:
        lines.append(f"| {name} | {ma[0]:.2f} | {mb[0]:.2f} | {ma[1]:.2f} | {mb[1]:.2f} | "
                     f"{mb[1] / ma[1]:.3f} | {load} |")
    return [f"Load average before the sitting {' '.join(load_before)}, after "
            f"{' '.join(load_after)}; medians of {repeat} interleaved runs per checkout "
            f"(after one warm-up each); seconds.", "", *lines]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--prepare", type=Path)
    parser.add_argument("--work", type=Path)
    parser.add_argument("--before")
    parser.add_argument("--after")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--only", help="rows whose name holds one of these |-separated parts")
    args = parser.parse_args()
    if args.prepare:
        prepare(args.prepare)
        return
    from benchlib import machine_facts, write_results

    lines = sitting(args.work, {"before": args.before, "after": args.after}, args.repeat,
                     args.only)
    write_results(RESULTS, ["## House: the 5 % rule, one interleaved sitting", "",
                            f"Machine: {machine_facts()}. before: {args.before}; after: "
                            f"{args.after}.", "", *lines])


if __name__ == "__main__":
    main()
