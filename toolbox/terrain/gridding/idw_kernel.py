"""Inverse-distance-weighted mean and nearest neighbour (thesis eq. [45]), compiled kernels.

``Q = Σ q_k·w_k / Σ w_k`` with ``w_k = 1 / d_k^p`` over the chosen neighbours of the cell centre
(S002 par. 2.5.2 eq. [45] uses ``p = 1``; ``p = 2`` is the usual choice of GIS software). A
neighbour at distance 0 gives its height exactly. Neighbours are the k nearest points, optionally
only within a search radius, optionally chosen by sectors (the ``ceil(k / sectors)`` nearest in
each of ``sectors`` equal angular sectors, so one-sided clusters do not dominate).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from toolbox.terrain.gridding.bin_kernels import block_knn, knn_one, sector_one
from toolbox.terrain.gridding.neighbours import PointBins, block_scratch, block_size


@njit(nogil=True, cache=True, inline="always")
def idw_value(d2, z_index, pz, n, power):
    """Weighted mean of ``pz[z_index[:n]]`` with weights ``d^-power`` (``d2`` squared distances);
    the height of a neighbour at distance 0; never outside the neighbours' height range."""
    if n == 1:
        return pz[z_index[0]]
    for t in range(n):
        if d2[t] == 0.0:
            return pz[z_index[t]]
    num = 0.0
    den = 0.0
    lo = math.inf
    hi = -math.inf
    half = -0.5 * power
    for t in range(n):
        if power == 2.0:
            w = 1.0 / d2[t]
        elif power == 1.0:
            w = 1.0 / math.sqrt(d2[t])
        else:
            w = math.pow(d2[t], half)
        z = pz[z_index[t]]
        num += w * z
        den += w
        lo = z if z < lo else lo
        hi = z if z > hi else hi
    # a convex combination: clamp the last-bit rounding so the result never leaves the range
    value = num / den
    return lo if value < lo else (hi if value > hi else value)


@njit(nogil=True, cache=True)
def _smallest(d2, n):
    nearest = math.inf
    for t in range(n):
        if d2[t] < nearest:
            nearest = d2[t]
    return nearest


@njit(nogil=True, cache=True)
def _grid_sectors(px, py, offsets, x0, y0, size, nbx, nby, pz, xs, ys, mask, r2max, power,
                  sectors, per_sector, min_neighbours, max_d2, best_d2, best_i, sec_d2, sec_i,
                  sec_count, out):
    """Sector search, cell by cell (its own kernel: grids without sectors never compile it)."""
    h, w = mask.shape
    for r in range(h):
        for c in range(w):
            if not mask[r, c]:
                continue
            n = sector_one(px, py, offsets, x0, y0, size, nbx, nby, xs[c], ys[r], sectors,
                           per_sector, r2max, np.int64(-1), sec_d2, sec_i, sec_count, best_d2,
                           best_i)
            if n == 0 or n < min_neighbours or _smallest(best_d2, n) > max_d2:
                continue
            out[r, c] = idw_value(best_d2, best_i, pz, n, power)


# duplicate-ok: the block-of-cells loop of polynomial._grid (see there)
@njit(nogil=True, cache=True)
def _grid(px, py, offsets, x0, y0, size, nbx, nby, pz, xs, ys, mask, k, r2max, power,
          min_neighbours, max_d2, block, best_d2, best_i, cand_x, cand_y, cand_p, cand_d, bd2,
          bi, bn, bnear, out):
    """k nearest neighbours by blocks of cells (``block_knn``; work arrays: ``block_scratch``)."""
    h, w = mask.shape
    for r0 in range(0, h, block):
        r1 = r0 + block if r0 + block < h else h
        for c0 in range(0, w, block):
            c1 = c0 + block if c0 + block < w else w
            block_knn(px, py, offsets, x0, y0, size, nbx, nby, xs, ys, c0, c1, r0, r1, mask, k,
                      r2max, best_d2, best_i, cand_x, cand_y, cand_p, cand_d, bd2, bi, bn,
                      bnear)
            for r in range(r0, r1):
                for c in range(c0, c1):
                    t = (r - r0) * (c1 - c0) + (c - c0)
                    n = bn[t]
                    if n == 0 or n < min_neighbours or bnear[t] > max_d2:
                        continue
                    out[r, c] = idw_value(bd2[t], bi[t], pz, n, power)


@njit(nogil=True, cache=True)
def _loo(px, py, offsets, x0, y0, size, nbx, nby, pz, targets, k, r2max, power,
         min_neighbours, max_d2, best_d2, best_i, out):
    for t in range(len(targets)):
        i = targets[t]
        n = knn_one(px, py, offsets, x0, y0, size, nbx, nby, px[i], py[i], k, r2max, i,
                    best_d2, best_i)
        if n == 0 or n < min_neighbours or best_d2[0] > max_d2:
            continue
        out[t] = idw_value(best_d2, best_i, pz, n, power)


@njit(nogil=True, cache=True)
def _loo_sectors(px, py, offsets, x0, y0, size, nbx, nby, pz, targets, r2max, power, sectors,
                 per_sector, min_neighbours, max_d2, best_d2, best_i, sec_d2, sec_i, sec_count,
                 out):
    for t in range(len(targets)):
        i = targets[t]
        n = sector_one(px, py, offsets, x0, y0, size, nbx, nby, px[i], py[i], sectors,
                       per_sector, r2max, i, sec_d2, sec_i, sec_count, best_d2, best_i)
        if n == 0 or n < min_neighbours or _smallest(best_d2, n) > max_d2:
            continue
        out[t] = idw_value(best_d2, best_i, pz, n, power)


