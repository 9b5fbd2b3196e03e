"""Speed round three (#31): before/after and product/peer timings measured side by side in one
sitting, interleaved (A B A B ...), medians of ``--runs`` (default 5), each run its own process.

    .venv/bin/python bench/round3_bench.py                            # all, to results/round3.md
    .venv/bin/python bench/round3_bench.py read      --work /tmp/r3   # 1M-point read in tin:delaunay
    .venv/bin/python bench/round3_bench.py idw       --work /tmp/r3   # dem:idw duplicate step
    .venv/bin/python bench/round3_bench.py dupcheck  --work /tmp/r3   # the bare duplicate check
    .venv/bin/python bench/round3_bench.py tinwrite  --work /tmp/r3   # tin:delaunay to GeoPackage
    .venv/bin/python bench/round3_bench.py contours  --work /tmp/r3   # carto:contours vs gdal_contour
    .venv/bin/python bench/round3_bench.py startup                    # --version / list / help
    .venv/bin/python bench/round3_bench.py startup --python "now, editable=.venv/bin/python" \\
        --python "now, pip install .=/tmp/inst/bin/python"               # several installs

``--before PYTHON`` adds the same cases run by another interpreter (a checkout of the previous
main with its own venv) to get before/after ratios in the same sitting. A case's time is the
whole process's wall time, or the in-process seconds it prints as its last stdout line
(``{"seconds": ...}``). Prints a markdown table; the machine's load is stated with it.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from benchlib import load_note, machine_facts, rewrite_generated  # noqa: E402


def run_once(cmd: list[str], env: dict | None = None) -> dict[str, float]:
    """``{"wall": s, "cpu": s, "peak_mb": MB, ...}``: the whole process's wall time, CPU time
    (user + system, all its threads) and peak resident memory, and the figures the command
    prints as its last stdout line (a JSON object with ``"seconds"`` first, in process)."""
    t0 = time.perf_counter()
    # a neutral working folder: ``python -c`` puts it first on sys.path, and a checkout there
    # would shadow the interpreter's own toolbox
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, cwd=tempfile.gettempdir())
    peak = [0]
    watcher = threading.Thread(target=_watch_peak, args=(proc, peak), daemon=True)
    watcher.start()
    stdout, stderr = proc.communicate()
    wall = time.perf_counter() - t0
    watcher.join()
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = usage.ru_utime + usage.ru_stime - _CHILD_CPU[0]
    _CHILD_CPU[0] = usage.ru_utime + usage.ru_stime
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {stderr.strip()[-2000:]}")
    lines = stdout.strip().splitlines()
    figures = {"wall": wall, "cpu": cpu, "peak_mb": peak[0] / 1024.0}
    if lines and lines[-1].startswith('{"seconds"'):
        figures.update(json.loads(lines[-1]))
    return figures


_CHILD_CPU = [0.0]  # the children's CPU seconds counted so far


def _watch_peak(proc: subprocess.Popen, peak: list[int], poll: float = 0.02) -> None:
    """Keep the child's peak resident memory (``VmHWM``, kB) in ``peak[0]`` while it runs."""
    status = Path(f"/proc/{proc.pid}/status")
    while proc.poll() is None:
        try:
            for line in status.read_text().splitlines():
                if line.startswith("VmHWM"):
                    peak[0] = max(peak[0], int(line.split()[1]))
        except (OSError, ValueError):
            pass
        time.sleep(poll)


def interleaved(cases: dict[str, list[str]], runs: int, env: dict | None = None,
                settle: bool = False) -> dict[str, list[dict]]:
    """Every case once per round, ``runs`` rounds (after one untimed warm-up round).
    ``settle``: ``sync`` before each run (untimed), so that no run is throttled by the kernel
    writing back the gigabyte an earlier run left in the page cache."""
    times: dict[str, list[dict]] = {name: [] for name in cases}
    for round_ in range(runs + 1):
        for name, cmd in cases.items():
            if settle:
                os.sync()
            figures = run_once(cmd, env)
            if round_:
                times[name].append(figures)
    return times


def median(values: list[dict], key: str) -> float:
    return statistics.median(v[key] for v in values)


