"""DEM gridding benchmark: dem:idw, dem:tin_linear and dem:quadratic against gdal_grid and scipy's
griddata, side by side on the same 1 million points -> 2000 x 2000 cells, in one run; plus the
peak memory of a 20000 x 20000 output.

    .venv/bin/python bench/dem_bench.py            # full size
    .venv/bin/python bench/dem_bench.py --small    # quick check (100,000 points, 632 x 632)
    .venv/bin/python bench/dem_bench.py --no-big   # skip the 20000 x 20000 memory run
    .venv/bin/python bench/dem_bench.py --whole-only   # only the whole-process TIN rows
    .venv/bin/python bench/dem_bench.py --crossover    # dem:tin_linear's numpy vs numba path

Data: uniform random points over 2 km x 2 km at the Siena coordinates (EPSG:3003) on a smooth
analytic surface, whose value at every cell centre is the truth for the RMSE. Every measurement
runs in its own subprocess (this script with ``--case``), so its peak memory (``ru_maxrss``) is
its own. Toolbox times are end to end through ``toolbox.run`` (read the GeoPackage, merge
duplicates, grid by tiles on local threads, write a DEFLATE GeoTIFF without overviews) after a
warm-up that loads the algorithm registry and numba's cached kernels; gdal_grid times are the
whole command (it reads the same GeoPackage); griddata's time excludes reading (arrays in memory).

Whole-process rows (what a user waits for at the prompt): ``toolbox run dem:tin_linear`` in a
fresh process (warm numba cache: the second run of a session; the 100,000-point runs take its
numpy path and never import numba), ``gdal_grid -a linear`` and a
Python process running scipy's griddata (its import, loading the points from .npy, the
interpolation), on 1,000,000 and on 100,000 points over the same 2 km square, each to the
2000 x 2000 grid of 1 m and the 100,000 points also to the 632 x 632 grid of ``--small``;
median of 3 interleaved runs, with CPU time (user + system) and peak RSS. First runs: the
TIN commands on 3,000 points with an empty per-user cache (numba compiles the kernels), then the
same commands again (kernels loaded from that cache).
Writes the markdown table to bench/results/dem.md.

Crossover (``--crossover``, bench/results/dem_crossover.md): ``dem:tin_linear`` whole process
with its numpy kernels (no numba import) and with its numba kernels, forced, interleaved, best of
3, over points x cells; it sets ``NUMPY_MAX_POINTS`` / ``NUMPY_MAX_CELLS`` in
toolbox/terrain/gridding/methods/tin_linear.py.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import case_arguments, load_note, machine_facts, measure_case, peak_rss_mb, run_measured

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
X0, Y0, SIZE = 1_687_000.0, 4_798_500.0, 2000.0
CRS = "EPSG:3003"
IDW_RADIUS = 12.0  # >= 12 points within 12 m for every cell at 0.25 points/m² (mean 113)


def surface(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Analytic terrain (m): two wave trains and a tilt over the 2 km square."""
    u, v = (x - X0) / SIZE, (y - Y0) / SIZE
    return 300.0 + 25.0 * np.sin(7.0 * u) * np.cos(5.0 * v) + 8.0 * np.sin(23.0 * u + 11.0 * v) \
        + 15.0 * u


def grid_shape(n_points: int) -> tuple[int, float]:
    width = int(round(2000 * np.sqrt(n_points / 1_000_000)))
    return width, SIZE / width


def make_data(work: Path, n_points: int) -> None:
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(1009)
    xy = np.column_stack([rng.uniform(X0, X0 + SIZE, n_points),
                          rng.uniform(Y0, Y0 + SIZE, n_points)])
    xyz = np.column_stack([xy, surface(xy[:, 0], xy[:, 1])])
    np.save(work / "points.npy", xyz)
    frame = gpd.GeoDataFrame({"z": xyz[:, 2]}, geometry=shapely.points(xyz), crs=CRS)
    frame.to_file(work / "points.gpkg", layer="points", engine="pyogrio")


# -- cases (each runs in a subprocess) -------------------------------------------------------------
ALGORITHMS = {
    "idw": ("dem:idw", {"NEIGHBOURS": 12, "POWER": 2.0, "RADIUS": IDW_RADIUS}),
    "nearest": ("dem:nearest", {}),
    "tin_linear": ("dem:tin_linear", {}),
    "quadratic": ("dem:quadratic", {"NEIGHBOURS": 12}),
}


