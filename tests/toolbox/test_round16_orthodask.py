"""Round 16 (orthodask): the algorithms that hand a coordinate map to the shared raster engine
run on a Dask cluster of worker *processes*, as the README's "Scaling out" says.

``ortho:photo --SCHEDULER tcp://...`` stopped with exit 3 ("Could not serialize ...": the
orthophoto's map, :class:`~toolbox.ortho.windows.OrthoWindows`, held a lock and thread-local
buffers; the RPC ortho's map a lock), and the per-window statistics of the report were kept on
the map object, so a worker's counts would not have come back. Now the maps pickle without
them and each window's statistics (and the occlusion mask and incidence angles) travel back
with the tile's result: the files' pixels and the report are those of ``SCHEDULER local``.
"""

from __future__ import annotations

import pickle
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio

import toolbox
import toolbox.raster.warp

TESTS = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(TESTS / "algorithms" / "ortho"))
sys.path.insert(0, str(TESTS / "algorithms" / "stereo"))
import ortho_scene  # noqa: E402
import rpc_scene  # noqa: E402
import stereo_scene  # noqa: E402


def _read(path) -> np.ndarray:
    with rasterio.open(path) as src:
        return src.read()


def _not_here(*args, **kwargs):
    raise AssertionError("a tile's work ran in the client, not on a worker")


def _on_workers(monkeypatch):
    """The warp's window function fails in this (the client's) process: a run that succeeds
    warped its windows on the worker processes, which import their own module."""
    monkeypatch.setattr(toolbox.raster.warp, "warp_window", _not_here)


def _local_and_cluster(alg, params, outputs, cluster, monkeypatch, tmp_path, files=()):
    """Run ``alg`` with SCHEDULER local, then on the cluster; the arrays of ``outputs`` (the
    parameters naming output rasters) and the STATISTICS of each run (``files``: other
    outputs, one per run)."""
    runs = {}
    for where in ("local", cluster):
        tag = "local" if where == "local" else "dask"
        named = {name: tmp_path / f"{tag}_{name.lower()}.tif" for name in outputs}
        others = {name: tmp_path / f"{tag}_{name.lower()}.json" for name in files}
        with monkeypatch.context() as patch:
            if where != "local":
                _on_workers(patch)
            stats = toolbox.run(alg, params | named | others | {"SCHEDULER": where})
        stats = stats["STATISTICS"]
        runs[tag] = ([_read(p) for p in named.values()], stats)
    return runs["local"], runs["dask"]


@pytest.fixture(scope="module")
def ortho_block(tmp_path_factory):
    """A random 800 x 800 photo of the synthetic block (its content does not matter here: the
    same bytes must come out), its project and the hilly DEM."""
    folder = tmp_path_factory.mktemp("orthodask")
    from toolbox.photogrammetry.synthetic import hills_dem, write_photo

    z, transform = hills_dem(ortho_scene.BOUNDS, cell=10.0, relief=ortho_scene.RELIEF,
                             base=ortho_scene.BASE, seed=3)
    rng = np.random.default_rng(11)
    photo = write_photo(folder / "p1.tif", rng.integers(1, 255, (800, 800), dtype="uint8"))
    dem = ortho_scene.write_dem(folder / "dem.tif", z, transform)
    project = ortho_scene.project_yaml(folder / "project.yaml", "p1.tif")
    return {"INPUT": photo, "PROJECT": project, "DEM": dem}


# 1100 x 200 cells of 2.5 m: two output windows (1024 + 76 columns), the photo in both
ORTHO_EXTENT = "1686750,4799000,1689500,4799500"