def table(times: dict[str, list[dict]], reference: str, header: str, key: str = "seconds",
          extra: tuple[str, ...] = ()) -> str:
    """Medians of ``key`` (and of the ``extra`` keys), range, ratio reference / case."""
    ref = median(times[reference], key)
    labels = "".join("peak MB | " if e == "peak_mb" else f"{e} s | " for e in extra)
    rows = [f"| {header} | median s | min-max s | {labels}"
            f"{reference} / this |", "|---|---:|---:|" + "---:|" * len(extra) + "---:|"]
    for name, values in times.items():
        med = median(values, key)
        spread = [v[key] for v in values]
        more = "".join(f"{median(values, e):.3f} | " for e in extra)
        rows.append(f"| {name} | {med:.3f} | {min(spread):.3f}-{max(spread):.3f} | {more}"
                    f"{ref / med:.2f}x |")
    return "\n".join(rows)


def in_process(python: str, code: str) -> list[str]:
    """A command timing ``code``'s last statement block; ``code`` sets ``seconds``."""
    return [python, "-c", code + "\nimport json; print(json.dumps({'seconds': seconds}))"]


# -- sections --------------------------------------------------------------------------------------
def points_file(work: Path, n: int) -> Path:
    folder = work / f"points_{n}"
    if not (folder / "points.gpkg").exists():
        import tin_bench

        folder.mkdir(parents=True, exist_ok=True)
        tin_bench.make_data(folder, n)
    return folder / "points.gpkg"


READ_GENERAL = """
import time
t0 = time.perf_counter()
from toolbox.io.vector import read_vector
from toolbox.io.vector_points import points_xyz
frame = read_vector({path!r}, name="INPUT")
frame = frame[frame.geometry.notna() & ~frame.geometry.is_empty]
xyz = points_xyz(frame, None, name="INPUT")
seconds = time.perf_counter() - t0
"""
READ_FAST = """
import time
t0 = time.perf_counter()
from toolbox.io.vector_points import read_points_xyz
xyz = read_points_xyz({path!r}, None, name="INPUT")
seconds = time.perf_counter() - t0
"""


def section_read(args) -> str:
    path = points_file(args.work, 1_000_000)
    py = sys.executable
    cases = {"general reader (tin:delaunay before: GeoDataFrame + points_xyz)":
             in_process(py, READ_GENERAL.format(path=str(path))),
             "fast reader (dem:idw, and tin:delaunay now)":
             in_process(py, READ_FAST.format(path=str(path)))}
    times = interleaved(cases, args.runs)
    return ("1,000,000 PointZ in a GeoPackage, read to an (N, 3) array, in process (imports "
            "included)\n\n" + table(times, next(iter(cases)), "reader"))


IDW_RUN = """
import json, sys, time
import toolbox
from toolbox.feedback import Feedback
x0, y0, size, width = {x0}, {y0}, {size}, {width}
params = {{"INPUT": {path!r}, "OUTPUT": {out!r}, "CELL_SIZE": size / width, "OVERVIEWS": False,
          "EXTENT": f"{{x0}},{{y0}},{{x0 + size}},{{y0 + size}}", **{extra!r}}}
feedback = Feedback()
t0 = time.perf_counter()
toolbox.run("dem:idw", params, feedback=feedback, overwrite=True)
total = time.perf_counter() - t0
print(json.dumps({{"seconds": feedback.timings["duplicates"], "total": total,
                  "tiles": feedback.timings["tiles"]}}))
"""
DUPLICATE_CHECK = """
import json, time
import numpy as np
from toolbox.terrain.gridding.neighbours import PointBins
rng = np.random.default_rng(1)
xy = rng.uniform(0, 1000, ({n}, 2)) * {scale}  # clustered: {n} points in {share} of the box
xy[0] = (1000.0, 1000.0)
bins = PointBins.build(xy)
bins.has_duplicates()  # numba's first calls and kernel cache off the clock
t0 = time.perf_counter()
found = bins.has_duplicates()
print(json.dumps({{"seconds": time.perf_counter() - t0}}))
"""