def run_case(name: str, work: Path, n_points: int) -> dict:
    """Run one measurement in this process; return seconds and extra facts."""
    sys.path.insert(0, str(ROOT))
    width, cell = grid_shape(n_points)
    facts: dict = {}
    if name == "griddata":
        from scipy.interpolate import griddata

        xyz = np.load(work / "points.npy")
        xs, ys = _centres(width, cell)
        gx, gy = np.meshgrid(xs - X0, ys - Y0)
        t0 = time.perf_counter()
        z = griddata(xyz[:, :2] - [X0, Y0], xyz[:, 2], (gx, gy), method="linear")
        seconds = time.perf_counter() - t0
        np.save(work / "griddata.npy", z.astype("float32"))
    else:
        import toolbox
        from toolbox.feedback import Feedback

        big = name.startswith("big_")
        alg, extra = ALGORITHMS[name.removeprefix("big_")]
        _warm_up(alg, extra, work)
        from toolbox.extras import require

        psutil = require("psutil", "bench", "the benchmarks")
        facts["rss_before_mb"] = psutil.Process().memory_info().rss / 2**20
        params = {"INPUT": work / "points.gpkg", "OUTPUT": work / f"{name}.tif",
                  "CELL_SIZE": cell / 10 if big else cell, "OVERVIEWS": False,
                  "EXTENT": f"{X0},{Y0},{X0 + SIZE},{Y0 + SIZE}", **extra}
        feedback = Feedback()
        t0 = time.perf_counter()
        out = toolbox.run(alg, params, feedback=feedback, overwrite=True)
        seconds = time.perf_counter() - t0
        stats = out["STATISTICS"]
        facts["cells"] = stats["cells"]["cells_with_value"]
        facts["timings"] = {k: round(v, 2) for k, v in feedback.timings.items()}
        facts["method"] = {k: v for k, v in stats["method"].items() if k != "options"}
        if big:
            facts["megabytes"] = round((work / f"{name}.tif").stat().st_size / 2**20)
            (work / f"{name}.tif").unlink()
    peak = peak_rss_mb()
    return {"seconds": seconds, "peak_mb": peak, **facts}


def _warm_up(alg: str, extra: dict, work: Path) -> None:
    """Load what every run pays once (the registry, numba's cached kernels) before the clock."""
    import geopandas as gpd
    import shapely

    import toolbox

    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 100, (300, 2)) + [X0, Y0]
    z = surface(xy[:, 0], xy[:, 1])
    path = work / "warm.gpkg"
    if not path.exists():
        gpd.GeoDataFrame({"z": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z),
                         crs=CRS).to_file(path)
    toolbox.run(alg, {"INPUT": path, "CELL_SIZE": 5, "OUTPUT": work / "warm.tif", **extra},
                overwrite=True)


def _centres(width: int, cell: float) -> tuple[np.ndarray, np.ndarray]:
    xs = X0 + (np.arange(width) + 0.5) * cell
    ys = Y0 + SIZE - (np.arange(width) + 0.5) * cell
    return xs, ys


def measure(name: str, work: Path, n_points: int) -> dict:
    return measure_case(__file__, name, work, n_points, ROOT, width=24)


def measure_gdal_grid(label: str, algorithm: str, work: Path, n_points: int) -> dict | None:
    exe = shutil.which("gdal_grid")
    if exe is None:
        return None
    width, _ = grid_shape(n_points)
    out = work / f"gdal_{label}.tif"
    out.unlink(missing_ok=True)
    cmd = [exe, "-q", "--config", "GDAL_NUM_THREADS", "ALL_CPUS", "-a", algorithm,
           "-txe", str(X0), str(X0 + SIZE), "-tye", str(Y0 + SIZE), str(Y0),
           "-outsize", str(width), str(width), "-ot", "Float32", "-l", "points",
           str(work / "points.gpkg"), str(out)]
    seconds, peak_mb, status, stderr = run_measured(cmd)
    if status != 0:
        raise RuntimeError(f"gdal_grid failed: {stderr[-2000:]}")
    result = {"seconds": seconds, "peak_mb": peak_mb}
    print(f"  gdal_grid {label:<14} {seconds:8.2f} s  {result['peak_mb']:8.0f} MB", flush=True)
    return result