@pytest.mark.distributed
@pytest.mark.parametrize("extra, outputs", [
    ({}, ["OUTPUT"]),  # the planned windows (the common case)
    ({"OCCLUSION": True}, ["OUTPUT", "OCCLUSION_MASK", "INCIDENCE"]),  # measured, aux rasters
], ids=["planned", "occlusion"])
def test_ortho_photo_on_worker_processes_is_the_local_ortho(ortho_block, cluster, monkeypatch,
                                                            tmp_path, extra, outputs):
    params = ortho_block | {"CELL_SIZE": 2.5, "EXTENT": ORTHO_EXTENT, "OVERVIEWS": False} | extra
    (local, ls), (dask, ds) = _local_and_cluster("ortho:photo", params, outputs, cluster,
                                                 monkeypatch, tmp_path)
    assert local[0].shape[1:] == (200, 1100)
    alpha = local[0][-1]
    assert alpha[:, :1024].any() and alpha[:, 1024:].any()  # the photo in both windows
    for a, b in zip(local, dask, strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    assert ds == ls
    assert ls["cells"] == 200 * 1100 and ls["warp"]["windows"] == 2
    assert 0 < ls["outside_photo_fraction"] < 1 and ls["max_relief_displacement_m"] > 1


@pytest.mark.distributed
def test_rpc_ortho_on_worker_processes_is_the_local_ortho(cluster, monkeypatch, tmp_path):
    ramp = rpc_scene.write_ramp(tmp_path / "ramp.tif", rpc_scene.synthetic_rpc(), 1200, 1000)
    dem = rpc_scene.write_synthetic_dem(tmp_path / "dem.tif")
    params = {"INPUT": ramp, "DEM": dem, "CELL_SIZE": 4.0, "OVERVIEWS": False,
              "EXTENT": "656000,4983300,660400,4984100"}  # 1100 x 200 cells: two windows
    (local, ls), (dask, ds) = _local_and_cluster("ortho:photo", params, ["OUTPUT"], cluster,
                                                 monkeypatch, tmp_path)
    assert local[0][-1].any() and np.array_equal(local[0], dask[0])
    assert ds == ls and ls["cells"] == 1100 * 200 and ls["warp"]["windows"] == 2


@pytest.mark.distributed
def test_epipolar_pair_on_worker_processes_is_the_local_pair(cluster, monkeypatch, tmp_path):
    rng = np.random.default_rng(5)
    from toolbox.photogrammetry.synthetic import write_photo

    for name in ("L", "R"):
        write_photo(tmp_path / f"{name}.tif", rng.integers(1, 255, (600, 600), dtype="uint8"))
    params = {"PROJECT": stereo_scene.project_yaml(tmp_path / "project.yaml"), "LEFT": "L",
              "RIGHT": "R", "TERRAIN_HEIGHT": 320.0}
    (local, ls), (dask, ds) = _local_and_cluster(
        "stereo:epipolar", params, ["OUTPUT_LEFT", "OUTPUT_RIGHT"], cluster, monkeypatch,
        tmp_path, files=["TRANSFORM"])
    assert all(a[-1].any() for a in local)
    assert all(np.array_equal(a, b) for a, b in zip(local, dask, strict=True))
    assert ds == ls


@pytest.mark.distributed
def test_volume_against_a_dem_on_worker_processes_is_the_local_volume(cluster, monkeypatch,
                                                                       tmp_path):
    import geopandas as gpd
    import shapely
    from affine import Affine

    x0, y0, size = 1_688_000.0, 4_799_500.0, 600  # 2 x 2 tiles of 512 cells
    rng = np.random.default_rng(5)
    xy = np.vstack([[[x0, y0], [x0 + size, y0], [x0 + size, y0 + size], [x0, y0 + size]],
                    np.column_stack([rng.uniform(0, size, 100) + x0,
                                     rng.uniform(0, size, 100) + y0])])
    z = 250 + 5 * np.sin(xy[:, 0] / 50.0)
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z),
                     crs="EPSG:3003").to_file(tmp_path / "points.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "points.gpkg",
                                 "OUTPUT": tmp_path / "tin.gpkg"})
    centres = np.arange(size) + 0.5
    _, gy = np.meshgrid(x0 + centres, y0 + size - centres)
    dem = 250 + 3 * np.cos(gy / 40.0)
    dem[290:330, 100:560] = -9999.0  # no height across the tiles' border
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=size, height=size,
                       count=1, dtype="float64", crs="EPSG:3003", nodata=-9999.0,
                       transform=Affine(1.0, 0, x0, 0, -1.0, y0 + size)) as dst:
        dst.write(dem, 1)
    params = {"TIN": tmp_path / "tin.gpkg", "REFERENCE_DEM": tmp_path / "dem.tif"}
    local = toolbox.run("tin:volume", params | {"SCHEDULER": "local"})["STATISTICS"]
    with monkeypatch.context() as patch:  # the tiles' TIN is rasterised on the workers
        import toolbox.terrain.tin.kernels as kernels

        patch.setattr(kernels, "rasterize_tin", _not_here)
        remote = toolbox.run("tin:volume", params | {"SCHEDULER": cluster})["STATISTICS"]
    assert remote == local
    assert local["cells_without_dem"] == 40 * 460 and local["cut_volume"] > 0