def section_idw(args) -> str:
    """dem:idw with and without RADIUS (100k and 1M points): the duplicate step."""
    import tin_bench

    pythons = {"now": sys.executable}
    if args.before:
        pythons = {"before": args.before, **pythons}
    out = []
    for n in (100_000, 1_000_000):
        path = points_file(args.work, n)
        width = int(round(2000 * (n / 1_000_000) ** 0.5))
        cases = {}
        for label, python in pythons.items():
            for radius in (None, 100.0):
                extra = {} if radius is None else {"RADIUS": radius}
                code = IDW_RUN.format(x0=tin_bench.X0, y0=tin_bench.Y0, size=tin_bench.SIZE,
                                      width=width, path=str(path), extra=extra,
                                      out=str(args.work / f"idw_{label}_{n}.tif"))
                cases[f"{label}, {n:,} points, RADIUS {radius or 'none'}"] = [python, "-c",
                                                                              code]
        times = interleaved(cases, args.runs)
        out.append(f"dem:idw, {n:,} uniform points to {width} x {width} cells, in process after "
                   "the imports: the `duplicates` step (local origin, bins, duplicate check), "
                   "with the run's total and its `tiles` step\n\n"
                   + table(times, next(iter(cases)), "run", extra=("total", "tiles")))
    return "\n\n".join(out)


def section_dupcheck(args) -> str:
    """The bare duplicate check on uniform and clustered points, before and after."""
    pythons = {"now": sys.executable}
    if args.before:
        pythons = {"before": args.before, **pythons}
    cases = {}
    for label, python in pythons.items():
        for share in ("1", "0.001", "0.0001"):
            cases[f"{label}, 1,000,000 points in {share} of the box"] = [
                python, "-c", DUPLICATE_CHECK.format(n=1_000_000, scale=float(share) ** 0.5,
                                                     share=share)]
    times = interleaved(cases, args.runs)
    return ("`PointBins.has_duplicates` on 1,000,000 points spread over the bounding box or "
            "clustered in 0.1 % or 0.01 % of it (one far point stretches the box), in process, its second "
            "call (the first loads numba's kernel)\n\n" + table(times, next(iter(cases)), "points"))


TRIANGLE_RUN = """
import json, time
import numpy as np
import triangle
xy = np.ascontiguousarray(np.load({path!r})[:, :2])
t0 = time.perf_counter()
tri = triangle.triangulate({{"vertices": xy}}, "")["triangles"]
print(json.dumps({{"seconds": time.perf_counter() - t0}}))
"""


def section_tinwrite(args) -> str:
    """tin:delaunay on 1M points to a GeoPackage with the defaults (edges and spatial index),
    whole process, before/after; Triangle in memory as the peer."""
    n = args.points or 1_000_000
    path = points_file(args.work, n)
    cases = {"Triangle in memory (no I/O)": [sys.executable, "-c", TRIANGLE_RUN.format(
        path=str(path.with_name("points.npy")))]}
    pythons = {"now": sys.executable}
    if args.before:
        pythons = {"before": args.before, **pythons}
    for label, python in pythons.items():
        exe = str(Path(python).with_name("toolbox"))
        out = args.work / f"tin_{label}.gpkg"
        cases[f"tin:delaunay {label} (GeoPackage, edges, index)"] = [
            exe, "run", "tin:delaunay", "--INPUT", str(path), "--OUTPUT", str(out),
            "--overwrite", "-q"]
    times = interleaved(cases, args.runs, settle=True)  # 1.4 GB written a run
    for values in times.values():  # the peer's figure is its in-process time
        for v in values:
            v.setdefault("seconds", v["wall"])
    return (f"{n:,} points: `toolbox run tin:delaunay` to a GeoPackage with the defaults "
            "(edges layer and spatial indexes), whole process (wall, and CPU = user + system), "
            "against Triangle's triangulation in memory; `sync` before each run (untimed)\n\n"
            + table(times, next(iter(cases)), "run", extra=("cpu", "peak_mb")))


def make_dem(path: Path, size: int = 2000) -> None:
    """The demo relief (matplotlib's jacksboro DEM) resampled to ``size`` x ``size`` cells of
    1 m (cubic spline)."""
    from affine import Affine
    from scipy.ndimage import zoom

    from toolbox.demo.samples.terrain import CRS, XMIN, YMAX, terrain
    from toolbox.raster.writer import write_raster

    z, _ = terrain()
    z = zoom(z.astype("float64"), (size / z.shape[0], size / z.shape[1]), order=3)
    write_raster(path, z.astype("float32"), Affine(1.0, 0, XMIN, 0, -1.0, YMAX), CRS,
                 nodata=-9999.0)


