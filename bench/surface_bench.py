"""Surface benchmark: reading and gridding a LAZ point cloud (beside PDAL's ``writers.gdal`` when
the ``pdal`` Python package and its library are installed: PyPI has no binary wheel), and the
StereoSGBM floor of dense matching (OpenCV alone on one synthetic epipolar pair, shifted by 32
pixels) beside the toolbox's matcher (``match_pair``: row strips and validity checks); and the
epipolar resampling of one noise "scan" of 4 x the pair side (``--pair 4161`` = 16644 px, the
film scans), by windows.

    .venv/bin/python bench/surface_bench.py --small      # 1 M points, 1000 x 1000 pair (quick)
    .venv/bin/python bench/surface_bench.py --points 10000000 --pair 4000

Every measurement runs in its own subprocess (this script with ``--case``), so its peak memory
(``VmHWM``) is its own. Data: uniform random points over 2 km x 2 km at the Siena coordinates
(EPSG:3003) on a smooth analytic surface, written as LAZ by the toolbox's writer; classes 2
(ground, 70 %) and 5. The toolbox grids the class-2 points by dem:nearest at 1 m; PDAL grids
the same class with ``filters.range`` + ``writers.gdal`` (output_type=idw, radius 1 m).
Writes the markdown table to bench/results/surface.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import machine_facts, peak_rss_mb, run_measured

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
X0, Y0, SIZE = 1_685_000.0, 4_795_000.0, 2_000.0
CRS = "EPSG:3003"


def make_laz(path: Path, n: int) -> None:
    from toolbox.io.pointcloud import write_point_cloud

    rng = np.random.default_rng(7)
    xyz = np.column_stack([rng.uniform(X0, X0 + SIZE, n), rng.uniform(Y0, Y0 + SIZE, n),
                           np.zeros(n)])
    u, v = (xyz[:, 0] - X0) / SIZE, (xyz[:, 1] - Y0) / SIZE
    xyz[:, 2] = 300.0 + 30.0 * np.sin(6.0 * u) * np.cos(4.0 * v)
    cls = np.where(rng.random(n) < 0.7, 2, 5)
    write_point_cloud(path, xyz, CRS, classification=cls)


def scan(path: Path, size: int) -> None:
    """A noise "scan" of ``size`` x ``size`` uint8 pixels, tiled, written by blocks of rows."""
    import rasterio

    rng = np.random.default_rng(5)
    profile = {"driver": "GTiff", "width": size, "height": size, "count": 1, "dtype": "uint8",
               "tiled": True, "blockxsize": 256, "blockysize": 256}
    with rasterio.open(path, "w", **profile) as ds:
        for r0 in range(0, size, 1024):
            rows = min(1024, size - r0)
            ds.write(rng.integers(0, 256, (1, rows, size), dtype=np.uint8),
                     window=rasterio.windows.Window(0, r0, size, rows))


def case(name: str, work: Path, pair: int) -> dict:
    t0 = time.perf_counter()
    if name == "read":
        from toolbox.io.pointcloud import PointFilter, open_point_cloud, read_xyz

        xyz, report = read_xyz(open_point_cloud(work / "cloud.laz"), PointFilter((2,)))
        extra = {"points_kept": report.kept}
    elif name == "grid":
        import toolbox

        toolbox.run("dem:nearest", {"INPUT": str(work / "cloud.laz"), "CLASSES": "2",
                                    "CELL_SIZE": 1.0, "OUTPUT": str(work / "toolbox.tif")})
        extra = {}
    elif name == "pdal":
        import pdal  # noqa: F401  (absent: the parent reports "not installed")

        spec = [str(work / "cloud.laz"), {"type": "filters.range", "limits": "Classification[2:2]"},
                {"type": "writers.gdal", "filename": str(work / "pdal.tif"), "resolution": 1.0,
                 "radius": 1.0, "output_type": "idw"}]
        pdal.Pipeline(json.dumps(spec)).execute()
        extra = {}
    elif name in ("sgbm", "match_pair"):
        import cv2

        rng = np.random.default_rng(3)
        left = cv2.GaussianBlur((rng.random((pair, pair + 64)) * 255).astype(np.uint8), (3, 3), 0)
        right = left[:, 32:32 + pair].copy()
        left = left[:, :pair].copy()
        t0 = time.perf_counter()
        if name == "sgbm":  # the floor: OpenCV alone, whole images
            sgbm = cv2.StereoSGBM.create(minDisparity=0, numDisparities=64, blockSize=5,
                                         P1=8 * 25, P2=32 * 25,
                                         mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
            disp = sgbm.compute(left, right) / 16.0
        else:  # the toolbox: strips of 1024 rows, left-right check, validity masks
            from toolbox.stereo.matching import match_pair

            ok = np.ones(left.shape, bool)
            disp = match_pair(left, right, ok, ok, 0, 64)
        extra = {"median_disparity": float(np.nanmedian(np.where(disp > 0, disp, np.nan)))}
    elif name == "epipolar":  # one normalised image of a scan-sized photo, by windows
        from toolbox.photogrammetry.camera import RadialDistortion
        from toolbox.photogrammetry.synthetic import frame_photo
        from toolbox.stereo.epipolar import epipolar_geometry, resample_image

        size = pair * 4
        photos = [frame_photo((X0 + dx, Y0, 1500.0), angles, width=size, height=size,
                              principal_distance_mm=153.0, crs=CRS, photo_id=pid,
                              distortion=RadialDistortion.from_polynomial(3e-7))
                  for dx, angles, pid in ((0.0, (0.01, -0.02, 0.03), "a"),
                                          (500.0, (-0.01, 0.01, -0.02), "b"))]
        geometry = epipolar_geometry(*photos)
        t0 = time.perf_counter()
        resample_image(geometry, photos[0], 0, work / "scan.tif", work / "epi.tif",
                       overviews=False)
        extra = {"size": size}
    else:
        raise SystemExit(f"unknown case {name}")
    return {"seconds": time.perf_counter() - t0, "peak_mb": peak_rss_mb(), **extra}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true", help="1 M points, 1000 x 1000 pair")
    ap.add_argument("--points", type=int, default=10_000_000)
    ap.add_argument("--pair", type=int, default=4000, help="side of the SGBM pair, pixels")
    ap.add_argument("--case")
    ap.add_argument("--work")
    args = ap.parse_args()
    if args.small:
        args.points, args.pair = 1_000_000, 1000
    if args.case:
        result = case(args.case, Path(args.work), args.pair)
        (Path(args.work) / f"{args.case}.json").write_text(json.dumps(result))
        return
    rows = []
    with tempfile.TemporaryDirectory(prefix="surface_bench_") as tmp:
        work = Path(tmp)
        t0 = time.perf_counter()
        make_laz(work / "cloud.laz", args.points)
        print(f"wrote {args.points:,} points in {time.perf_counter() - t0:.1f} s", flush=True)
        scan(work / "scan.tif", args.pair * 4)
        for name in ("read", "grid", "pdal", "sgbm", "match_pair", "epipolar"):
            cmd = [sys.executable, __file__, "--case", name, "--work", str(work),
                   "--pair", str(args.pair)]
            seconds, peak, code, err = run_measured(cmd)
            if code:
                last = err.strip().splitlines()[-1] if err.strip() else f"exit {code}"
                rows.append(f"| {name} | - | - | not run: {last} |")
            else:
                inner = json.loads((work / f"{name}.json").read_text())
                note = f"{inner['seconds']:.2f} s inside the process"
                if name == "epipolar":
                    note += f" (a {inner['size']} x {inner['size']} uint8 scan, bilinear)"
                if name in ("sgbm", "match_pair"):
                    note += f" ({args.pair} x {args.pair}, 64 disparities, median " \
                            f"{inner['median_disparity']:.2f} of 32)"
                rows.append(f"| {name} | {seconds:.1f} | {peak:.0f} | {note} |")
            print(rows[-1], flush=True)
    table = "\n".join([f"Points: {args.points:,}; {machine_facts()}", "",
                       "| case | seconds | peak MB | note |", "|---|---|---|---|", *rows])
    out = HERE / "results" / "surface.md"
    out.write_text(table + "\n")
    print(f"-> {out}")


if __name__ == "__main__":
    main()