def test_window_results_pickle_empty_and_come_back_by_tile(ortho_block, tmp_path):
    """Without a cluster: the ortho's map pickles (no lock, thread-local or writer), its copy
    starts without results, and the results of the windows inside a tile (the parts a warp
    split it into too) move from the copy to the caller's map."""
    from rasterio.windows import Window

    from toolbox.io.grid import GridSpec
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler
    from toolbox.ortho.sensor import CollinearityMap
    from toolbox.ortho.windows import OrthoWindows
    from toolbox.photogrammetry.synthetic import frame_photo

    photo = frame_photo(ortho_scene.CENTRE, ortho_scene.ANGLES, width=800, height=800,
                        crs=ortho_scene.CRS)
    grid = GridSpec.from_bounds((1687000.0, 4798000.0, 1689000.0, 4800000.0), 10.0,
                                ortho_scene.CRS)
    sampler = DemSampler(open_raster_info(ortho_block["DEM"]), grid.crs)
    here = OrthoWindows(photo, grid, sampler, CollinearityMap(photo, block=32), 300.0)
    there = pickle.loads(pickle.dumps(here))
    assert there.window_results() == {}
    tile, parts = Window(0, 0, 200, 100), [Window(0, 0, 100, 100), Window(100, 0, 100, 100)]
    other = Window(0, 100, 200, 100)
    for window in [tile, *parts, other]:
        there.measured(window)
    assert there.take_window_results(Window(0, 0, 50, 50)) is None
    here.merge_window_results(there.take_window_results(tile))
    assert sorted(here.window_results()) == [(0, 0, 100, 100), (0, 0, 200, 100), (100, 0, 100, 100)]
    assert list(there.window_results()) == [(0, 100, 200, 100)]
    assert here.totals().cells == 200 * 100  # the parts, not their parent too


@pytest.mark.distributed
def test_relative_paths_reach_workers_running_in_another_directory(ortho_block, cluster,
                                                                   monkeypatch, tmp_path):
    """The workers started in the test's first directory; the runs give the rasters relative
    to another one (the caller's): a worker read 'p1.tif' in its own directory and the run
    stopped with exit 3 ("p1.tif: No such file or directory"). The engine's inputs, the
    warp's photo and the DEM sampler now read them in the client's folder (the executor runs
    a run's tasks there), as the sampler's heights taken on a worker show."""
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler

    monkeypatch.chdir(ortho_block["DEM"].parent)
    params = {"INPUT": "p1.tif", "PROJECT": "project.yaml", "DEM": "dem.tif", "CELL_SIZE": 5.0,
              "EXTENT": ORTHO_EXTENT, "OVERVIEWS": False}
    for alg, run in (("ortho:photo", params), ("dem:slope", {"INPUT": "dem.tif",
                                                             "TILE_SIZE": 128})):
        files = {}
        for where in ("local", cluster):
            files[where] = tmp_path / f"{alg[-5:]}_{len(files)}.tif"
            toolbox.run(alg, run | {"SCHEDULER": where, "OUTPUT": files[where]})
        assert np.array_equal(*(_read(f) for f in files.values())), alg
    from functools import partial

    from toolbox.executor import map_tiles

    info = open_raster_info("dem.tif")  # relative: the workers started in another folder
    sampler = DemSampler(info, None)
    left, bottom, right, top = info.bounds
    xs = np.linspace(left, right, 7)[1:-1]
    ys = np.linspace(bottom, top, 7)[1:-1]
    local = sampler.heights(xs, ys)
    there = next(map_tiles(partial(sampler.heights, xs), [ys], scheduler=cluster))
    assert np.isfinite(local).all() and np.array_equal(there, local)