TRACE_BLOCKS = """
import json, time
import numpy as np
import rasterio
from toolbox.cartography.contours import block_windows, contour_levels
with rasterio.open({path!r}) as src:
    z = src.read(1, masked=True).astype("float64").filled(np.nan)
levels = contour_levels(np.nanmin(z), np.nanmax(z), 1.0)
levels = levels - 1024 * np.spacing(np.abs(levels))
blocks = [np.ascontiguousarray(z[r:r + h, c:c + w])
          for r, c, h, w in block_windows(*z.shape, 512)]
if {kernel!r}:
    from toolbox.cartography.contour_kernel import grid_lines
    grid_lines(blocks[0][:8, :8], levels)  # numba's cached kernels loaded off the clock

    def trace(b):
        grid_lines(b, levels)
else:
    import contourpy

    def trace(b):  # what carto:contours did before: the block's own levels, one pass each
        lv = levels[(levels >= np.nanmin(b)) & (levels < np.nanmax(b))]
        gen = contourpy.contour_generator(np.arange(b.shape[1], dtype=float),
                                          np.arange(b.shape[0], dtype=float), b,
                                          line_type=contourpy.LineType.ChunkCombinedOffset)
        gen.multi_lines(lv)
t0, c0 = time.perf_counter(), time.process_time()
for b in blocks:
    trace(b)
print(json.dumps({{"seconds": time.perf_counter() - t0, "cpu": time.process_time() - c0}}))
"""


def section_contours(args) -> str:
    """carto:contours against gdal_contour on a 2000 x 2000 DEM, 1 m interval, whole process;
    and the total length of the two line sets inside the cell-centre box."""
    import shutil

    import geopandas as gpd
    import rasterio
    import shapely

    dem = args.work / "dem2000.tif"
    if not dem.exists():
        make_dem(dem)
    gdal_out = args.work / "gdal_contours.gpkg"
    cases = {"gdal_contour -i 1": ["sh", "-c", f"rm -f {gdal_out} && "
                                   f"{shutil.which('gdal_contour')} -q -i 1 -a elev "
                                   f"{dem} {gdal_out}"]}
    pythons = {"now": sys.executable}
    if args.before:
        pythons = {"before": args.before, **pythons}
    for label, python in pythons.items():
        cases[f"carto:contours {label}"] = [
            str(Path(python).with_name("toolbox")), "run", "carto:contours", "--INPUT", str(dem),
            "--OUTPUT", str(args.work / f"contours_{label}.gpkg"), "--INTERVAL", "1",
            "--overwrite", "-q"]
    # the same run with numba's JIT instead of the kernel compiled ahead of time (toolbox.aot)
    cases["carto:contours now, numba's JIT (TOOLBOX_AOT=0)"] = [
        "env", "TOOLBOX_AOT=0", *cases["carto:contours now"][:6],
        str(args.work / "contours_now_jit.gpkg"), *cases["carto:contours now"][7:]]
    times = interleaved(cases, args.runs)
    for values in times.values():
        for v in values:
            v["seconds"] = v["wall"]
    with rasterio.open(dem) as src:
        t = src.transform
        box = shapely.box(t.c + 0.5, t.f - src.height + 0.5, t.c + src.width - 0.5, t.f - 0.5)
    gdal = gpd.read_file(gdal_out)
    ours = gpd.read_file(args.work / "contours_now.gpkg", layer="contours")
    ref_len = float(shapely.length(shapely.intersection(gdal.geometry.values, box)).sum())
    our_len = float(shapely.length(ours.geometry.values).sum())
    same = sorted(set(gdal["elev"])) == sorted(set(ours["elev"]))
    trace = interleaved({
        "contourpy, each block's levels one pass each (before)":
            [sys.executable, "-c", TRACE_BLOCKS.format(path=str(dem), kernel=False)],
        "one-pass kernel (now)":
            [sys.executable, "-c", TRACE_BLOCKS.format(path=str(dem), kernel=True)]},
        args.runs)
    from toolbox.aot import compiled_available

    aot_note = ("*now* traces with the kernel compiled ahead of time (`toolbox warmup`, "
                "toolbox.aot: no numba import)" if compiled_available("contour_lines") else
                "no kernel compiled ahead of time on this machine (`toolbox warmup` did not "
                "build it): *now* is numba's JIT too")
    return (f"{aot_note}.\n\n2000 x 2000 DEM of 1 m (the demo relief resampled), 1 m interval: "
            f"{len(set(ours['elev']))} levels (gdal_contour's the same: {same}); total length "
            f"{our_len:.0f} m against gdal_contour's {ref_len:.0f} m inside the cell-centre box "
            f"({100 * (our_len / ref_len - 1):+.3f} %). Whole process, wall and CPU\n\n"
            + table(times, next(iter(cases)), "command", extra=("cpu",))
            + "\n\nTracing alone, in process, one thread: the 16 blocks of 513 x 513 cells "
            "(TILE_SIZE 512), wall and CPU\n\n"
            + table(trace, next(iter(trace)), "tracer", extra=("cpu",)))


