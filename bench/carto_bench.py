"""Cartography benchmark: carto:contours against gdal_contour (speed, and line-by-line agreement)
and dem:slope / dem:aspect / dem:hillshade against gdaldem, on the demo's real relief.

    .venv/bin/python bench/carto_bench.py            # 4x the demo DEM: 1376 x 1612 cells, 1 m
    .venv/bin/python bench/carto_bench.py --small    # the demo DEM itself: 344 x 403, 4 m

Data: matplotlib's jacksboro DEM as in the demo (toolbox/demo/samples/terrain.py), enlarged by
cubic spline interpolation for the full size. Toolbox times are ``toolbox.run`` in this process
after a warm-up (imports and registry loaded), reading and writing files as the CLI does;
GDAL times are the whole command; the terrain rows also give ``toolbox run``'s whole
process. Agreement: the share of each contour set's length within 1 mm of the other's lines of
the same level (gdal_contour's lines are clipped to the cell-centre
extent: it runs them on half a cell to the raster edge). Writes bench/results/carto.md.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, run_measured

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def make_dem(path: Path, factor: int) -> tuple[int, int]:
    from affine import Affine
    from scipy.ndimage import zoom

    sys.path.insert(0, str(ROOT))
    from toolbox.demo.samples.terrain import CELL, CRS, XMIN, YMAX, terrain
    from toolbox.raster.writer import write_raster

    z, _ = terrain()
    if factor > 1:
        z = zoom(z.astype("float64"), factor, order=3).astype("float32")
    cell = CELL / factor
    write_raster(path, z, Affine(cell, 0, XMIN, 0, -cell, YMAX), CRS, nodata=-9999.0)
    return z.shape


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import geopandas as gpd
    import rasterio

    import toolbox
    from toolbox.cartography.compare import contour_agreement

    note = f"{load_note()}; load average {os.getloadavg()[0]:.1f}"
    work = Path(tempfile.mkdtemp(prefix="carto_bench_"))
    try:
        dem = work / "dem.tif"
        rows, cols = make_dem(dem, 1 if args.small else 4)
        small = work / "warm.tif"
        make_dem(small, 1)
        toolbox.run("carto:contours", {"INPUT": small, "OUTPUT": work / "warm.gpkg"})
        toolbox.run("dem:slope", {"INPUT": small, "OUTPUT": work / "warm_slope.tif"})
        have_gdal = shutil.which("gdal_contour") and shutil.which("gdaldem")
        tools = subprocess.run(["gdalinfo", "--version"], capture_output=True, text=True
                               ).stdout.strip().split(",")[0] if have_gdal else "no GDAL tools"
        facts = machine_facts(f"rasterio's GDAL {rasterio.__gdal_version__}",
                              f"command-line {tools}")
        lines = [f"## Cartography (`bench/carto_bench.py{' --small' if args.small else ''}`)",
                 "", f"{facts}. {note}.", "",
                 f"DEM {cols} x {rows} cells (the demo relief{'' if args.small else ', 4x'}).",
                 ""]
        # contours
        interval = 1.0
        tiles = 256
        t_ours = timed(lambda: toolbox.run("carto:contours", {
            "INPUT": dem, "INTERVAL": interval, "TILE_SIZE": tiles,
            "OUTPUT": work / "ours.gpkg"}))
        ours = gpd.read_file(work / "ours.gpkg", layer="contours")
        lines += ["| contours, 1 m interval | seconds | lines | agreement (length within 1 mm) |",
                  "|---|---|---|---|",
                  f"| carto:contours ({tiles}-cell tiles, stitched) | {t_ours:.2f} | {len(ours)} "
                  "| - |"]
        if have_gdal:
            secs, _, code, err = run_measured(["gdal_contour", "-q", "-i", str(interval), "-a",
                                               "elev", str(dem), str(work / "gdal.gpkg")])
            if code:
                raise RuntimeError(err)
            gdal = gpd.read_file(work / "gdal.gpkg")
            with rasterio.open(dem) as src:
                t, w, h = src.transform, src.width, src.height
            half = t.a / 2
            box = (t.c + half, t.f + t.e * h + half, t.c + t.a * w - half, t.f - half)
            agree = contour_agreement(ours, gdal, 0.001, clip=box)
            lines.append(f"| gdal_contour | {secs:.2f} | {len(gdal)} | ours "
                         f"{100 * agree['ours_matched']:.2f}%, gdal "
                         f"{100 * agree['reference_matched']:.2f}% |")
            lines.append(f"| ratio gdal / ours | {secs / t_ours:.2f} | | |")
        lines += ["", "| terrain | toolbox s (in process / whole `toolbox run`) | gdaldem s "
                  "| max difference (interior) |", "|---|---|---|---|"]
        cli = str(Path(sys.executable).with_name("toolbox"))
        cases = [("slope", "dem:slope", [], "degrees"), ("aspect", "dem:aspect", [], "degrees"),
                 ("hillshade", "dem:hillshade", [], "grey levels")]
        for mode, alg, flags, unit in cases:
            out = work / f"{mode}.tif"
            t_alg = timed(lambda alg=alg, out=out: toolbox.run(alg, {"INPUT": dem, "OUTPUT": out,
                                                                     "OVERVIEWS": False}))
            t_cli, _, code, err = run_measured([cli, "run", alg, "--overwrite", "--INPUT",
                                                str(dem), "--OVERVIEWS", "false", "--OUTPUT",
                                                str(work / f"{mode}_cli.tif")])
            if code:
                raise RuntimeError(err)
            ours = f"{t_alg:.2f} / {t_cli:.2f}"
            if not have_gdal:
                lines.append(f"| {alg} | {ours} | (gdaldem missing) | |")
                continue
            ref = work / f"gdal_{mode}.tif"
            secs, _, code, err = run_measured(["gdaldem", mode, "-q", str(dem), str(ref), *flags])
            with rasterio.open(out) as a, rasterio.open(ref) as b:
                x = a.read(1).astype("float64")[1:-1, 1:-1]
                y = b.read(1).astype("float64")[1:-1, 1:-1]
            if mode == "aspect":
                d = np.abs((x - y + 180) % 360 - 180)[(x >= 0) & (y >= 0)]
                diff = f"{np.percentile(d, 99.9):.4f} (99.9th percentile) {unit}"
            else:
                diff = f"{np.abs(x - y).max():.4f} {unit}"
            lines.append(f"| {alg} vs gdaldem {mode} | {ours} | {secs:.2f} | {diff} |")
        text = "\n".join(lines) + "\n"
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "carto.md").write_text(text)
        print(text)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
