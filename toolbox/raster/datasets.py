"""Rasters kept open per thread: rasterio datasets are not thread-safe, and a dataset kept open
lets GDAL's block cache serve the overlapping reads of neighbouring tiles. The one per-thread
dataset cache of the raster engine and the warp."""

from __future__ import annotations

import threading
import warnings
from typing import Any


class ThreadDatasets:
    """``get(path)``: this thread's open dataset of ``path``; :meth:`close` closes every one.
    Pickles empty (a Dask worker opens its own)."""

    def __init__(self) -> None:
        self._local = threading.local()
        self._all: list[Any] = []
        self._lock = threading.Lock()

    def get(self, path: Any) -> Any:
        import rasterio

        opened = getattr(self._local, "datasets", None)
        if opened is None:
            opened = self._local.datasets = {}
        dataset = opened.get(path)
        if dataset is None or dataset.closed:  # a reused thread after close(): open again
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
                dataset = opened[path] = rasterio.open(path)
            with self._lock:
                self._all.append(dataset)
        return dataset

    def close(self) -> None:
        with self._lock:
            for dataset in self._all:
                dataset.close()
            self._all.clear()

    def __getstate__(self) -> dict:
        return {}

    def __setstate__(self, state: dict) -> None:
        self.__init__()