def _sector_scratch(sectors: int, per_sector: int) -> tuple:
    """Work arrays of the sector kernels: the neighbours found and, per sector, the best
    distances, indices and counts."""
    cap = sectors * per_sector
    return (np.empty(cap), np.empty(cap, dtype=np.int64), np.empty((sectors, per_sector)),
            np.empty((sectors, per_sector), dtype=np.int64), np.zeros(sectors, dtype=np.int64))


def _sq(distance: float | None) -> float:
    if distance is None or not math.isfinite(distance):
        return math.inf
    return float(distance) ** 2


def _cell(xs: np.ndarray, ys: np.ndarray) -> float:
    """Cell spacing of a grid given by its column and row centres (1 for a single cell)."""
    if len(xs) > 1:
        return abs(float(xs[1] - xs[0]))
    return abs(float(ys[1] - ys[0])) if len(ys) > 1 else 1.0


def _per_sector(neighbours: int, sectors: int) -> int:
    return max(1, math.ceil(neighbours / sectors)) if sectors > 1 else 0


def idw_grid(xyz: np.ndarray, xs: np.ndarray, ys: np.ndarray, mask: np.ndarray,
             neighbours: int = 12, power: float = 2.0, radius: float = math.inf,
             sectors: int = 0, min_neighbours: int = 1,
             max_distance: float = math.inf) -> np.ndarray:
    """IDW heights (eq. [45]) at the cell centres ``xs`` x ``ys`` (local coordinates).

    Parameters
    ----------
    xyz : (n, 3) float64
        Data points, local origin.
    xs, ys : (w,), (h,) float64
        Column and row centres; row 0 is ``ys[0]``.
    mask : (h, w) bool
        Cells to compute; the others stay NaN.
    neighbours : int
        k nearest points (with ``sectors > 1``: ``ceil(k / sectors)`` per sector).
    power : float
        Weight exponent p in ``1 / d^p``.
    radius : float
        Search radius (CRS units); required (finite) with sectors.
    min_neighbours : int
        Cells with fewer neighbours found stay NaN.
    max_distance : float
        Cells whose nearest point is farther stay NaN.
    """
    bins = PointBins.build(xyz[:, :2])
    out = np.full((len(ys), len(xs)), np.nan)
    xs = np.asarray(xs, "float64")
    ys = np.asarray(ys, "float64")
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    if sectors > 1:
        from toolbox.executor import check_abandoned

        per_sector = _per_sector(neighbours, sectors)
        args, pz, scratch = bins.args(), bins.binned(xyz[:, 2]), _sector_scratch(int(sectors),
                                                                                 per_sector)
        # row by row: a cell near the data's edge, where a sector stays short of points, scans
        # every point within RADIUS (a large RADIUS: seconds per row), and a canceled run waits
        # for its running tiles (toolbox.executor.abandoned)
        for r in range(len(ys)):
            check_abandoned()
            _grid_sectors(*args, pz, xs, ys[r:r + 1], mask[r:r + 1], _sq(radius), float(power),
                          int(sectors), per_sector, int(min_neighbours), _sq(max_distance),
                          *scratch, out[r:r + 1])
        return out
    block = block_size(bins, neighbours, _cell(xs, ys))
    _grid(*bins.args(), bins.binned(xyz[:, 2]), xs, ys, mask, int(neighbours), _sq(radius),
          float(power), int(min_neighbours), _sq(max_distance), block,
          *block_scratch(len(bins), int(neighbours), block), out)
    return out


def idw_loo(bins: PointBins, z: np.ndarray, targets: np.ndarray, neighbours: int = 12,
            power: float = 2.0, radius: float = math.inf, sectors: int = 0,
            min_neighbours: int = 1, max_distance: float = math.inf) -> np.ndarray:
    """Leave-one-out IDW prediction at the data points ``targets`` (NaN where impossible)."""
    targets = np.asarray(targets, dtype=np.int64)
    out = np.full(len(targets), np.nan)
    positions = bins.positions()[targets]
    if sectors > 1:
        per_sector = _per_sector(neighbours, sectors)
        _loo_sectors(*bins.args(), bins.binned(z), positions, _sq(radius), float(power),
                     int(sectors), per_sector, int(min_neighbours), _sq(max_distance),
                     *_sector_scratch(int(sectors), per_sector), out)
        return out
    k = int(neighbours)
    _loo(*bins.args(), bins.binned(z), positions, k, _sq(radius), float(power),
         int(min_neighbours), _sq(max_distance), np.empty(k), np.empty(k, dtype=np.int64), out)
    return out


def nearest_grid(xyz: np.ndarray, xs: np.ndarray, ys: np.ndarray, mask: np.ndarray,
                 max_distance: float = math.inf) -> np.ndarray:
    """Height of the nearest data point at each cell centre (thesis par. 2.5.2, method 1)."""
    return idw_grid(xyz, xs, ys, mask, neighbours=1, max_distance=max_distance)


def nearest_loo(bins: PointBins, z: np.ndarray, targets: np.ndarray,
                max_distance: float = math.inf) -> np.ndarray:
    """Leave-one-out nearest-neighbour prediction: the height of the nearest other point."""
    return idw_loo(bins, z, targets, neighbours=1, max_distance=max_distance)