GRIDDATA_SCRIPT = """
import sys
import numpy as np
from scipy.interpolate import griddata
xyz = np.load(sys.argv[1])
x0, y0, size, width = (float(v) for v in sys.argv[2:6])
cell = size / width
xs = (np.arange(int(width)) + 0.5) * cell
gx, gy = np.meshgrid(xs, size - xs)
z = griddata(xyz[:, :2] - [x0, y0], xyz[:, 2], (gx, gy), method="linear").astype("float32")
"""


def whole_process_commands(work: Path, width: int) -> dict[str, list[str]]:
    """The three whole-process commands on ``work``'s points to a ``width`` x ``width`` grid."""
    cell = SIZE / width
    toolbox_exe = str(Path(sys.executable).with_name("toolbox"))
    return {
        "dem:tin_linear": [toolbox_exe, "run", "dem:tin_linear", "--INPUT",
                           str(work / "points.gpkg"), "--OUTPUT", str(work / "whole.tif"),
                           "--CELL_SIZE", repr(cell), "--OVERVIEWS", "false", "--EXTENT",
                           f"{X0},{Y0},{X0 + SIZE},{Y0 + SIZE}", "--overwrite", "-q"],
        "gdal_grid -a linear": [
            shutil.which("gdal_grid") or "gdal_grid", "-q", "--config", "GDAL_NUM_THREADS",
            "ALL_CPUS", "-a", "linear:radius=0:nodata=-9999", "-txe", str(X0), str(X0 + SIZE),
            "-tye", str(Y0 + SIZE), str(Y0), "-outsize", str(width), str(width), "-ot",
            "Float32", "-l", "points", str(work / "points.gpkg"), str(work / "whole_gdal.tif")],
        "scipy griddata (python process)": [sys.executable, "-c", GRIDDATA_SCRIPT,
                                            str(work / "points.npy"), str(X0), str(Y0),
                                            str(SIZE), str(width)],
    }


def measure_whole(cmd: list[str], repeat: int = 3) -> list[tuple[float, float, float]]:
    """(wall s, CPU s of the child, peak MB) of each of ``repeat`` runs of ``cmd``."""
    runs = []
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        seconds, peak_mb, status, stderr = run_measured(cmd)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if status != 0:
            raise RuntimeError(f"{cmd[0]} failed: {stderr[-2000:]}")
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        runs.append((seconds, cpu, peak_mb))
    return runs


CROSSOVER_SCRIPT = """
import sys
import toolbox
from toolbox.terrain.gridding import neighbours
from toolbox.terrain.gridding.methods import tin_linear
folder, cell, path = sys.argv[1], float(sys.argv[2]), sys.argv[3]
if path == "numpy":  # no limit: the numpy kernels whatever the size
    neighbours.NUMPY_MAX_POINTS = tin_linear.NUMPY_MAX_POINTS = tin_linear.NUMPY_MAX_CELLS = 1e18
else:
    tin_linear.NUMPY_MAX_CELLS = -1
toolbox.run("dem:tin_linear", {"INPUT": folder + "/points.gpkg", "OUTPUT": folder + "/x.tif",
            "CELL_SIZE": cell, "OVERVIEWS": False, "EXTENT": sys.argv[4]}, overwrite=True)
"""


def crossover_rows(work: Path, points=(100_000, 250_000, 400_000, 700_000),
                   widths=(632, 1414, 2000, 2828), repeat: int = 3) -> list[str]:
    """Whole-process dem:tin_linear, numpy path against numba path (forced), best of
    ``repeat`` interleaved runs per case; markdown lines."""
    lines = ["| points | cells | numpy path | numba path | faster |", "|---|---|---|---|---|"]
    extent = f"{X0},{Y0},{X0 + SIZE},{Y0 + SIZE}"
    for n in points:
        folder = work / f"cross_{n}"
        folder.mkdir(exist_ok=True)
        make_data(folder, n)
        for width in widths:
            best = {}
            for _ in range(repeat):
                for path in ("numpy", "numba"):
                    ((wall, cpu, _),) = measure_whole(
                        [sys.executable, "-c", CROSSOVER_SCRIPT, str(folder), repr(SIZE / width),
                         path, extent], 1)
                    best[path] = min(best.get(path, (np.inf, 0)), (wall, cpu))
            faster = min(best, key=lambda k: best[k][0])
            lines.append(f"| {n:,} | {width} x {width} | {best['numpy'][0]:.2f} s "
                         f"({best['numpy'][1]:.2f} s CPU) | {best['numba'][0]:.2f} s "
                         f"({best['numba'][1]:.2f} s CPU) | {faster} |")
            print("  " + lines[-1], flush=True)
    return lines


