"""TIN benchmark: the toolbox (CDT by default, Triangle when chosen) against Shewchuk's Triangle
called directly, scipy's Delaunay and ``gdal_grid -a linear``, side by side on the same 1 million
points, in one run; and the TIN written as GeoPackage, FlatGeobuf and GeoParquet.

    .venv/bin/python bench/tin_bench.py            # full size (1,000,000 points, 2000 x 2000)
    .venv/bin/python bench/tin_bench.py --small    # quick check (100,000 points, 632 x 632)

Every measurement runs in its own subprocess (this script with ``--case``), so its peak memory
(``VmHWM``) is its own; timings exclude interpreter start-up and loading the input arrays.
Data: uniform random points over 10 km x 10 km at the Siena coordinates (EPSG:3003) on a smooth
analytic surface, and 500 non-crossing zig-zag breaklines of 100 vertices each.
Writes the markdown table to bench/results/tin.md.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import case_arguments, load_note, machine_facts, measure_case, peak_rss_mb, run_measured

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
X0, Y0, SIZE = 1_685_000.0, 4_795_000.0, 10_000.0
CRS = "EPSG:3003"


def surface(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    u, v = (x - X0) / SIZE, (y - Y0) / SIZE
    return 300.0 + 30.0 * np.sin(6.0 * u) * np.cos(4.0 * v) + 10.0 * u * v


def make_data(work: Path, n_points: int, n_lines: int = 500, line_vertices: int = 100) -> None:
    """Points, breakline vertices and segments as .npy; points as a GeoPackage (PointZ)."""
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(2009)
    xy = np.column_stack([rng.uniform(X0, X0 + SIZE, n_points), rng.uniform(Y0, Y0 + SIZE, n_points)])
    xyz = np.column_stack([xy, surface(xy[:, 0], xy[:, 1])])
    np.save(work / "points.npy", xyz)
    gap = SIZE / (n_lines + 1)
    lx = np.linspace(X0 + 10, X0 + SIZE - 10, line_vertices)
    lines, segments = [], []
    for k in range(n_lines):
        ly = Y0 + (k + 1) * gap + np.where(np.arange(line_vertices) % 2 == 0, -gap / 4, gap / 4)
        start = n_points + k * line_vertices
        lines.append(np.column_stack([lx, ly, surface(lx, ly)]))
        idx = np.arange(start, start + line_vertices)
        segments.append(np.column_stack([idx[:-1], idx[1:]]))
    np.save(work / "all_points.npy", np.vstack([xyz, *lines]))
    np.save(work / "segments.npy", np.vstack(segments).astype(np.int32))
    frame = gpd.GeoDataFrame({"z": xyz[:, 2]}, geometry=shapely.points(xyz), crs=CRS)
    frame.to_file(work / "points.gpkg", layer="points", engine="pyogrio", use_arrow=True)
    line_frame = gpd.GeoDataFrame({"k": np.arange(n_lines)},
                                  geometry=[shapely.linestrings(p) for p in lines], crs=CRS)
    line_frame.to_file(work / "breaklines.gpkg", layer="breaklines", engine="pyogrio")


# -- cases (each runs in a subprocess) -------------------------------------------------------------
def _grid(n_points: int) -> tuple[int, float]:
    width = int(round(2000 * np.sqrt(n_points / 1_000_000)))
    return width, SIZE / width


def run_case(name: str, work: Path, n_points: int) -> dict:
    """Run one measurement in this process; return seconds and extra facts."""
    sys.path.insert(0, str(ROOT))
    from toolbox.terrain.tin import kernels

    width, cell = _grid(n_points)
    facts: dict = {}
    _warm_up(kernels, registry=name.endswith("_cli"))
    if name.endswith("_triangle"):  # the toolbox's kernels with Triangle behind them
        import os

        os.environ["TOOLBOX_TRIANGULATOR"] = "triangle"
        name = name.removesuffix("_triangle")
    if name in ("triangle", "ours", "scipy"):
        xyz = np.load(work / "points.npy")
        xy = np.ascontiguousarray(xyz[:, :2])
        if name == "scipy":
            from scipy.spatial import Delaunay
            xy = xy - [X0 + SIZE / 2, Y0 + SIZE / 2]
        t0 = time.perf_counter()
        if name == "triangle":
            triangle = _triangle_module()
            tri = triangle.triangulate({"vertices": xy}, "")["triangles"]
        elif name == "ours":
            tri = kernels.triangulate(xy)
        else:
            tri = Delaunay(xy).simplices
        seconds = time.perf_counter() - t0
        facts["triangles"] = len(tri)
    elif name in ("triangle_breaklines", "ours_breaklines"):
        xy = np.ascontiguousarray(np.load(work / "all_points.npy")[:, :2])
        seg = np.load(work / "segments.npy")
        t0 = time.perf_counter()
        if name == "triangle_breaklines":
            triangle = _triangle_module()
            tri = triangle.triangulate({"vertices": xy, "segments": seg}, "pc")["triangles"]
        else:
            tri = kernels.triangulate(xy, seg)
        seconds = time.perf_counter() - t0
        facts["triangles"] = len(tri)
    elif name in WRITE_CASES:
        from toolbox.io.crs import parse_crs
        from toolbox.terrain.tin.build import build_tin
        from toolbox.terrain.tin.store import write_tin

        model = build_tin(np.load(work / "points.npy"))
        ext = WRITE_CASES[name]
        out = work / f"{name}{ext}"
        for old in work.glob(f"{name}*{ext}"):
            old.unlink()
        t0 = time.perf_counter()
        counts = write_tin(out, model, parse_crs(CRS), spatial_index=not name.endswith("noindex"))
        seconds = time.perf_counter() - t0
        facts.update(counts)
        facts["megabytes"] = round(sum(f.stat().st_size for f in work.glob(f"{name}*")) / 2**20, 1)
    elif name in ("delaunay_cli", "delaunay_breaklines_cli", "delaunay_lean_cli",
                  "delaunay_parquet_cli"):
        import toolbox
        from toolbox.feedback import Feedback

        ext = ".parquet" if name == "delaunay_parquet_cli" else ".gpkg"
        params = {"INPUT": work / "points.gpkg", "OUTPUT": work / f"{name}{ext}"}
        if name == "delaunay_breaklines_cli":
            params["BREAKLINES"] = work / "breaklines.gpkg"
        if name == "delaunay_lean_cli":
            params.update(EDGES=False, SPATIAL_INDEX=False)
        feedback = Feedback()
        t0 = time.perf_counter()
        toolbox.run("tin:delaunay", params, feedback=feedback, overwrite=True)
        seconds = time.perf_counter() - t0
        facts["timings"] = {k: round(v, 2) for k, v in feedback.timings.items()}
    elif name == "rasterize_kernel":
        xyz = np.load(work / "points.npy")
        tri = kernels.triangulate(xyz[:, :2])
        t0 = time.perf_counter()
        z = kernels.rasterize_tin(xyz, tri, X0, Y0 + SIZE, cell, cell, width, width)
        seconds = time.perf_counter() - t0
        facts["cells"] = int(z.size)
    elif name in ("to_raster_cli", "to_raster_parquet_cli"):
        import toolbox

        tin = work / ("delaunay_cli.gpkg" if name == "to_raster_cli" else "write_parquet.parquet")
        t0 = time.perf_counter()
        toolbox.run("tin:to_raster", {"TIN": tin, "CELL_SIZE": cell, "OVERVIEWS": False,
                                      "EXTENT": f"{X0},{Y0},{X0 + SIZE},{Y0 + SIZE}",
                                      "OUTPUT": work / "tin.tif"}, overwrite=True)
        seconds = time.perf_counter() - t0
    else:
        raise ValueError(f"unknown case {name}")
    peak = peak_rss_mb()
    return {"seconds": seconds, "peak_mb": peak, **facts}


WRITE_CASES = {"write_gpkg": ".gpkg", "write_gpkg_noindex": ".gpkg", "write_fgb": ".fgb",
               "write_fgb_noindex": ".fgb", "write_parquet": ".parquet"}


def _triangle_module():
    from toolbox.extras import require

    return require("triangle", "triangle", "the Triangle rows of the TIN benchmark")


def _warm_up(kernels, registry: bool) -> None:
    """Load what every run pays once (numba's compiled kernels; the algorithm registry for runs
    through toolbox.run, which imports every algorithm module) before the clock starts."""
    if registry:
        from toolbox.registry import discover

        discover()
    tiny = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 2.0]])
    kernels.rasterize_tin(tiny, np.array([[0, 1, 2]]), 0.0, 1.0, 0.5, 0.5, 2, 2)
    kernels.interpolate_tin(tiny, np.array([[0, 1, 2]]), np.array([0.2]), np.array([0.2]))


def measure(name: str, work: Path, n_points: int) -> dict:
    """Run one case in a fresh process."""
    return measure_case(__file__, name, work, n_points, ROOT)


def measure_gdal_grid(work: Path, n_points: int) -> dict | None:
    exe = shutil.which("gdal_grid")
    if exe is None:
        return None
    width, _ = _grid(n_points)
    out = work / "gdal_linear.tif"
    out.unlink(missing_ok=True)
    cmd = [exe, "-q", "-a", "linear:nodata=-9999", "-txe", str(X0), str(X0 + SIZE),
           "-tye", str(Y0 + SIZE), str(Y0), "-outsize", str(width), str(width), "-ot", "Float32",
           "-l", "points", str(work / "points.gpkg"), str(out)]
    seconds, peak_mb, status, stderr = run_measured(cmd)
    if status != 0:
        raise RuntimeError(f"gdal_grid failed: {stderr[-2000:]}")
    result = {"seconds": seconds, "peak_mb": peak_mb}
    print(f"  {'gdal_grid -a linear':<26} {seconds:8.2f} s  {result['peak_mb']:8.0f} MB",
          flush=True)
    return result


def agreement(work: Path) -> float | None:
    """Largest |difference| between tin:to_raster and gdal_grid where both have data."""
    import rasterio

    try:
        with rasterio.open(work / "tin.tif") as a, rasterio.open(work / "gdal_linear.tif") as b:
            za, zb = a.read(1, masked=True), b.read(1, masked=True)
    except rasterio.errors.RasterioIOError:
        return None
    both = ~za.mask & ~zb.mask
    return float(np.abs(za.data[both].astype("f8") - zb.data[both]).max()) if both.any() else None


def machine() -> str:
    from importlib.metadata import version

    import numba
    import pyogrio

    gdal = subprocess.run(["gdal_grid", "--version"], capture_output=True, text=True).stdout.strip() \
        if shutil.which("gdal_grid") else "gdal_grid not installed"
    return machine_facts(f"numba {numba.__version__}",
                         f"pythoncdt {_version_or_none('pythoncdt')}",
                         f"triangle {_version_or_none('triangle')}",
                         f"scipy {version('scipy')}",
                         f"pyogrio {pyogrio.__version__} (GDAL {pyogrio.__gdal_version_string__})",
                         f"pyarrow {_version_or_none('pyarrow')}", gdal)


def _version_or_none(name: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


def main(small: bool = False) -> str:
    load = load_note()
    n_points = 100_000 if small else 1_000_000
    work = Path(tempfile.mkdtemp(prefix="tin_bench_"))
    try:
        print(f"tin bench: {n_points:,} points in {work}", flush=True)
        make_data(work, n_points)
        # the short triangulation cases run 3 rounds, interleaved; the fastest run is kept
        short = ("triangle", "ours", "ours_triangle", "triangle_breaklines", "ours_breaklines",
                 "ours_breaklines_triangle")
        rounds = [{name: measure(name, work, n_points) for name in short} for _ in range(3)]
        r = {name: min((x[name] for x in rounds), key=lambda m: m["seconds"]) for name in short}
        r.update({name: measure(name, work, n_points) for name in (
            "scipy", *WRITE_CASES, "delaunay_cli", "delaunay_lean_cli", "delaunay_parquet_cli",
            "delaunay_breaklines_cli", "rasterize_kernel", "to_raster_cli",
            "to_raster_parquet_cli")})
        gdal = measure_gdal_grid(work, n_points)
        max_diff = agreement(work) if gdal else None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    width, _ = _grid(n_points)
    text = table(r, gdal, n_points, width, max_diff, load)
    if not small:
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "tin.md").write_text(text)
    print(text)
    return text


def table(r: dict, gdal: dict | None, n_points: int, width: int, max_diff: float | None,
          load: str) -> str:
    def row(step, ours, peer_name, peer):
        ratio = f"{ours['seconds'] / peer['seconds']:.2f}" if peer else "-"
        peer_text = f"{peer_name}: {peer['seconds']:.2f} s, {peer['peak_mb']:.0f} MB" if peer \
            else "-"
        return (f"| {step} | {ours['seconds']:.2f} s | {ours['peak_mb']:.0f} MB | {peer_text} | "
                f"{ratio} |")

    seg_vertices = 500 * 100
    lines = [
        "## TIN (tin:delaunay, tin:to_raster)", "",
        f"{n_points:,} random points over 10 km x 10 km (EPSG:3003 coordinates); breaklines: 500 "
        f"zig-zag lines, {seg_vertices:,} vertices; raster {width} x {width} cells "
        f"({width * width / 1e6:.0f} M). One run, side by side; each step in its own process "
        "(Triangle and toolbox triangulation times: fastest of 3 interleaved runs; "
        "time excludes interpreter start-up, imports, numba's cached-kernel loading and loading "
        "the arrays; peak = max RSS of that process, which for the `toolbox.run` rows includes "
        "importing every algorithm of the toolbox).", "",
        "| step | toolbox | toolbox peak | peer | toolbox / peer |",
        "|---|---|---|---|---|",
        row("triangulate (kernels.triangulate, CDT)", r["ours"], "Triangle direct",
            r["triangle"]),
        row("triangulate (kernels.triangulate, TOOLBOX_TRIANGULATOR=triangle)",
            r["ours_triangle"], "Triangle direct", r["triangle"]),
        row("triangulate (kernels.triangulate, CDT)", r["ours"], "scipy Delaunay", r["scipy"]),
        row("triangulate with breaklines (CDT)", r["ours_breaklines"], "Triangle `-pc` direct",
            r["triangle_breaklines"]),
        row("triangulate with breaklines (TOOLBOX_TRIANGULATOR=triangle)",
            r["ours_breaklines_triangle"], "Triangle `-pc` direct", r["triangle_breaklines"]),
        row("write TIN GeoPackage 1.2 (3 layers, spatial index)", r["write_gpkg"], "", None),
        row("write TIN GeoPackage 1.2 (no spatial index)", r["write_gpkg_noindex"], "", None),
        row("write TIN FlatGeobuf (3 files, spatial index)", r["write_fgb"], "", None),
        row("write TIN FlatGeobuf (no spatial index)", r["write_fgb_noindex"], "", None),
        row("write TIN GeoParquet (3 files)", r["write_parquet"], "", None),
        row("tin:delaunay end to end (read GPKG, build, write)", r["delaunay_cli"], "", None),
        row("tin:delaunay, EDGES=false SPATIAL_INDEX=false", r["delaunay_lean_cli"], "", None),
        row("tin:delaunay end to end, OUTPUT tin.parquet (GeoParquet, the big-TIN format)",
            r["delaunay_parquet_cli"], "", None),
        row("tin:delaunay with breaklines, end to end", r["delaunay_breaklines_cli"], "", None),
        row(f"rasterise TIN to {width}x{width} (kernel)", r["rasterize_kernel"],
            "gdal_grid -a linear", gdal),
        row("tin:to_raster end to end (read TIN GPKG, write GeoTIFF)", r["to_raster_cli"],
            "gdal_grid -a linear", gdal),
        row("tin:to_raster end to end (read TIN GeoParquet, write GeoTIFF)",
            r["to_raster_parquet_cli"], "gdal_grid -a linear", gdal),
        "",
        f"GeoPackage: {r['write_gpkg'].get('triangles', 0):,} triangles, "
        f"{r['write_gpkg'].get('nodes', 0):,} nodes, {r['write_gpkg'].get('edges', 0):,} edges, "
        f"{r['write_gpkg'].get('megabytes', 0)} MB (FlatGeobuf "
        f"{r['write_fgb'].get('megabytes', 0)} MB, GeoParquet "
        f"{r['write_parquet'].get('megabytes', 0)} MB). tin:delaunay step timings (s): "
        f"{r['delaunay_cli'].get('timings')}; to GeoParquet: "
        f"{r['delaunay_parquet_cli'].get('timings')}. Big TINs: write `--OUTPUT tin.parquet` "
        "(or `.fgb`); a GeoPackage is bound by GDAL's per-feature SQLite inserts and R-tree.",
    ]
    if max_diff is not None:
        lines.append(f"tin:to_raster vs gdal_grid -a linear, largest |difference| where both "
                     f"have data: {max_diff:.3g} (float32 output).")
    lines += ["", f"Machine: {machine()}; {load}.", ""]
    return "\n".join(lines)


CORE_CASES = ("triangle", "ours", "triangle_breaklines", "ours_breaklines")


def core(rounds: int, n_points: int) -> str:
    """The triangulation core alone against Triangle called directly (issue 31's row): the
    four short cases interleaved for ``rounds`` rounds, each in its own process; medians,
    ranges and the ratio Triangle / ours (above 1: ours is faster)."""
    import statistics

    load = load_note()
    work = Path(tempfile.mkdtemp(prefix="tin_core_"))
    try:
        make_data(work, n_points)
        runs = {name: [] for name in CORE_CASES}
        for _ in range(rounds):
            for name in CORE_CASES:
                runs[name].append(measure(name, work, n_points)["seconds"])
    finally:
        shutil.rmtree(work, ignore_errors=True)
    med = {name: statistics.median(v) for name, v in runs.items()}
    lines = [f"Triangulation core, {n_points:,} points, medians of {rounds} interleaved runs "
             f"(each its own process; {load}):", "",
             "| case | ours (CDT) | Triangle direct | Triangle / ours |", "|---|---|---|---|"]
    for label, ours, peer in (("points", "ours", "triangle"),
                              ("points + breaklines", "ours_breaklines", "triangle_breaklines")):
        lines.append(f"| {label} | {med[ours]:.3f} s ({min(runs[ours]):.3f}-"
                     f"{max(runs[ours]):.3f}) | {med[peer]:.3f} s ({min(runs[peer]):.3f}-"
                     f"{max(runs[peer]):.3f}) | {med[peer] / med[ours]:.2f}x |")
    return "\n".join(lines)


if __name__ == "__main__":
    args = case_arguments(__doc__.splitlines()[0],
                          lambda parser: parser.add_argument("--core", type=int, metavar="ROUNDS"))
    if args.case:
        print(json.dumps(run_case(args.case, args.work, args.points)))
    elif args.core:
        print(core(args.core, args.points))
    else:
        main(small=args.small)
