"""Nearest-neighbour search for gridding: a uniform bin grid ("cell list") searched ring by ring.

Gridding asks for the k nearest data points of millions of regularly spaced cell centres. A
k-d tree (``scipy.spatial.cKDTree``) answers about 0.3 million 12-neighbour queries per second
and core; bins of about two points each, searched outwards from the query's bin in square rings
until the k-th distance is below the nearest unvisited ring, answer the same queries (same
distances, exactly) several times faster and can be fused with the interpolation in one compiled
loop, without (cells, k) temporaries. ``cKDTree`` remains the reference in the tests and the tool
for scattered queries elsewhere.

Conventions: coordinates are float64 in a local origin (see
:func:`toolbox.terrain.points.local_origin`); distances are returned squared (``d2``);
a missing neighbour has index ``-1`` and ``d2 = inf``. Among equal squared distances (points on a
lattice) the lower x, then the lower y ranks first: the k nearest kept are the same whatever the
bins, blocks, tiles or input order (compared only on an exact tie, so free off ties).

The compiled searches live in :mod:`toolbox.terrain.gridding.bin_kernels`, imported on first use:
building the bins, the duplicate test and the rectangle search run in numpy below
:data:`NUMPY_MAX_POINTS` points (same results), so a small run never imports numba.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TARGET_PER_BIN = 2.0
#: up to this many points the bins are sorted, checked for duplicates and searched by rectangle
#: in numpy (a few ms at 100,000 points) instead of the compiled kernels, whose first call in a
#: process costs numba's import and cache load (about 1 s); the results are the same
NUMPY_MAX_POINTS = 400_000
#: above NUMPY_MAX_POINTS, bins of at most this many points are checked for duplicate XY pair by
#: pair (compiled); the points of more crowded bins are sorted instead
PAIRWISE_MAX = 32


@dataclass(frozen=True)
class PointBins:
    """Points sorted into a uniform grid of square bins.

    The compiled searches work on *binned positions*: position ``p`` is the p-th point in bin
    order (row-major bins, input order within a bin), with coordinates ``x[p]``, ``y[p]`` stored
    contiguously for cache-friendly scans; ``order[p]`` is its index in the input.

    Attributes
    ----------
    x, y : (n,) float64
        Point coordinates (local origin), in bin order.
    order : (n,) int64
        Input index of each binned position.
    offsets : (nbx * nby + 1,) int64
        Positions ``offsets[b]:offsets[b + 1]`` are the points of bin ``b = row * nbx + col``.
    x0, y0, size : float
        Lower-left corner of bin (0, 0) and the bin side.
    nbx, nby : int
        Bins per row and per column.
    """

    x: np.ndarray
    y: np.ndarray
    order: np.ndarray
    offsets: np.ndarray
    x0: float
    y0: float
    size: float
    nbx: int
    nby: int

    @classmethod
    def build(cls, xy: np.ndarray, per_bin: float = TARGET_PER_BIN) -> PointBins:
        """Bin ``xy`` ((n, 2) float) with about ``per_bin`` points per occupied bin area."""
        xy = np.asarray(xy, dtype="float64")
        x = np.ascontiguousarray(xy[:, 0])
        y = np.ascontiguousarray(xy[:, 1])
        n = len(x)
        if n == 0:
            return cls(x, y, np.zeros(0, np.int64), np.zeros(2, np.int64), 0.0, 0.0, 1.0, 1, 1)
        x0, y0 = float(x.min()), float(y.min())
        wx, wy = float(x.max()) - x0, float(y.max()) - y0
        bins_wanted = max(1.0, n / per_bin)
        if wx > 0 and wy > 0:
            size = math.sqrt(wx * wy / bins_wanted)
        else:  # all points on a vertical or horizontal line, or at one place
            size = max(wx, wy) / bins_wanted
        if not size > 0:
            size = 1.0
        while True:
            nbx, nby = int(wx // size) + 1, int(wy // size) + 1
            if nbx * nby <= 4 * n + 16:
                break
            size *= 1.5
        offsets = np.zeros(nbx * nby + 1, dtype=np.int64)
        if n <= NUMPY_MAX_POINTS:  # the counting sort's bins, its order (stable within a bin)
            col = np.minimum((x - x0) // size, nbx - 1).astype(np.int64)
            row = np.minimum((y - y0) // size, nby - 1).astype(np.int64)
            key = row * nbx + col
            order = np.argsort(key, kind="stable")
            np.cumsum(np.bincount(key, minlength=nbx * nby), out=offsets[1:])
        else:
            from toolbox.terrain.gridding.bin_kernels import _counting_sort

            order = np.empty(n, dtype=np.int64)
            _counting_sort(x, y, x0, y0, float(size), nbx, nby, np.empty(n, dtype=np.int64),
                           np.empty(nbx * nby, dtype=np.int64), offsets, order)
        return cls(x[order], y[order], order, offsets, x0, y0, float(size), nbx, nby)

    def binned(self, values: np.ndarray) -> np.ndarray:
        """``values`` (per input point) in bin order, contiguous float64."""
        return np.ascontiguousarray(np.asarray(values, dtype="float64")[self.order])

    def positions(self) -> np.ndarray:
        """Binned position of each input point (the inverse of ``order``)."""
        inverse = np.empty_like(self.order)
        inverse[self.order] = np.arange(len(self.order))
        return inverse

    def __len__(self) -> int:
        return len(self.x)

    def args(self) -> tuple:
        """The arrays and numbers the compiled search functions take, in their order."""
        return (self.x, self.y, self.offsets, self.x0, self.y0, self.size, self.nbx, self.nby)

    def query(self, qx: np.ndarray, qy: np.ndarray, k: int, radius: float = math.inf,
              skip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """k nearest points of each query point: ``(d2 (q, k), index (q, k))``, nearest first,
        indices into the input points.

        ``radius`` limits the search (points farther are not neighbours); ``skip[i]`` is an input
        point index query ``i`` must ignore (leave-one-out), ``-1`` for none.
        """
        qx = np.ascontiguousarray(qx, dtype="float64").ravel()
        qy = np.ascontiguousarray(qy, dtype="float64").ravel()
        skip_pos = np.full(len(qx), -1, dtype=np.int64)
        if skip is not None:
            skip = np.asarray(skip, dtype=np.int64)
            given = skip >= 0
            skip_pos[given] = self.positions()[skip[given]]
        from toolbox.terrain.gridding.bin_kernels import _query_many

        r2 = radius * radius if math.isfinite(radius) else math.inf
        k = int(k)
        d2 = np.full((len(qx), k), np.inf)
        pos = np.full((len(qx), k), -1, dtype=np.int64)
        _query_many(*self.args(), qx, qy, k, r2, skip_pos, np.empty(k),
                    np.empty(k, dtype=np.int64), d2, pos)
        index = np.where(pos >= 0, self.order[np.maximum(pos, 0)], -1)
        return d2, index

    def has_duplicates(self) -> bool:
        """True when two points have exactly the same x and y."""
        return self.duplicate_check()[0]

    def duplicate_check(self) -> tuple[bool, int]:
        """``(found, comparisons)``: whether two points have exactly the same x and y, and the
        number of value comparisons made (pairs compared, plus one per point sorted).

        Duplicates share a bin. Up to :data:`NUMPY_MAX_POINTS` points: one sort of all the points
        by (x, y), duplicates then neighbours. Above: compiled pairwise comparison inside bins of
        at most :data:`PAIRWISE_MAX` points, and one sort of the points of the crowded bins
        (clustered data), so the work stays O(n log n) for any distribution.
        """
        n = len(self.x)
        if n <= NUMPY_MAX_POINTS:
            return _sorted_duplicates(self.x, self.y), n
        from toolbox.terrain.gridding.bin_kernels import _has_duplicates

        found, comparisons = _has_duplicates(self.x, self.y, self.offsets, PAIRWISE_MAX)
        if found:
            return True, int(comparisons)
        counts = np.diff(self.offsets)
        if counts.max() <= PAIRWISE_MAX:  # no crowded bin: all compared pairwise
            return False, int(comparisons)
        crowded = np.repeat(counts > PAIRWISE_MAX, counts)
        m = int(np.count_nonzero(crowded))
        return _sorted_duplicates(self.x[crowded], self.y[crowded]), int(comparisons) + m

    def in_rect(self, xmin: float, ymin: float, xmax: float, ymax: float) -> np.ndarray:
        """Indices (ascending) of the points with ``xmin <= x <= xmax`` and ``ymin <= y <= ymax``."""
        if len(self.x) == 0:
            return np.zeros(0, dtype=np.int64)
        c0 = max(0, math.floor((xmin - self.x0) / self.size))
        c1 = min(self.nbx - 1, math.floor((xmax - self.x0) / self.size))
        r0 = max(0, math.floor((ymin - self.y0) / self.size))
        r1 = min(self.nby - 1, math.floor((ymax - self.y0) / self.size))
        if c1 < c0 or r1 < r0:
            return np.zeros(0, dtype=np.int64)
        if len(self.x) <= NUMPY_MAX_POINTS:
            p = np.arange(self.offsets[r0 * self.nbx + c0], self.offsets[r1 * self.nbx + c1 + 1])
            px, py = self.x[p], self.y[p]
            p = p[(px >= xmin) & (px <= xmax) & (py >= ymin) & (py <= ymax)]
            return np.sort(self.order[p])
        from toolbox.terrain.gridding.bin_kernels import _in_rect

        rows = np.arange(r0, r1 + 1) * self.nbx
        out = np.empty(int((self.offsets[rows + c1 + 1] - self.offsets[rows + c0]).sum()),
                       dtype=np.int64)
        m = _in_rect(self.x, self.y, self.offsets, self.nbx, c0, c1, r0, r1, float(xmin),
                     float(ymin), float(xmax), float(ymax), out)
        return np.sort(self.order[out[:m]])


def beyond(xyz: np.ndarray, xs: np.ndarray, ys: np.ndarray, mask: np.ndarray,
           max_distance: float) -> np.ndarray:
    """(h, w) bool: masked cell centres ``xs`` x ``ys`` farther than ``max_distance`` from every
    point of ``xyz`` (squared distances compared as the compiled search does: a point at exactly
    ``max_distance`` is near). A k-d tree (scipy), no numba: for the numpy path of small runs."""
    from scipy.spatial import cKDTree

    far = np.zeros(mask.shape, dtype=bool)
    rows, cols = np.nonzero(mask)
    if not len(rows):
        return far
    qx, qy = np.asarray(xs, dtype="float64")[cols], np.asarray(ys, dtype="float64")[rows]
    if not len(xyz):
        far[rows, cols] = True
        return far
    _, index = cKDTree(xyz[:, :2]).query(np.column_stack([qx, qy]), k=1)
    dx, dy = xyz[index, 0] - qx, xyz[index, 1] - qy
    far[rows, cols] = dx * dx + dy * dy > max_distance * max_distance
    return far


def block_scratch(npts: int, k: int, block: int) -> tuple:
    """Work arrays of :func:`block_knn`, in its argument order: the k best of the ring search,
    candidate x, y, index and distance (one per point) and, per cell of a block, the k best
    distances and indices, the count found and the nearest distance."""
    cells = block * block
    return (np.empty(k), np.empty(k, dtype=np.int64),
            np.empty(npts), np.empty(npts), np.empty(npts, dtype=np.int64), np.empty(npts),
            np.empty((cells, k)), np.empty((cells, k), dtype=np.int64),
            np.empty(cells, dtype=np.int64), np.empty(cells))


def block_size(bins: PointBins, k: int, cell: float) -> int:
    """Cells per block side for :func:`block_knn`: about the expected k-th neighbour distance
    plus a cell, 1 to 16 cells (measured best on uniform data)."""
    n = max(len(bins), 1)
    area = bins.nbx * bins.nby * bins.size ** 2
    d_k = math.sqrt(max(k, 1) * area / (math.pi * n))
    return int(min(16, max(1, round(d_k / cell + 0.75))))


def grid_knn(bins: PointBins, xs: np.ndarray, ys: np.ndarray, k: int, radius: float = math.inf,
             mask: np.ndarray | None = None, block: int | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """k nearest points of every cell centre of the grid ``xs`` x ``ys`` (block search).

    Returns ``(d2 (h, w, k), index (h, w, k))`` with input indices, nearest first; ``inf`` /
    ``-1`` where missing or masked out. Mainly for tests: the gridding kernels fuse this search
    with the interpolation.
    """
    from toolbox.terrain.gridding.bin_kernels import _grid_knn

    xs = np.asarray(xs, dtype="float64")
    ys = np.asarray(ys, dtype="float64")
    if mask is None:
        mask = np.ones((len(ys), len(xs)), dtype=np.bool_)
    cell = abs(xs[1] - xs[0]) if len(xs) > 1 else (abs(ys[1] - ys[0]) if len(ys) > 1 else 1.0)
    block = block or block_size(bins, k, cell)
    out_d2 = np.full((len(ys), len(xs), k), np.inf)
    out_i = np.full((len(ys), len(xs), k), -1, dtype=np.int64)
    r2 = radius * radius if math.isfinite(radius) else math.inf
    _grid_knn(*bins.args(), xs, ys, np.ascontiguousarray(mask, dtype=np.bool_), int(k), r2,
              int(block), *block_scratch(len(bins), int(k), int(block)), out_d2, out_i)
    order = np.argsort(out_d2, axis=2, kind="stable")  # the search keeps them unordered
    out_d2 = np.take_along_axis(out_d2, order, axis=2)
    out_i = np.take_along_axis(out_i, order, axis=2)
    index = np.where(out_i >= 0, bins.order[np.maximum(out_i, 0)], -1)
    return out_d2, index


def _sorted_duplicates(x: np.ndarray, y: np.ndarray) -> bool:
    """True when two (x, y) are equal: one sort by (x, y), duplicates then neighbours."""
    xy = np.empty(len(x), dtype=np.complex128)  # sorts by real, then imaginary
    xy.real, xy.imag = x, y
    xy.sort()
    return bool(np.any(xy[1:] == xy[:-1]))