STARTUP_POINTS = 10_000


def startup_points(work: Path) -> Path:
    """10,000 PointZ with a float field, EPSG:3003, one GeoPackage layer (``vector:info``)."""
    path = work / "startup_points.gpkg"
    if not path.exists():
        import geopandas as gpd
        import numpy as np
        import shapely

        rng = np.random.default_rng(31)
        x, y = rng.uniform(0, 300, (2, STARTUP_POINTS)) + [[1_687_000.0], [4_798_500.0]]
        z = rng.uniform(300, 400, STARTUP_POINTS)
        gpd.GeoDataFrame({"z": z}, geometry=shapely.points(x, y, z), crs="EPSG:3003").to_file(
            path, layer="pts")
    return path


def section_startup(args) -> str:
    """``toolbox --version`` / ``list`` / ``help dem:idw --json`` against ``gdalinfo --version``,
    and ``toolbox run vector:info`` on 10,000 points (also against ``ogrinfo -so -al``), whole
    process, for every interpreter of ``--python`` (an editable install and a ``pip install .``,
    before and now); each interpreter with its own spec-index cache folder (warm), Python
    allowed to write its bytecode caches as on a user's machine (``PYTHONDONTWRITEBYTECODE``
    removed)."""
    import shutil

    pythons = dict(p.split("=", 1) for p in args.python) or {"now": sys.executable}
    points = startup_points(args.work)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    cases = {"gdalinfo --version": [shutil.which("gdalinfo") or "gdalinfo", "--version"],
             "ogrinfo -so -al (10,000 points)": [shutil.which("ogrinfo") or "ogrinfo", "-so",
                                                 "-al", str(points)]}
    for label, python in pythons.items():
        cache = args.work / f"cache_{label.replace(' ', '_').replace('.', '')}"
        exe = str(Path(python).with_name("toolbox"))
        for command in (["--version"], ["list"], ["help", "dem:idw", "--json"],
                        ["run", "vector:info", "--INPUT", str(points)]):
            name = " ".join(command[:3]) if command[0] != "run" else "run vector:info"
            cases[f"toolbox {name} ({label})"] = ["env", f"XDG_CACHE_HOME={cache}", exe, *command]
    times = interleaved(cases, max(args.runs, 10), env)
    labels = ", ".join(f"*{label}* = {python}" for label, python in pythons.items())
    return (f"Whole process, CPU (user + system: what load on the shared cores changes least) "
            f"and wall time, medians of the interleaved runs; {labels}; `vector:info` on "
            f"{STARTUP_POINTS:,} PointZ in a GeoPackage. The ratio is gdalinfo's CPU time over "
            "the row's (above 1: the row is faster)\n\n"
            + table(times, next(iter(cases)), "command (CPU s)", key="cpu", extra=("wall",)))


SECTIONS = {"read": section_read, "idw": section_idw, "tinwrite": section_tinwrite,
            "contours": section_contours,
            "startup": section_startup,
            "dupcheck": section_dupcheck}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sections", nargs="*", choices=[[], *sorted(SECTIONS)],
                        help="default: all, written to bench/results/round3.md")
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "round3_bench")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--before", help="python of the previous version (before/after rows)")
    parser.add_argument("--python", action="append", default=[], metavar="LABEL=PYTHON",
                        help="startup: an interpreter to measure, under a label (repeat it)")
    parser.add_argument("--points", type=int, help="tinwrite: points (default 1,000,000)")
    args = parser.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    path = HERE / "results" / "round3.md"
    for name in args.sections or list(SECTIONS):
        head = f"{machine_facts()}. {load_note()}; load average {os.getloadavg()[0]:.1f}."
        lines = [f"### {name}", "", head, "", SECTIONS[name](args)]
        print("\n".join(lines), flush=True)
        # each section's table between its markers: the notes written under it are kept
        old = path.read_text() if path.exists() else "## Speed round three (`bench/round3_bench.py`)\n"
        path.write_text(rewrite_generated(old, "round3", {name: lines}))


if __name__ == "__main__":
    main()
