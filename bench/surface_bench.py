"""Surface benchmark: two 16644 x 16644 film scans to a 1 m DSM (dem:match) beside OpenCV's
StereoSGBM alone on the same epipolar images (the floor); reading and gridding a LAZ point
cloud beside the peers available here (laspy + numpy binning, cell by cell; PDAL's
``writers.gdal`` only where the ``pdal`` package and its library are installed: PyPI has no
binary wheel and Debian no package); the SGBM floor on a noise pair beside the toolbox's
matcher (``match_pair``: row strips and validity checks) and the epipolar resampling of one
noise "scan" of 4 x the pair side, by windows.

    .venv/bin/python bench/surface_bench.py --sections scans               # the scan pair
    .venv/bin/python bench/surface_bench.py --sections points --points 100000000 --grid-max 10000000
    .venv/bin/python bench/surface_bench.py --small                         # quick, all sections

Every measurement runs in its own subprocess (this script with ``--case``), so its peak memory
(``VmHWM``) is its own. Scans: the Siena pair 1_7150-1_7151 with its real orientations,
rendered at 1/8 on the demo's landscape (buildings standing) and upsampled to 16644 px (see
:func:`siena_scans`); the DSM is checked against that surface. Points: uniform random points
over 2 km x 2 km at the Siena coordinates (EPSG:3003) on a smooth analytic surface, written as
LAZ by chunks by the toolbox's writer; classes 2 (ground, 70 %) and 5. The toolbox grids the
class-2 points by dem:nearest at 1 m, streamed (``grid``: two chunked passes, per-tile buckets
on disk) and, up to ``--grid-max`` points, in memory (``grid_memory``: about 190 bytes a kept
point), and the two grids are compared cell for cell; the binning peer averages the same class
per 1 m cell. Prints the
markdown tables (bench/results/surface.md keeps them with notes).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import load_note, machine_facts, peak_rss_mb, run_measured

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
X0, Y0, SIZE = 1_685_000.0, 4_795_000.0, 2_000.0
CRS = "EPSG:3003"


def make_laz(path: Path, n: int, chunk: int = 5_000_000) -> None:
    """``n`` points written by chunks (never all in memory), each chunk seeded from its index."""
    from toolbox.io.pointcloud import PointCloudWriter

    with PointCloudWriter(path, np.array([X0, Y0, 0.0]), CRS) as writer:
        for k, start in enumerate(range(0, n, chunk)):
            m = min(chunk, n - start)
            rng = np.random.default_rng([7, k])
            x, y = rng.uniform(X0, X0 + SIZE, m), rng.uniform(Y0, Y0 + SIZE, m)
            u, v = (x - X0) / SIZE, (y - Y0) / SIZE
            z = 300.0 + 30.0 * np.sin(6.0 * u) * np.cos(4.0 * v)
            writer.write(np.column_stack([x, y, z]),
                         classification=np.where(rng.random(m) < 0.7, 2, 5))


def bin_mean(path: Path, cell: float = 1.0) -> np.ndarray:
    """The peer available here: laspy reading by chunks, numpy binning of the class-2 points
    (mean z per cell on the same 1 m grid as dem:nearest's over the points' bounds); memory is
    the grid plus one chunk. NaN where no point fell."""
    import laspy

    with laspy.open(path) as reader:
        h = reader.header
        x0, y1 = np.floor(h.mins[0] / cell) * cell, np.ceil(h.maxs[1] / cell) * cell
        cols = int(np.ceil((h.maxs[0] - x0) / cell))
        rows = int(np.ceil((y1 - h.mins[1]) / cell))
        total, count = np.zeros(rows * cols), np.zeros(rows * cols)
        for pts in reader.chunk_iterator(2_000_000):
            keep = np.asarray(pts.classification) == 2
            c = np.minimum(((np.asarray(pts.x)[keep] - x0) / cell).astype(np.int64), cols - 1)
            r = np.minimum(((y1 - np.asarray(pts.y)[keep]) / cell).astype(np.int64), rows - 1)
            flat = r * cols + c
            total += np.bincount(flat, np.asarray(pts.z)[keep], rows * cols)
            count += np.bincount(flat, None, rows * cols)
    with np.errstate(invalid="ignore"):
        return (total / count).reshape(rows, cols)


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


PAIR = ("1_7150", "1_7151")  # a stereo pair of the Siena block (real orientations, B/H 0.16)
SCAN = 16644  # px, the film scans' side
HEIGHTS = (280.0, 365.0)  # terrain 287-343 m, roofs up to 16 m above it


def siena_scans(work: Path, reduction: int = 8) -> Path:
    """Two 16644 x 16644 grey "scans" of the Siena pair with the real orientations, and their
    project (``scans/project.yaml``). Rendering 277 M rays a photo would take half an hour, so
    each photo is rendered through the collinearity equations at 1/``reduction`` of the scan
    (the landscape of the demo, buildings standing) and upsampled bilinearly to the scan's
    pixels (OpenCV, pixel centres kept): what the matcher sees is geometrically the scan."""
    from dataclasses import replace

    import cv2
    import rasterio

    from toolbox.demo.samples.landscape import landscape_surface, landscape_texture
    from toolbox.demo.samples.siena import BUNDLED
    from toolbox.photogrammetry.fiducials import InteriorOrientation
    from toolbox.photogrammetry.project import Project, load_project, save_project
    from toolbox.photogrammetry.synthetic import render_photo

    folder = work / "scans"
    folder.mkdir(exist_ok=True)
    project = load_project(BUNDLED / "siena_project.yaml")
    surface, transform = landscape_surface()
    paint = landscape_texture()
    small = SCAN // reduction
    scale = np.diag([float(reduction), float(reduction), 1.0])
    cameras, photos = {}, {}
    for pid in PAIR:
        photo = project.photo(pid)
        cam = photo.camera
        low = replace(photo, camera=replace(cam, image_size_px=(small, small),
                                            pixel_size_mm=cam.pixel_size_mm * reduction),
                      interior=InteriorOrientation(photo.interior.pixel_to_fiducial @ scale,
                                                   photo.interior.transformation))
        rgb = render_photo(low, surface, transform, paint, dtype="float32", fill=0.0)
        grey = np.clip(rgb.mean(axis=0), 0, 255).astype(np.uint8)
        full = cv2.resize(grey, (small * reduction, small * reduction),
                          interpolation=cv2.INTER_LINEAR)
        full = np.pad(full, ((0, SCAN - full.shape[0]), (0, SCAN - full.shape[1])))
        path = folder / f"{pid}.tif"
        with rasterio.open(path, "w", driver="GTiff", width=SCAN, height=SCAN, count=1,
                           dtype="uint8", tiled=True, blockxsize=512, blockysize=512) as ds:
            ds.write(full, 1)
        del full
        cameras[cam.name] = cam
        photos[pid] = replace(photo, image=path)
    return save_project(Project(project.crs, cameras, photos), folder / "project.yaml")


def scan_epipolar(work: Path) -> tuple:
    """The pair's epipolar images as dem:match makes them for a 1 m DSM (same pixel, same
    disparity range): (left, right, left valid, right valid, min disparity, count)."""
    from toolbox.photogrammetry.project import load_project
    from toolbox.stereo.dsm import matching_pixel, read_epipolar
    from toolbox.stereo.epipolar import epipolar_geometry, photo_image, resample_image
    from toolbox.stereo.matching import disparity_range, to_uint8
    from toolbox.stereo.pairs import PairRules, select_pairs

    project = load_project(work / "scans" / "project.yaml")
    left, right = (project.photo(p) for p in PAIR)
    rules = PairRules(sum(HEIGHTS) / 2.0, 0.3, 0.05, 2.0, 20.0)
    pairs, _ = select_pairs([left, right], rules)
    a, b, report = pairs[0]
    pixel = matching_pixel(a, 1.0, report.distance_m)
    geometry = epipolar_geometry(a, b, pixel_mm=pixel)
    d_min, count = disparity_range(geometry, a, *HEIGHTS)
    arrays = []
    for side, photo in enumerate((a, b)):
        path = work / f"epi_{side}.tif"
        resample_image(geometry, photo, side, photo_image(photo, None, "image"), path,
                       "bilinear", overviews=False)
        data, valid = read_epipolar(path)
        arrays.append((to_uint8(data, valid), valid))
    (li, lv), (ri, rv) = arrays
    return li, ri, lv, rv, d_min, count


def case(name: str, work: Path, pair: int) -> dict:
    t0 = time.perf_counter()
    if name == "read":
        from toolbox.io.pointcloud import PointFilter, open_point_cloud, read_xyz

        xyz, report = read_xyz(open_point_cloud(work / "cloud.laz"), PointFilter((2,)))
        extra = {"points_kept": report.kept}
    elif name in ("grid", "grid_memory", "tin", "tin_memory", "quality", "quality_memory"):
        import os

        import toolbox

        # grid: streamed (two chunked passes, per-tile buckets on disk: any cloud above
        # 10 M points); grid_memory: the same run with every point held (the oracle); tin,
        # tin_memory: the same for dem:tin_linear
        # quality, quality_memory: dem:nearest with QUALITY (leave-one-out), streamed / held
        streamed = name in ("grid", "tin", "quality")
        os.environ["TOOLBOX_STREAM_POINTS"] = "0" if streamed else str(10 ** 12)
        out = {"grid": "toolbox.tif", "grid_memory": "memory.tif"}.get(name, f"{name}.tif")
        method = "tin_linear" if name.startswith("tin") else "nearest"
        params = {"INPUT": str(work / "cloud.laz"), "CLASSES": "2", "CELL_SIZE": 1.0,
                  "OUTPUT": str(work / out), "OVERVIEWS": False}
        if name.startswith("quality"):
            params["QUALITY"] = str(work / f"{name}_report.json")
        stats = toolbox.run(f"dem:{method}", params)["STATISTICS"]
        extra = {"streamed": stats.get("streamed"), "points_used": stats["points_used"],
                 "cells": stats["cells"]["cells_with_value"],
                 "cross_validation": stats.get("cross_validation"),
                 "timings": stats.get("timings")}
    elif name == "numpy_bin":
        grid = bin_mean(work / "cloud.laz")
        np.save(work / "bin.npy", grid.astype(np.float32))
        extra = {"cells": int(np.isfinite(grid).sum())}
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
    elif name == "scan_dsm":  # the whole dem:match run: two 16644 px scans -> 1 m DSM
        import toolbox

        out = toolbox.run("dem:match", {
            "PROJECT": str(work / "scans" / "project.yaml"), "PHOTOS": ",".join(PAIR),
            "MIN_HEIGHT": HEIGHTS[0], "MAX_HEIGHT": HEIGHTS[1], "CELL_SIZE": 1.0,
            "OUTPUT": str(work / "scan_dsm.tif"), "COUNT": str(work / "scan_count.tif"),
            "SPREAD": str(work / "scan_spread.tif")})
        stats = out["STATISTICS"]
        pair_stats = stats["pairs"][0]
        extra = {"cells": stats["cells_with_value"], "grid": stats["grid"],
                 "image_size": pair_stats["image_size"],
                 "disparities": pair_stats["num_disparities"],
                 "matched": pair_stats["matched_fraction_of_left"],
                 "error": scan_dsm_error(work / "scan_dsm.tif")}
    elif name == "scan_sgbm":  # the floor: OpenCV alone on the same epipolar images, whole
        import cv2

        left, right, lv, rv, d_min, count = scan_epipolar(work)
        width = max(left.shape[1], right.shape[1])
        left = np.pad(left, ((0, 0), (0, width - left.shape[1])))
        right = np.pad(right, ((0, 0), (0, width - right.shape[1])))
        t0 = time.perf_counter()
        sgbm = cv2.StereoSGBM.create(minDisparity=d_min, numDisparities=count, blockSize=5,
                                     P1=8 * 25, P2=32 * 25, disp12MaxDiff=1,
                                     uniquenessRatio=10, speckleWindowSize=100, speckleRange=2,
                                     mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
        sgbm.compute(left, right)
        extra = {"image_size": [int(left.shape[1]), int(left.shape[0])],
                 "disparities": count}
    else:
        raise SystemExit(f"unknown case {name}")
    import os

    return {"seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time(),
            "load": os.getloadavg()[0], "peak_mb": peak_rss_mb(), **extra}


def scan_dsm_error(path: Path) -> dict:
    """Median and 90th percentile of |DSM - the rendered surface| (m) on the valid cells more
    than 3 m from a building wall, and the valid share of the cells."""
    import rasterio
    import shapely
    from scipy import ndimage

    from toolbox.demo.samples.landscape import landscape_surface, landscape_vectors

    surface, st = landscape_surface()
    with rasterio.open(path) as ds:
        dsm = ds.read(1, masked=True).filled(np.nan)
        t = ds.transform
    rows, cols = np.indices(dsm.shape)
    x, y = t.c + (cols + 0.5) * t.a, t.f + (rows + 0.5) * t.e
    truth = ndimage.map_coordinates(surface, [(y - st.f) / st.e - 0.5, (x - st.c) / st.a - 0.5],
                                    order=1, mode="nearest")
    walls = shapely.union_all(landscape_vectors()["buildings"]).boundary.buffer(3.0)
    ok = np.isfinite(dsm) & ~shapely.contains_xy(walls, x, y)
    err = np.abs(dsm - truth)[ok]
    return {"median": float(np.median(err)), "p90": float(np.percentile(err, 90)),
            "valid": float(np.isfinite(dsm).mean())}


def measured_row(name: str, work: Path, pair: int) -> tuple[str, dict | None]:
    """Run one case in its own process; its markdown row and its inner results."""
    cmd = [sys.executable, __file__, "--case", name, "--work", str(work), "--pair", str(pair)]
    seconds, peak, code, err = run_measured(cmd)
    if code:
        last = err.strip().splitlines()[-1] if err.strip() else f"exit {code}"
        return f"| {name} | - | - | not run: {last} |", None
    inner = json.loads((work / f"{name}.json").read_text())
    note = f"{inner['seconds']:.2f} s inside the process, {inner['cpu_seconds']:.0f} CPU s " \
           f"(all threads), load average {inner['load']:.1f} at the end"
    if name in ("grid", "grid_memory", "tin", "tin_memory", "quality", "quality_memory"):
        note += f"; {inner['points_used']:,} points gridded, {inner['cells']:,} cells"
        info = inner.get("streamed")
        if info:
            note += (f"; streamed: chunks of {info['chunk_points']:,}, {info['tiles']} tiles "
                     f"of {info['tile_size']} cells, {info['points_spilled']:,} points "
                     f"spilled to disk ({24 * info['points_spilled'] / 1e9:.2f} GB), largest "
                     f"bucket {info['bucket_points_max']:,} points")
            if "passes" in info:
                note += f", {info['passes']} passes, {info['tiles_retried']} tiles redone"
    if name == "epipolar":
        note += f" (a {inner['size']} x {inner['size']} uint8 scan, bilinear)"
    if name in ("sgbm", "match_pair"):
        note += f" ({pair} x {pair}, 64 disparities, median " \
                f"{inner['median_disparity']:.2f} of 32)"
    if name == "scan_dsm":
        e = inner["error"]
        note += (f"; epipolar images {inner['image_size'][0]} x {inner['image_size'][1]}, "
                 f"{inner['disparities']} disparities, {100 * inner['matched']:.0f} % of the left "
                 f"image matched; DSM {inner['grid']['width']} x {inner['grid']['height']} cells "
                 f"of 1 m, {100 * e['valid']:.0f} % valid; abs(DSM - surface) away from walls: "
                 f"median {e['median']:.2f} m, 90 % {e['p90']:.2f} m")
    if name == "scan_sgbm":
        note += (f" (StereoSGBM 3-way alone, whole {inner['image_size'][0]} x "
                 f"{inner['image_size'][1]} images, {inner['disparities']} disparities; the "
                 "process also resampled them, untimed inside)")
    return f"| {name} | {seconds:.1f} | {peak:.0f} | {note} |", inner


def compare_grids(tif: Path, binned: np.ndarray, laz: Path) -> str:
    """Same cells? dem:nearest's grid against the numpy binning's (cell by cell, by centre)."""
    import laspy
    import rasterio

    with laspy.open(laz) as reader:
        h = reader.header
        x0, y1 = np.floor(h.mins[0]), np.ceil(h.maxs[1])
    with rasterio.open(tif) as ds:
        grid = ds.read(1, masked=True).filled(np.nan)
        t = ds.transform
    rows, cols = np.indices(grid.shape)
    c = np.floor(t.c + (cols + 0.5) * t.a - x0).astype(np.int64)
    r = np.floor(y1 - (t.f + (rows + 0.5) * t.e)).astype(np.int64)
    inside = (r >= 0) & (r < binned.shape[0]) & (c >= 0) & (c < binned.shape[1])
    other = np.full(grid.shape, np.nan)
    other[inside] = binned[r[inside], c[inside]]
    both = np.isfinite(grid) & np.isfinite(other)
    diff = np.abs(grid - other)[both]
    return (f"Same cells as the binning: dem:nearest {int(np.isfinite(grid).sum()):,} cells "
            f"with a value, the "
            f"binning {int(np.isfinite(binned).sum()):,}; on the {int(both.sum()):,} they share, "
            f"abs(nearest - cell mean) median {np.median(diff):.3f} m, max {diff.max():.3f} m "
            "(nearest point vs mean of the cell's points on a smooth surface).")


def compare_memory(streamed: Path, memory: Path) -> str:
    """The streamed grid against the in-memory one (the oracle): cell for cell."""
    import rasterio

    with rasterio.open(streamed) as a, rasterio.open(memory) as b:
        x, y = a.read(1), b.read(1)
        same = a.transform == b.transform and x.shape == y.shape
    equal = same and bool(np.array_equal(x, y))
    return (f"Streamed against in memory: {'identical' if equal else 'DIFFERENT'} grids "
            f"({x.shape[1]} x {x.shape[0]} cells, {int(np.sum(x != y)) if same else '-'} cells "
            "differ).")


def compare_quality(streamed: Path, memory: Path) -> str:
    """The streamed QUALITY report against the in-memory one (the oracle)."""
    a = json.loads(memory.read_text())["methods"]["nearest"]
    b = json.loads(streamed.read_text())["methods"]["nearest"]
    info = b.pop("streamed", {})
    keys = ("points", "predicted", "not_predicted", "max_abs_error", "worst_point_index",
            "worst_point", "hull_vertices_not_predicted")
    same = [k for k in keys if a.get(k) == b.get(k)]
    sums = ("rmse", "mean_error", "mean_abs_error", "std_error")
    rel = {k: abs(b[k] - a[k]) / abs(a[k]) for k in sums if a.get(k)}
    diff = {k: abs(b[k] - a[k]) for k in sums if a.get(k) is not None}
    return (f"QUALITY streamed against in memory: equal {', '.join(same)} (of {len(keys)}); "
            f"RMSE {b['rmse']:.6f} m on {b['predicted']:,} points; relative differences "
            + ", ".join(f"{k} {v:.1e}" for k, v in rel.items()) + " (absolute: "
            + ", ".join(f"{k} {v:.1e} m" for k, v in diff.items()) + f"; mean error "
            f"{a['mean_error']:.3e} m in memory)"
            + f"; streamed QUALITY tiles {info.get('tiles')}, largest bucket "
            f"{info.get('bucket_points_max', 0):,}, {info.get('points_spilled', 0):,} points "
            "spilled")


def compare_tin(streamed: Path, memory: Path) -> str:
    """The streamed TIN grid against the in-memory one: same nodata, cells within 1e-9."""
    import rasterio

    with rasterio.open(streamed) as a, rasterio.open(memory) as b:
        x, y = a.read(1, masked=True).filled(np.nan), b.read(1, masked=True).filled(np.nan)
        same = a.transform == b.transform and x.shape == y.shape
    if not same:
        return "Streamed TIN against in memory: DIFFERENT grids"
    both = np.isfinite(x) & np.isfinite(y)
    rel = np.abs(x[both] - y[both]) / np.maximum(np.abs(y[both]), 1e-300)
    return (f"Streamed TIN against in memory: {x.shape[1]} x {x.shape[0]} cells, "
            f"{int(np.sum(np.isfinite(x) != np.isfinite(y)))} differ in having a value, "
            f"{int(both.sum()):,} with a value in both, {int(np.sum(rel > 1e-9))} of them more "
            f"than 1e-9 apart (largest relative difference {rel.max() if rel.size else 0:.2e}).")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true", help="1 M points, 1000 x 1000 pair")
    ap.add_argument("--points", type=int, default=10_000_000)
    ap.add_argument("--pair", type=int, default=4000, help="side of the SGBM pair, pixels")
    ap.add_argument("--sections", default="points,stereo,scans",
                    help="points (LAZ reading and gridding), stereo (SGBM floor on a noise pair, "
                    "epipolar resampling of a scan) and/or scans (two 16644 px scans to a 1 m "
                    "DSM)")
    ap.add_argument("--grid-max", type=int, default=30_000_000,
                    help="largest cloud dem:nearest is run on IN MEMORY (grid_memory: about "
                    "190 bytes a kept point); the streamed grid runs at any size")
    ap.add_argument("--cases", default=None,
                    help="comma-separated cases to run (default: all of the sections')")
    ap.add_argument("--case")
    ap.add_argument("--work")
    args = ap.parse_args()
    if args.small:
        args.points, args.pair = 1_000_000, 1000
    if args.case:
        result = case(args.case, Path(args.work), args.pair)
        (Path(args.work) / f"{args.case}.json").write_text(json.dumps(result))
        return
    sections = args.sections.split(",")
    out = [f"{machine_facts()}; {load_note()}", ""]
    with tempfile.TemporaryDirectory(prefix="surface_bench_") as tmp:
        work = Path(tmp)
        if "scans" in sections:
            t0 = time.perf_counter()
            siena_scans(work)
            print(f"scans made in {time.perf_counter() - t0:.1f} s", flush=True)
            out += ["Two 16644 x 16644 scans (the Siena pair 1_7150-1_7151) to a 1 m DSM:", "",
                    "| case | seconds | peak MB | note |", "|---|---|---|---|"]
            for name in ("scan_dsm", "scan_sgbm"):
                row, _ = measured_row(name, work, args.pair)
                out.append(row)
                print(row, flush=True)
            out.append("")
        if "points" in sections or "stereo" in sections:
            t0 = time.perf_counter()
            make_laz(work / "cloud.laz", args.points if "points" in sections else 1000)
            print(f"wrote {args.points:,} points in {time.perf_counter() - t0:.1f} s", flush=True)
            if "stereo" in sections:
                scan(work / "scan.tif", args.pair * 4)
            title = f"Points: {args.points:,}" if "points" in sections else \
                f"Stereo floor: a {args.pair} px noise pair"
            out += [title, "", "| case | seconds | peak MB | note |",
                    "|---|---|---|---|"]
            for name in ("read", "grid", "grid_memory", "tin", "tin_memory", "quality",
                         "quality_memory", "numpy_bin", "pdal",
                         "sgbm",
                         "match_pair", "epipolar"):
                stereo_case = name in ("sgbm", "match_pair", "epipolar")
                if (stereo_case and "stereo" not in sections) or \
                        (not stereo_case and "points" not in sections):
                    continue
                if args.cases and name not in args.cases.split(","):
                    continue
                if name in ("grid_memory", "tin_memory", "quality_memory") \
                        and args.points > args.grid_max:
                    out.append(f"| {name} | - | - | not run: {args.points:,} points is "
                               f"over --grid-max {args.grid_max:,} (see the notes) |")
                    continue
                row, _ = measured_row(name, work, args.pair)
                out.append(row)
                print(row, flush=True)
            if (work / "toolbox.tif").exists() and (work / "bin.npy").exists():
                out += ["", compare_grids(work / "toolbox.tif", np.load(work / "bin.npy"),
                                          work / "cloud.laz")]
            if (work / "toolbox.tif").exists() and (work / "memory.tif").exists():
                out += ["", compare_memory(work / "toolbox.tif", work / "memory.tif")]
            if (work / "quality_report.json").exists() and \
                    (work / "quality_memory_report.json").exists():
                out += ["", compare_quality(work / "quality_report.json",
                                            work / "quality_memory_report.json")]
            if (work / "tin.tif").exists() and (work / "tin_memory.tif").exists():
                out += ["", compare_tin(work / "tin.tif", work / "tin_memory.tif")]
    print("\n".join(out))


if __name__ == "__main__":
    main()
