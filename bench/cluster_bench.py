"""A two-worker Dask cluster against local threads, whole process: wall time, the client's own CPU
and the workers' CPU, and the bytes of the outputs (issue 31: "writing and overviews off the
client where the storage allows").

Usage::

    .venv/bin/python bench/cluster_bench.py [--work /tmp/cluster_bench] [--runs 3] [--size 6000]

Cases: ``dem:hillshade`` of a SIZE x SIZE DEM and ``dem:idw`` of 400,000 points onto a grid of
the same size, each as a GeoTIFF with overviews and as a COG. The cluster is
``dask scheduler`` + ``dask worker --nworkers 2 --nthreads 1`` on this machine (the README's
two-worker run). Each run is its own ``toolbox run`` process, local and cluster interleaved;
medians. The client's CPU is the ``toolbox`` process's (user + system); the workers' is read
from their processes before and after the run. Writes ``bench/results/cluster.md``.
"""

from __future__ import annotations

import argparse
import hashlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from benchlib import load_note, machine_facts, write_results  # noqa: E402

TOOLBOX = str(Path(sys.executable).with_name("toolbox"))
DASK = str(Path(sys.executable).with_name("dask"))


def make_inputs(work: Path, size: int) -> dict[str, Path]:
    """A smooth DEM of ``size`` x ``size`` cells of 1 m and 400,000 points sampled from it."""
    import rasterio
    from rasterio.transform import from_origin

    dem = work / "dem.tif"
    points = work / "points.gpkg"
    if not dem.exists():
        rows, cols = np.mgrid[0:size, 0:size].astype("float32")
        z = 300 + 40 * np.sin(cols / 410.0) * np.cos(rows / 530.0) + 0.002 * (rows + cols)
        with rasterio.open(dem, "w", driver="GTiff", width=size, height=size, count=1,
                           dtype="float32", crs="EPSG:32632", tiled=True, blockxsize=512,
                           blockysize=512, compress="DEFLATE", predictor=3,
                           transform=from_origin(600_000, 4_800_000 + size, 1, 1)) as dst:
            dst.write(z.astype("float32"), 1)
    if not points.exists():
        import geopandas as gpd
        import shapely

        rng = np.random.default_rng(7)
        x = rng.uniform(0, size, 400_000)
        y = rng.uniform(0, size, 400_000)
        z = 300 + 40 * np.sin(x / 410.0) * np.cos((size - y) / 530.0)
        gpd.GeoDataFrame(geometry=shapely.points(600_000 + x, 4_800_000 + y, z),
                         crs="EPSG:32632").to_file(points, layer="points", engine="pyogrio")
    return {"dem": dem, "points": points}


def cases(inputs: dict[str, Path], size: int) -> dict[str, list[str]]:
    common = {"dem:hillshade": ["--INPUT", str(inputs["dem"])],
              "dem:idw": ["--INPUT", str(inputs["points"]), "--CELL_SIZE", "1",
                          "--EXTENT", f"600000,4800000,{600000 + size},{4800000 + size}"]}
    out = {}
    for alg, args in common.items():
        out[alg] = args
        out[f"{alg} --COG"] = [*args, "--COG", "true"]
    return out


def workers_cpu(pids: list[int]) -> float:
    """User + system CPU seconds so far of the processes ``pids`` and all their descendants."""
    import psutil

    total = 0.0
    for pid in pids:
        try:
            root = psutil.Process(pid)
            for p in [root, *root.children(recursive=True)]:
                times = p.cpu_times()
                total += times.user + times.system
        except psutil.Error:
            pass
    return total


def run(alg: str, args: list[str], output: Path, scheduler: str, worker_pids: list[int]):
    cmd = [TOOLBOX, "run", alg.split()[0], *args[:], "--OUTPUT", str(output),
           "--SCHEDULER", scheduler, "--overwrite"]
    before = workers_cpu(worker_pids)
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    client = r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime
    return wall, client, workers_cpu(worker_pids) - before


def start_cluster(port: int = 8786) -> tuple[list[subprocess.Popen], str]:
    address = f"tcp://127.0.0.1:{port}"
    scheduler = subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                  "--dashboard-address", "127.0.0.1:0"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(3)
    worker = subprocess.Popen([DASK, "worker", address, "--nworkers", "2", "--nthreads", "1",
                               "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    from distributed import Client

    with Client(address, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)
    return [scheduler, worker], address


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path,
                        default=Path(tempfile.gettempdir()) / "cluster_bench")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--size", type=int, default=6000)
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    inputs = make_inputs(args.work, args.size)
    note = load_note()
    procs, address = start_cluster()
    try:
        worker_pids = [procs[1].pid]
        rows = []
        for alg, alg_args in cases(inputs, args.size).items():
            name = alg.replace(":", "_").replace(" --", "_")
            times: dict[str, list] = {"local": [], "cluster": []}
            for i in range(args.runs + 1):
                for where, scheduler in (("local", "local"), ("cluster", address)):
                    result = run(alg, alg_args, args.work / f"{name}_{where}.tif", scheduler,
                                 worker_pids)
                    if i:  # the first round warms the workers (imports, numba's cache)
                        times[where].append(result)
            same = sha(args.work / f"{name}_local.tif") == sha(args.work / f"{name}_cluster.tif")
            med = {w: [statistics.median(x[k] for x in v) for k in range(3)]
                   for w, v in times.items()}
            rows.append(f"| `{alg}` | {med['local'][0]:.2f} / {med['local'][1]:.2f} | "
                        f"{med['cluster'][0]:.2f} / {med['cluster'][1]:.2f} / "
                        f"{med['cluster'][2]:.2f} | {med['local'][1] / med['cluster'][1]:.2f}x | "
                        f"{'yes' if same else 'NO'} |")
            print(rows[-1], flush=True)
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait()
    import dask

    lines = ["## A two-worker Dask cluster against local threads (`bench/cluster_bench.py`)", "",
             machine_facts(f"dask {dask.__version__}") + f"; {note}.", "",
             f"{args.size} x {args.size} cells of 1 m, GeoTIFF with overviews (or `--COG`); "
             f"medians of {args.runs} interleaved runs after a warm-up round, each a "
             "`toolbox run` process; the cluster is `dask scheduler` + `dask worker --nworkers "
             "2 --nthreads 1` on the same 2 cores (so not faster: the point is what leaves the "
             "client). Client CPU = the `toolbox` process's user + system time.", "",
             "What runs where on the cluster: the tiles on the workers; the client validates, "
             "plans, gathers the tiles in order and writes them (a GeoTIFF has one writer), then "
             "a worker makes the overviews, or the COG copy, of the closed file (it sees the "
             "file: shared storage). The workers' CPU is the cluster's whole cost (the tiles, "
             "their transfer and pickling): more than the local run's on the same 2 cores; a "
             "cluster pays off with more machines, and the client's share is what limits it.",
             "",
             "| run | local threads: wall / client CPU s | cluster: wall / client CPU / "
             "workers' CPU s | client CPU local / cluster | same bytes |",
             "|---|---:|---:|---:|:-:|", *rows, ""]
    write_results(HERE / "results" / "cluster.md", lines)


if __name__ == "__main__":
    main()
