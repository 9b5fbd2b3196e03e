"""A Dask worker keeps the rasters its tiles read open across tasks (GDAL's block cache then
serves the blocks neighbouring tiles share), per thread, at most LIMIT of them, and opens a file
again once it was written again; the engine's tiles read through it on a cluster."""

from __future__ import annotations

import os
import pickle
import threading

import numpy as np
import rasterio
from rasterio.transform import from_origin

from toolbox.raster.datasets import WorkerDatasets, worker_datasets


def _raster(path, value: float) -> None:
    with rasterio.open(path, "w", driver="GTiff", width=8, height=6, count=1, dtype="float32",
                       crs="EPSG:32632", transform=from_origin(0, 6, 1, 1)) as dst:
        dst.write(np.full((1, 6, 8), value, dtype="float32"))


def test_kept_open_per_thread_reopened_when_rewritten_and_bounded(tmp_path):
    cache = WorkerDatasets()
    paths = [tmp_path / f"r{i}.tif" for i in range(WorkerDatasets.LIMIT + 2)]
    for i, p in enumerate(paths):
        _raster(p, i)
    first = cache.get(paths[0])
    assert cache.get(paths[0]) is first  # the same handle for the next tile
    other = []
    thread = threading.Thread(target=lambda: other.append(cache.get(paths[0])))
    thread.start()
    thread.join()
    assert other[0] is not first  # rasterio datasets are not thread-safe: one per thread
    _raster(paths[0], 99.0)  # written again: another size or time
    os.utime(paths[0], ns=(1, 1))
    again = cache.get(paths[0])
    assert again is not first and again.read(1)[0, 0] == 99.0
    for p in paths[1:]:
        cache.get(p)
    assert first.closed and again.closed  # the least recently read, beyond LIMIT
    assert not cache.get(paths[-1]).closed


def test_pickles_as_the_process_instance(tmp_path):
    from toolbox.raster.datasets import ThreadDatasets

    assert pickle.loads(pickle.dumps(WorkerDatasets())) is worker_datasets()
    assert worker_datasets() is worker_datasets()
    travelled = pickle.loads(pickle.dumps(ThreadDatasets()))  # a holder sent to a worker
    assert travelled is worker_datasets()
    _raster(tmp_path / "r.tif", 1.0)
    kept = travelled.get(tmp_path / "r.tif")
    travelled.close()  # its task's end: the worker keeps the raster for the next task
    assert not kept.closed and worker_datasets().get(tmp_path / "r.tif") is kept


def test_a_gdal_virtual_path_is_kept_by_its_name(tmp_path):
    _raster(tmp_path / "r.tif", 5.0)
    cache = WorkerDatasets()
    from rasterio.io import MemoryFile  # no network here: /vsimem/ is a virtual path too

    with MemoryFile((tmp_path / "r.tif").read_bytes(), filename="r.tif") as memory:
        first = cache.get(memory.name)
        assert memory.name.startswith("/vsimem/") and first.read(1)[0, 0] == 5.0
        assert cache.get(memory.name) is first
        first.close()
