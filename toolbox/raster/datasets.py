"""Rasters kept open per thread: rasterio datasets are not thread-safe, and a dataset kept open
lets GDAL's block cache serve the overlapping reads of neighbouring tiles. The one per-thread
dataset cache of the raster engine and the warp."""

from __future__ import annotations

import os
import threading
import warnings
from typing import Any


def file_stamp(path: Any) -> tuple[int, int]:
    """(size in bytes, modification time in ns) of a file: how a process tells that it sees the
    very file another closed, or that a file it keeps open was written again."""
    stat = os.stat(path)
    return stat.st_size, stat.st_mtime_ns


def open_quietly(path: Any) -> Any:
    """``rasterio.open(path)`` without the warning about a raster with no georeferencing (a
    photo is fine as it is)."""
    import rasterio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        return rasterio.open(path)


class ThreadDatasets:
    """``get(path)``: this thread's open dataset of ``path``; :meth:`close` closes every one.
    Pickles as the receiving process's :class:`WorkerDatasets` (a Dask worker opens its own
    and keeps them across its tasks)."""

    def __init__(self) -> None:
        self._local = threading.local()
        self._all: list[Any] = []
        self._lock = threading.Lock()

    def get(self, path: Any) -> Any:
        opened = getattr(self._local, "datasets", None)
        if opened is None:
            opened = self._local.datasets = {}
        dataset = opened.get(path)
        if dataset is None or dataset.closed:  # a reused thread after close(): open again
            dataset = opened[path] = open_quietly(path)
            with self._lock:
                self._all.append(dataset)
        return dataset

    def adopt(self, path: Any, dataset: Any) -> None:
        """Make the open ``dataset`` of ``path`` this thread's (closed by :meth:`close`)."""
        opened = getattr(self._local, "datasets", None)
        if opened is None:
            opened = self._local.datasets = {}
        opened[path] = dataset
        with self._lock:
            self._all.append(dataset)

    def close(self) -> None:
        with self._lock:
            for dataset in self._all:
                dataset.close()
            self._all.clear()

    def __reduce__(self):
        return worker_datasets, ()


class WorkerDatasets:
    """The rasters a Dask worker process keeps open across its tasks, per thread: the last
    :data:`LIMIT` files each thread read, keyed by absolute path, size and modification time (a
    file written again is opened again; 'dem.tif' of another run's folder is another file,
    however alike its size and time; a GDAL virtual path by its name only). Tiles of one input
    run one after another on a worker; a dataset opened per task loses GDAL's block cache, so
    every tile decompressed again the blocks its halo shares with its neighbours (a 6000 x
    6000 hillshade: 7.2 s of workers' CPU against 2.6 s for the whole local run). Pickles as
    the process's one instance (:func:`worker_datasets`)."""

    LIMIT = 8

    def __init__(self) -> None:
        self._local = threading.local()

    def get(self, path: Any) -> Any:
        from collections import OrderedDict

        try:
            key = (os.path.abspath(path), file_stamp(path))
        except (OSError, TypeError, ValueError):  # a GDAL virtual path (/vsicurl/...)
            key = (str(path), None)
        opened = getattr(self._local, "datasets", None)
        if opened is None:
            opened = self._local.datasets = OrderedDict()
        dataset = opened.get(key)
        if dataset is None or dataset.closed:
            dataset = opened[key] = open_quietly(path)
            while len(opened) > self.LIMIT:
                opened.popitem(last=False)[1].close()
        opened.move_to_end(key)
        return dataset

    def close(self) -> None:
        """Nothing: a holder closed after its task (a :class:`ThreadDatasets` that travelled
        here) leaves the worker's rasters open for its next tasks."""

    def __reduce__(self):
        return worker_datasets, ()


_WORKER_DATASETS: list[WorkerDatasets] = []


def worker_datasets() -> WorkerDatasets:
    """This process's :class:`WorkerDatasets` (made on first use)."""
    if not _WORKER_DATASETS:
        _WORKER_DATASETS.append(WorkerDatasets())
    return _WORKER_DATASETS[0]