def whole_process_rows(work: Path, n_big: int, n_small: int, repeat: int = 3) -> list[dict]:
    """Whole-process rows: each case's three commands interleaved ``repeat`` times."""
    small = work / "small"
    small.mkdir(exist_ok=True)
    if not (small / "points.gpkg").exists():
        make_data(small, n_small)
    cases = [(work, n_big, 2000), (small, n_small, 2000), (small, n_small,
                                                            grid_shape(n_small)[0])]
    rows = []
    for folder, n, width in cases:
        commands = whole_process_commands(folder, width)
        if shutil.which("gdal_grid") is None:
            commands.pop("gdal_grid -a linear")
        runs: dict[str, list] = {name: [] for name in commands}
        for _ in range(repeat):  # interleaved: the machine's load hits every command alike
            for name, cmd in commands.items():
                runs[name] += measure_whole(cmd, 1)
        for name, values in runs.items():
            row = {"points": n, "width": width, "what": name,
                   "wall": statistics.median(v[0] for v in values),
                   "cpu": statistics.median(v[1] for v in values),
                   "peak_mb": max(v[2] for v in values)}
            rows.append(row)
            print(f"  whole {name:<32} {n:>9,} pts {width} px {row['wall']:6.2f} s wall "
                  f"{row['cpu']:6.2f} s CPU {row['peak_mb']:6.0f} MB", flush=True)
    return rows


def first_run_rows(work: Path) -> list[dict]:
    """dem:tin_linear, tin:delaunay, tin:to_raster on 3,000 points: cold (a fresh cache folder:
    numba compiles) then warm (the same folder)."""
    folder = work / "first"
    folder.mkdir(exist_ok=True)
    make_data(folder, 3000)
    toolbox_exe = str(Path(sys.executable).with_name("toolbox"))
    commands = {
        "dem:tin_linear": ["dem:tin_linear", "--INPUT", str(folder / "points.gpkg"),
                           "--CELL_SIZE", "5", "--OUTPUT", str(folder / "dem.tif")],
        "tin:delaunay": ["tin:delaunay", "--INPUT", str(folder / "points.gpkg"), "--OUTPUT",
                         str(folder / "tin.gpkg")],
        "tin:to_raster": ["tin:to_raster", "--TIN", str(folder / "tin.gpkg"), "--CELL_SIZE",
                          "5", "--OUTPUT", str(folder / "tin.tif")],
    }
    saved = {k: os.environ.get(k) for k in ("XDG_CACHE_HOME", "NUMBA_CACHE_DIR")}
    os.environ["XDG_CACHE_HOME"] = str(folder / "cache")
    os.environ["NUMBA_CACHE_DIR"] = str(folder / "cache" / "numba")
    rows = []
    try:
        for case in ("cold cache (compiles)", "warm cache"):
            for name, args in commands.items():
                ((wall, cpu, peak),) = measure_whole([toolbox_exe, "run", *args, "--overwrite",
                                                      "-q"], 1)
                rows.append({"what": name, "case": case, "wall": wall, "cpu": cpu,
                             "peak_mb": peak})
                print(f"  first run {name:<16} {case:<22} {wall:6.2f} s wall {cpu:6.2f} s CPU",
                      flush=True)
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    return rows


