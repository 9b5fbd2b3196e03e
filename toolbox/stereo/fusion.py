"""Fusion of matched points into a DSM grid: per pair the median and the quartiles of the
heights of its points in each cell; then across pairs the median of the pairs' medians (DSM),
the number of pairs (COUNT) and SPREAD = the highest upper quartile minus the lowest lower
quartile of the pairs (one pair: its interquartile range; several: also their disagreement).
Cells without points stay empty: no interpolation, so no cell outside the stereo coverage gets
a value."""

from __future__ import annotations

from typing import Any

import numpy as np


def cell_index(xy: np.ndarray, transform: Any, width: int, height: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Flat cell index of each point of a north-up grid, and the mask of points inside it."""
    cols = np.floor((xy[:, 0] - transform.c) / transform.a).astype(np.int64)
    rows = np.floor((xy[:, 1] - transform.f) / transform.e).astype(np.int64)
    inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
    return rows * width + cols, inside


def group_quantiles(keys: np.ndarray, values: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(unique keys, median, lower quartile, upper quartile, count)`` of ``values`` grouped
    by ``keys`` (vectorised; quartiles by linear interpolation, as ``numpy.quantile``)."""
    if len(keys) == 0:
        empty = np.zeros(0)
        return keys, empty, empty, empty, np.zeros(0, dtype=np.int64)
    order = _group_order(keys, values)
    k, v = keys[order], values[order].astype(np.float64)
    starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    counts = np.diff(np.r_[starts, len(k)])

    def quantile(q: float) -> np.ndarray:
        pos = (counts - 1) * q
        below = np.floor(pos).astype(np.int64)
        frac = pos - below
        above = np.minimum(below + 1, counts - 1)
        return v[starts + below] * (1 - frac) + v[starts + above] * frac

    return k[starts], quantile(0.5), quantile(0.25), quantile(0.75), counts


def _group_order(keys: np.ndarray, values: np.ndarray) -> np.ndarray:
    """The order of ``np.lexsort((values, keys))`` (by key, then value) from ONE argsort of a
    combined float64 key ``key + 0.5 (value - min) / range``: two to three times faster than
    lexsort for millions of points. Keys are cell indices (< 2^31), so the value is resolved
    to 2^-20 of its range (0.1 mm over 100 m): heights closer than that may come in either
    order, which changes no quantile by more than that."""
    v = values.astype(np.float64)
    lo = float(v.min())
    span = float(v.max()) - lo
    combined = keys.astype(np.float64)
    if span > 0:
        combined += (v - lo) * (0.5 / span)
    return np.argsort(combined)


def cell_statistics(cells: np.ndarray, heights: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One pair's cells (flat indices of its points) and the median, lower and upper quartile
    of its heights in each."""
    keys, median, q25, q75, _ = group_quantiles(cells, heights)
    return keys, median, q25, q75


def pair_cells(xyz: np.ndarray, transform: Any, width: int, height: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`cell_statistics` of points (N, 3) on a north-up grid (points outside ignored)."""
    cells, inside = cell_index(xyz, transform, width, height)
    return cell_statistics(cells[inside], xyz[inside, 2])


def fuse(pairs: list[tuple[np.ndarray, ...]], width: int, height: int
         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DSM (float32, NaN empty), COUNT (uint16 pairs) and SPREAD (float32, NaN empty) grids
    from the pairs' :func:`pair_cells`."""
    n = width * height
    dsm = np.full(n, np.nan, dtype=np.float32)
    count = np.zeros(n, dtype=np.uint16)
    spread = np.full(n, np.nan, dtype=np.float32)
    if pairs:
        keys = np.concatenate([p[0] for p in pairs])
        cells, median, _, _, counts = group_quantiles(keys, np.concatenate([p[1] for p in pairs]))
        dsm[cells] = median
        count[cells] = counts
        hi = np.full(n, -np.inf)
        lo = np.full(n, np.inf)
        np.maximum.at(hi, keys, np.concatenate([p[3] for p in pairs]))
        np.minimum.at(lo, keys, np.concatenate([p[2] for p in pairs]))
        spread[cells] = hi[cells] - lo[cells]
    shape = (height, width)
    return dsm.reshape(shape), count.reshape(shape), spread.reshape(shape)
