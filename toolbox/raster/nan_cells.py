"""NaN cells of a float photo become no data in the warped output, counted.

A float source with NaN pixels (a partly-NaN photo, and the resampled cells next to them) would
otherwise come out as opaque NaN cells: with an alpha band their alpha is 255. :class:`NanCells`
sits between the raster engine and the writer: in every tile it writes, a cell with a NaN in any
data band gets alpha 0 (its data bands 0) or, without alpha, every data band NaN (the writer
turns NaN into ``nodata``). :attr:`NanCells.count` is the number of such cells (without alpha,
among the cells ``inside(window)`` says the photo covers: the others are no data already).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np


class NanCells:
    """A writer proxy: ``write(window, array)`` masks NaN cells, then writes; anything else is
    the wrapped writer's (``blank``, ``update_tags``...)."""

    def __init__(self, writer: Any, alpha: bool,
                 inside: Callable[[Any], np.ndarray] | None = None):
        self._writer, self._alpha, self._inside = writer, alpha, inside
        self._lock = threading.Lock()
        self.count = 0

    def write(self, window: Any, array: np.ndarray) -> None:
        data = array[np.newaxis] if array.ndim == 2 else array
        if data.dtype.kind == "f":
            bands = data[:-1] if self._alpha else data
            bad = np.isnan(bands).any(axis=0)
            if self._alpha:
                bad &= data[-1] > 0  # cells outside the photo are already transparent
            elif self._inside is not None and bad.any():
                bad &= self._inside(window)
            found = int(bad.sum())
            if found:
                data = data.copy()
                if self._alpha:
                    data[:-1, bad] = 0
                    data[-1, bad] = 0
                else:
                    data[:, bad] = np.nan
                with self._lock:
                    self.count += found
        self._writer.write(window, data if array.ndim == 3 else data[0])

    def __getattr__(self, name: str) -> Any:
        return getattr(self._writer, name)