def whole_process_table(rows: list[dict], first: list[dict]) -> list[str]:
    lines = ["", "### dem:tin_linear, whole process", "",
             "A fresh process per run, as at the prompt (toolbox: start-up, read the GeoPackage, "
             "triangulate, rasterise, write the GeoTIFF without overviews; numba's kernel "
             "cache warm). Median of 3 interleaved runs; CPU = user + system of the process; "
             "peak = its max RSS.", "",
             "| points -> cells | command | wall s | CPU s | peak MB | wall / toolbox |",
             "|---|---|---:|---:|---:|---:|"]
    ours = {(r["points"], r["width"]): r["wall"] for r in rows if r["what"] == "dem:tin_linear"}
    for r in rows:
        ratio = r["wall"] / ours[(r["points"], r["width"])]
        lines.append(f"| {r['points']:,} -> {r['width']} x {r['width']} | {r['what']} | "
                     f"{r['wall']:.2f} | {r['cpu']:.2f} | {r['peak_mb']:.0f} | {ratio:.2f} |")
    lines += ["", "First runs on 3,000 points (5 m cells), whole process:", "",
              "| command | per-user cache | wall s | CPU s | peak MB |", "|---|---|---:|---:|---:|"]
    lines += [f"| {r['what']} | {r['case']} | {r['wall']:.2f} | {r['cpu']:.2f} | "
              f"{r['peak_mb']:.0f} |" for r in first]
    return lines


def accuracy(values: np.ndarray, n_points: int) -> dict:
    """RMSE and max error against the analytic surface over the cells with a value."""
    width, cell = grid_shape(n_points)
    xs, ys = _centres(width, cell)
    truth = surface(xs[None, :], ys[:, None])
    ok = np.isfinite(values)
    err = values[ok].astype("float64") - truth[ok]
    return {"rmse": float(np.sqrt(np.mean(err ** 2))), "max_abs": float(np.abs(err).max()),
            "valid": int(ok.sum())}


def raster_values(path: Path) -> np.ndarray:
    import rasterio

    with rasterio.open(path) as src:
        return src.read(1, masked=True).astype("float64").filled(np.nan)


def machine() -> str:
    from importlib.metadata import version

    import numba
    import rasterio

    gdal = subprocess.run(["gdal_grid", "--version"], capture_output=True, text=True).stdout.strip() \
        if shutil.which("gdal_grid") else "gdal_grid not installed"
    return machine_facts(f"numba {numba.__version__}", f"scipy {version('scipy')}",
                         f"dask {version('dask')}",
                         f"rasterio {rasterio.__version__} (GDAL {rasterio.__gdal_version__})",
                         f"gdal_grid: {gdal}")


def main(small: bool = False, big: bool = True, whole_only: bool = False) -> str:
    load = load_note()
    n_points = 100_000 if small else 1_000_000
    width, cell = grid_shape(n_points)
    work = Path(tempfile.mkdtemp(prefix="dem_bench_"))
    try:
        print(f"dem bench: {n_points:,} points -> {width} x {width} cells in {work}", flush=True)
        make_data(work, n_points)
        whole = whole_process_rows(work, n_points, 10_000 if small else 100_000)
        first = first_run_rows(work)
        if whole_only:
            text = "\n".join(whole_process_table(whole, first)
                              + ["", f"Machine: {machine()}; {load}.", ""])
            print(text)
            return text
        r = {name: measure(name, work, n_points)
             for name in ("idw", "tin_linear", "quadratic", "nearest", "griddata")}
        acc = {name: accuracy(raster_values(work / f"{name}.tif"), n_points)
               for name in ("idw", "tin_linear", "quadratic", "nearest")}
        acc["griddata"] = accuracy(np.load(work / "griddata.npy"), n_points)
        gdal = {
            "invdistnn": measure_gdal_grid(
                "invdistnn", f"invdistnn:power=2.0:max_points=12:radius={IDW_RADIUS}:"
                "nodata=-9999", work, n_points),
            "linear": measure_gdal_grid("linear", "linear:radius=0:nodata=-9999", work, n_points),
        }
        for label, result in gdal.items():
            if result is not None:
                acc[f"gdal_{label}"] = accuracy(raster_values(work / f"gdal_{label}.tif"),
                                                n_points)
        big_result = measure("big_nearest", work, n_points) if big else None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    text = table(r, gdal, acc, big_result, n_points, width, cell, load, whole, first)
    if not small:
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "dem.md").write_text(text)
    print(text)
    return text