def test_relative_paths_of_every_cluster_algorithm(ortho_block, cluster, monkeypatch):
    """ortho:batch (its DEM), mosaic:cut (its raster, and its FOLDER written by the workers)
    and carto:contours read their relative inputs on the workers themselves: each stopped with
    exit 3 ("dem.tif: No such file or directory"). A worker now runs the run's tasks in the
    client's working folder: the same outputs as a local run."""
    import pyogrio

    folder = ortho_block["DEM"].parent
    monkeypatch.chdir(folder)
    outputs = {}
    for where in ("local", cluster):
        tag = "local" if where == "local" else "dask"
        toolbox.run("ortho:batch", {"PROJECT": "project.yaml", "DEM": "dem.tif",
                                    "CELL_SIZE": 5.0, "FOLDER": f"batch_{tag}",
                                    "OUTPUT": f"batch_{tag}.json",
                                    "SCHEDULER": where}, overwrite=True)
        toolbox.run("mosaic:cut", {"INPUT": f"batch_{tag}/p1.tif", "SCALE": 500,
                                   "SHEET_WIDTH": 150, "SHEET_HEIGHT": 150,
                                   "OUTPUT": f"cut_{tag}", "SCHEDULER": where}, overwrite=True)
        toolbox.run("carto:contours", {"INPUT": "dem.tif", "INTERVAL": 5,
                                       "OUTPUT": f"contours_{tag}.gpkg", "SCHEDULER": where},
                    overwrite=True)
        outputs[tag] = {"ortho": _read(folder / f"batch_{tag}" / "p1.tif"),
                        "sheets": sorted(p.name for p in (folder / f"cut_{tag}").glob("*.tif")),
                        "lines": len(pyogrio.read_dataframe(folder / f"contours_{tag}.gpkg"))}
    assert np.array_equal(outputs["local"]["ortho"], outputs["dask"]["ortho"])
    assert outputs["local"]["sheets"] == outputs["dask"]["sheets"] and outputs["local"]["sheets"]
    assert outputs["local"]["lines"] == outputs["dask"]["lines"] > 0


class _CountedCall:
    """A callable whose unpickling is counted per process (on ``sys``: the counter must
    outlive the class, which Dask may send by value)."""

    def __init__(self):
        self.payload = np.zeros(100_000)  # what a kernel holding a DEM carries

    def __setstate__(self, state):
        import sys

        self.__dict__.update(state)
        sys._toolbox_test_unpickled = getattr(sys, "_toolbox_test_unpickled", 0) + 1

    def __call__(self, task):
        import os
        import sys

        return task, os.getpid(), getattr(sys, "_toolbox_test_unpickled", 0)


def test_a_shared_kernel_travels_to_each_worker_once(cluster):
    """map_tiles sent a callable object (the engine's kernel with its inputs: a DEM of up to
    128 MB for an ortho) with every task; it is now sent once, each worker fetching it once."""
    import sys

    import cloudpickle

    from toolbox.executor import Executor, map_tiles

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        results = list(map_tiles(_CountedCall(), range(12), executor=Executor("dask", 0, cluster,
                                                                               "SCHEDULER")))
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    assert [r[0] for r in results] == list(range(12))
    per_process: dict[int, int] = {}
    for _, pid, count in results:
        per_process[pid] = max(per_process.get(pid, 0), count)
    assert len(per_process) >= 1 and max(per_process.values()) == 1, per_process
