"""CPU of the toolbox's reads onto a grid in another CRS, for two checkouts side by side (house
issue #26, "one reprojection"): the raster engine's input tiles, the mosaic's source windows and
their masks, the ortho's DEM surface.

    .venv/bin/python bench/reproject_bench.py --prepare WORK
    .venv/bin/python bench/reproject_bench.py --work WORK --before SRC_A --after SRC_B \
        [--repeat 5]

``--prepare`` writes a 2000 x 2000 DEM (5 m, EPSG:3003, float32 with a nodata hole) and a
4000 x 4000 RGBA ortho (0.5 m, EPSG:3003, an alpha band). Each measure then runs this script
with ``--row`` in a fresh process with ``PYTHONPATH`` set to the checkout (SRC_A / SRC_B,
alternating run by run after one warm-up each); CPU seconds (user + system of the child and its
threads, ``os.wait4``) and wall seconds, medians. Rows: ``engine`` (read_window of the DEM onto
a 5 m UTM 32N grid of 1800 x 1800 cells, 512-cell tiles with a one-cell halo, bilinear),
``mosaic`` (read_window and read_valid of the ortho onto a 0.5 m UTM grid, 7 x 7 windows of 512
cells, bilinear), ``surface`` (the whole DEM onto GDAL's suggested UTM grid, bilinear:
ortho.plan.photo_surface's read).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROWS = ("engine", "mosaic", "surface")


def prepare(work: Path) -> None:
    import numpy as np
    import rasterio
    from affine import Affine

    work.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    yy, xx = np.mgrid[0:2000, 0:2000]
    z = (300 + 80 * np.sin(xx / 97.0) * np.cos(yy / 61.0)
         + rng.normal(0, 0.3, xx.shape)).astype("float32")
    z[900:1000, 700:900] = -9999
    with rasterio.open(work / "dem.tif", "w", driver="GTiff", width=2000, height=2000, count=1,
                       dtype="float32", crs="EPSG:3003", nodata=-9999, tiled=True,
                       compress="deflate", transform=Affine(5, 0, 1680000, 0, -5, 4800000)) as d:
        d.write(z, 1)
    rgba = rng.integers(0, 255, (4, 4000, 4000), dtype=np.uint8)
    rgba[3] = 255
    rgba[3, :, :300] = 0
    with rasterio.open(work / "ortho.tif", "w", driver="GTiff", width=4000, height=4000,
                       count=4, dtype="uint8", crs="EPSG:3003", photometric="RGB", alpha="YES",
                       tiled=True, compress="deflate",
                       transform=Affine(0.5, 0, 1680000, 0, -0.5, 4800000)) as d:
        d.write(rgba)


def utm(x: float, y: float):
    from pyproj import Transformer

    e, n = Transformer.from_crs(3003, 32632, always_xy=True).transform(x, y)
    return round(e), round(n)


def row(name: str, work: Path) -> None:
    import rasterio
    from affine import Affine
    from pyproj import CRS
    from rasterio.windows import Window

    crs = CRS.from_epsg(32632)
    if name == "engine":
        from toolbox.io.grid import GridSpec
        from toolbox.raster.engine import read_window
        from toolbox.raster.tile import iter_tiles

        e, n = utm(1680500, 4799500)
        grid = GridSpec(Affine(5, 0, e, 0, -5, n), 1800, 1800, crs)
        with rasterio.open(work / "dem.tif") as src:
            for tile in iter_tiles(grid, 512, 1):
                read_window(src, grid, tile.window, bands=1, halo=1, resampling="bilinear")
    elif name == "mosaic":
        from toolbox.mosaic.sources import open_source, read_valid, read_window

        e, n = utm(1680100, 4799900)
        t = Affine(0.5, 0, e, 0, -0.5, n)
        source = open_source(work / "ortho.tif", 0)
        for r in range(0, 3584, 512):
            for c in range(0, 3584, 512):
                read_window(source, t, "EPSG:32632", Window(c, r, 512, 512), "bilinear")
                read_valid(source, t, "EPSG:32632", Window(c, r, 512, 512))
    elif name == "surface":
        with rasterio.open(work / "dem.tif") as src:
            try:
                from toolbox.raster.reproject import default_grid, read_onto
            except ImportError:  # before: ortho.plan.photo_surface's WarpedVRT
                from rasterio.enums import Resampling
                from rasterio.vrt import WarpedVRT

                with WarpedVRT(src, crs=crs.to_wkt(), resampling=Resampling.bilinear) as vrt:
                    vrt.read(1, masked=True).astype("float64").filled(float("nan"))
            else:
                t, w, h = default_grid(src, crs)
                read_onto(src, t, w, h, crs, indexes=1)[0].astype("float64")


def measure(name: str, work: Path, source: str) -> tuple[float, float]:
    env = dict(os.environ, PYTHONPATH=source)
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--row", name, "--work", str(work)],
                            env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    if status:
        raise SystemExit(f"row {name} failed under {source}")
    return time.perf_counter() - start, usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--prepare", type=Path)
    parser.add_argument("--work", type=Path)
    parser.add_argument("--row", choices=ROWS)
    parser.add_argument("--before")
    parser.add_argument("--after")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    if args.prepare:
        prepare(args.prepare)
        return
    if args.row:
        row(args.row, args.work)
        return
    print(f"load before: {os.getloadavg()}")
    print("| row | wall before | wall after | CPU before | CPU after | CPU after / before |")
    print("|---|---|---|---|---|---|")
    for name in ROWS:
        times: dict[str, list] = {"before": [], "after": []}
        for k in range(args.repeat + 1):
            for which in ("before", "after"):
                result = measure(name, args.work, getattr(args, which))
                if k:  # the first run of each: warm-up
                    times[which].append(result)
        wb, cb = (statistics.median(x) for x in zip(*times["before"]))
        wa, ca = (statistics.median(x) for x in zip(*times["after"]))
        print(f"| {name} | {wb:.2f} | {wa:.2f} | {cb:.2f} | {ca:.2f} | {ca / cb:.3f} |",
              flush=True)
    print(f"load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