def table(r: dict, gdal: dict, acc: dict, big: dict | None, n_points: int, width: int,
          cell: float, load: str, whole: list[dict], first: list[dict]) -> str:
    cells = width * width

    def line(what, ours_key, peer_label, peer, peer_acc_key):
        ours = r[ours_key]
        a = acc[ours_key]
        if peer is None:
            peer_text, ratio, peer_rmse = "not run", "-", "-"
        else:
            peer_text = f"{peer['seconds']:.2f} s, {peer['peak_mb']:.0f} MB"
            ratio = f"{peer['seconds'] / ours['seconds']:.1f}x"
            peer_rmse = f"{acc[peer_acc_key]['rmse']:.4f}" if peer_acc_key in acc else "-"
        return (f"| {what} | {ours['seconds']:.2f} s, {ours['peak_mb']:.0f} MB | "
                f"{a['rmse']:.4f} | {peer_label} | {peer_text} | {peer_rmse} | {ratio} |")

    quad = r["quadratic"]
    rate = quad["cells"] / quad["seconds"] / 1e6
    lines = [
        "## DEM gridding (dem:idw, dem:tin_linear, dem:quadratic)", "",
        f"{n_points:,} random points over 2 km x 2 km (EPSG:3003 coordinates) on an analytic "
        f"surface; output {width} x {width} cells of {cell:g} m ({cells / 1e6:.0f} M cells); "
        "RMSE against the surface at the cell centres. One run, side by side, each case in its "
        "own process (peak = its max RSS). Toolbox: `toolbox.run` end to end (read GeoPackage, "
        "merge duplicates, tiles on local threads, DEFLATE GeoTIFF, no overviews), after a "
        "warm-up; gdal_grid: the whole command on the same GeoPackage "
        "(GDAL_NUM_THREADS=ALL_CPUS); griddata: interpolation only, arrays in memory.", "",
        "| step | toolbox | toolbox RMSE (m) | peer | peer time, peak | peer RMSE (m) | "
        "peer / toolbox time |",
        "|---|---|---|---|---|---|---|",
        line("dem:idw, 12 neighbours, power 2, radius 12 m", "idw",
             "gdal_grid invdistnn (same power, max_points, radius)", gdal.get("invdistnn"),
             "gdal_invdistnn"),
        line("dem:tin_linear", "tin_linear", "gdal_grid linear", gdal.get("linear"),
             "gdal_linear"),
        line("dem:tin_linear", "tin_linear", "scipy griddata linear", r["griddata"], "griddata"),
        line("dem:quadratic, 12 neighbours", "quadratic", "-", None, ""),
        line("dem:nearest", "nearest", "-", None, ""),
        "",
        f"dem:quadratic: {quad['cells']:,} cells in {quad['seconds']:.2f} s = **{rate:.2f} "
        f"million cells per second** end to end (orders used: "
        f"{quad.get('method', {}).get('orders_used')}).",
        f"Step timings (s): idw {r['idw'].get('timings')}; tin_linear "
        f"{r['tin_linear'].get('timings')}; quadratic {quad.get('timings')}.",
    ]
    if big is not None:
        side = width * 10
        lines.append(
            f"Memory: dem:nearest to {side} x {side} cells ({side * side / 1e6:.0f} M cells, "
            f"{big.get('megabytes')} MB GeoTIFF) from the same points: **peak RSS "
            f"{big['peak_mb']:.0f} MB**, of which {big.get('rss_before_mb', 0):.0f} MB were "
            "already there before the run (interpreter, every algorithm module of the toolbox, "
            f"warm-up); {big['seconds']:.0f} s (tiles of 512 cells; the output is never held in "
            "memory). The 2000 x 2000 runs peak at the same level: memory does not grow with "
            "the output size (dem:tin_linear's does grow with the number of points, its TIN "
            "being built whole).")
    lines += whole_process_table(whole, first)
    lines += ["", f"Machine: {machine()}; {load}.", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    def own(parser):
        parser.add_argument("--no-big", dest="big", action="store_false")
        parser.add_argument("--whole-only", action="store_true",
                            help="only the whole-process dem:tin_linear rows")
        parser.add_argument("--crossover", action="store_true",
                            help="dem:tin_linear's numpy path against its numba path")

    args = case_arguments(__doc__.splitlines()[0], own)
    if args.case:
        print(json.dumps(run_case(args.case, args.work, args.points)))
    elif args.crossover:
        note = load_note()
        with tempfile.TemporaryDirectory() as tmp:
            table_lines = crossover_rows(Path(tmp))
        text = "\n".join(["## dem:tin_linear: numpy path against numba path (whole process)", "",
                          *table_lines, "", f"Machine: {machine()}; {note}.", ""])
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "dem_crossover.md").write_text(text)
        print(text)
    else:
        main(small=args.small, big=args.big, whole_only=args.whole_only)
