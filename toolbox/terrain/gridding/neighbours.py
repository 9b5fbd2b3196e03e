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
a missing neighbour has index ``-1`` and ``d2 = inf``. Among equal distances the point met first
(lower bin, then lower index) ranks first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

TARGET_PER_BIN = 2.0


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
        order = np.empty(n, dtype=np.int64)
        offsets = np.zeros(nbx * nby + 1, dtype=np.int64)
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
        r2 = radius * radius if math.isfinite(radius) else math.inf
        k = int(k)
        d2 = np.full((len(qx), k), np.inf)
        pos = np.full((len(qx), k), -1, dtype=np.int64)
        _query_many(*self.args(), qx, qy, k, r2, skip_pos, np.empty(k),
                    np.empty(k, dtype=np.int64), d2, pos)
        index = np.where(pos >= 0, self.order[np.maximum(pos, 0)], -1)
        return d2, index

    def has_duplicates(self) -> bool:
        """True when two points have exactly the same x and y (they share a bin). O(n)."""
        return bool(_has_duplicates(self.x, self.y, self.offsets))

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
        rows = np.arange(r0, r1 + 1) * self.nbx
        out = np.empty(int((self.offsets[rows + c1 + 1] - self.offsets[rows + c0]).sum()),
                       dtype=np.int64)
        m = _in_rect(self.x, self.y, self.offsets, self.nbx, c0, c1, r0, r1, float(xmin),
                     float(ymin), float(xmax), float(ymax), out)
        return np.sort(self.order[out[:m]])


# Compile time (a newcomer's first run compiles every kernel it meets): the search kernels
# allocate nothing (the callers pass their output and work arrays), call no builtin min/max
# (each arity and type compiles an overload of its own) and are not inlined into numba's IR
# (``inline="always"`` types a callee again at every call site; LLVM inlines small callees).


@njit(nogil=True, cache=True)
def _counting_sort(x, y, x0, y0, size, nbx, nby, key, fill, offsets, order):
    """Sort the point indices by bin (row-major), input order within a bin, into ``order``;
    ``offsets`` (zeros on entry) gets the bin offsets; ``key`` (n,) and ``fill`` (bins,) are
    work arrays. O(n)."""
    n = len(x)
    for i in range(n):
        col = int((x[i] - x0) // size)
        row = int((y[i] - y0) // size)
        b = (row if row < nby - 1 else nby - 1) * nbx + (col if col < nbx - 1 else nbx - 1)
        key[i] = b
        offsets[b + 1] += 1
    for b in range(nbx * nby):
        offsets[b + 1] += offsets[b]
        fill[b] = offsets[b]
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1


@njit(nogil=True, cache=True)
def _has_duplicates(x, y, offsets):
    for b in range(len(offsets) - 1):
        for i in range(offsets[b], offsets[b + 1]):
            for j in range(i + 1, offsets[b + 1]):
                if x[i] == x[j] and y[i] == y[j]:
                    return True
    return False


@njit(nogil=True, cache=True)
def _insert(best_d2, best_i, count, k, d2, index):
    """Insert (d2, index) into the sorted best list of capacity k; return the new count."""
    if count == k and d2 >= best_d2[k - 1]:
        return count
    pos = count if count < k else k - 1
    while pos > 0 and best_d2[pos - 1] > d2:
        best_d2[pos] = best_d2[pos - 1]
        best_i[pos] = best_i[pos - 1]
        pos -= 1
    best_d2[pos] = d2
    best_i[pos] = index
    return count + 1 if count < k else count


@njit(nogil=True, cache=True)
def _ring_start(x0, y0, size, nbx, nby, qx, qy):
    """Bin (ix, iy) of the query (possibly outside the grid), the distance from the query to
    that bin's border, and the first and last ring of bins worth searching."""
    fx = (qx - x0) / size
    fy = (qy - y0) / size
    ix = math.floor(fx)
    iy = math.floor(fy)
    mx = fx - ix if fx - ix < ix + 1 - fx else ix + 1 - fx
    my = fy - iy if fy - iy < iy + 1 - fy else iy + 1 - fy
    margin = (mx if mx < my else my) * size
    ox = -ix if ix < 0 else (ix - (nbx - 1) if ix > nbx - 1 else 0)  # rings outside the grid
    oy = -iy if iy < 0 else (iy - (nby - 1) if iy > nby - 1 else 0)
    fx_ = ix if ix > nbx - 1 - ix else nbx - 1 - ix  # ring reaching the farthest bin column
    fy_ = iy if iy > nby - 1 - iy else nby - 1 - iy
    return ix, iy, margin, (ox if ox > oy else oy), (fx_ if fx_ > fy_ else fy_)


@njit(nogil=True, cache=True)
def knn_one(px, py, offsets, x0, y0, size, nbx, nby, qx, qy, k, r2max, skip,
            best_d2, best_i):
    """The k nearest points of (qx, qy) within sqrt(r2max), skipping index ``skip``.

    Fills ``best_d2[:count]``, ``best_i[:count]`` (nearest first) and returns ``count``.
    Rings of bins around the query's bin are scanned outwards, each in bin order. (The ring
    start and the insertion of :func:`_ring_start` and :func:`_insert` are written out here:
    one function less to compile on a first run.)
    """
    count = 0
    if len(px) == 0 or k <= 0:
        return count
    fx = (qx - x0) / size
    fy = (qy - y0) / size
    ix = math.floor(fx)
    iy = math.floor(fy)
    mx = fx - ix if fx - ix < ix + 1 - fx else ix + 1 - fx
    my = fy - iy if fy - iy < iy + 1 - fy else iy + 1 - fy
    margin = (mx if mx < my else my) * size
    ox = -ix if ix < 0 else (ix - (nbx - 1) if ix > nbx - 1 else 0)
    oy = -iy if iy < 0 else (iy - (nby - 1) if iy > nby - 1 else 0)
    r = ox if ox > oy else oy
    fx_ = ix if ix > nbx - 1 - ix else nbx - 1 - ix
    fy_ = iy if iy > nby - 1 - iy else nby - 1 - iy
    rmax = fx_ if fx_ > fy_ else fy_
    while r <= rmax:
        if r > 0:  # nearest possible point of ring r
            lower = (r - 1) * size + margin
            lower2 = lower * lower
            if lower2 > r2max or (count == k and best_d2[k - 1] <= lower2):
                break
        row = iy - r if iy - r > 0 else 0
        row_end = iy + r if iy + r < nby - 1 else nby - 1
        col_start = ix - r if ix - r > 0 else 0
        col_end = ix + r if ix + r < nbx - 1 else nbx - 1
        while row <= row_end:
            edge_row = row == iy - r or row == iy + r
            col = col_start
            while col <= col_end:
                if not edge_row and col != ix - r and col != ix + r:
                    col = ix + r  # the ring's inside was scanned before
                    continue
                b = row * nbx + col
                for p in range(offsets[b], offsets[b + 1]):
                    if p == skip:
                        continue
                    dx = px[p] - qx
                    dy = py[p] - qy
                    d2 = dx * dx + dy * dy
                    if d2 > r2max or (count == k and d2 >= best_d2[k - 1]):
                        continue
                    pos = count if count < k else k - 1
                    while pos > 0 and best_d2[pos - 1] > d2:
                        best_d2[pos] = best_d2[pos - 1]
                        best_i[pos] = best_i[pos - 1]
                        pos -= 1
                    best_d2[pos] = d2
                    best_i[pos] = p
                    if count < k:
                        count += 1
                col += 1
            row += 1
        r += 1
    return count


@njit(nogil=True, cache=True)
def sector_one(px, py, offsets, x0, y0, size, nbx, nby, qx, qy, sectors, per_sector,
               r2max, skip, sec_d2, sec_i, sec_count, out_d2, out_i):
    """Sector search: the ``per_sector`` nearest points in each of ``sectors`` equal angular
    sectors (sector 0 starts east, counter-clockwise) within sqrt(r2max) (finite).

    ``sec_d2``/``sec_i`` are (sectors, per_sector) work arrays, ``sec_count`` (sectors,).
    Fills ``out_d2[:count]``/``out_i[:count]`` (sector by sector, nearest first within a sector)
    and returns ``count``.
    """
    for s in range(sectors):
        sec_count[s] = 0
    n = len(px)
    if n == 0:
        return 0
    ix, iy, margin, r0, rmax = _ring_start(x0, y0, size, nbx, nby, qx, qy)
    two_pi = 2.0 * math.pi
    r = r0
    while r <= rmax:
        if r > 0:
            lower = (r - 1) * size + margin
            lower2 = lower * lower
            if lower2 > r2max:
                break
            done = True
            for s in range(sectors):
                if sec_count[s] < per_sector or sec_d2[s, per_sector - 1] > lower2:
                    done = False
                    break
            if done:
                break
        for row in range(iy - r, iy + r + 1):
            if row < 0 or row >= nby:
                continue
            edge_row = row == iy - r or row == iy + r
            step = 1 if edge_row else 2 * r
            col = ix - r
            while col <= ix + r:
                if 0 <= col < nbx:
                    b = row * nbx + col
                    for p in range(offsets[b], offsets[b + 1]):
                        if p == skip:
                            continue
                        dx = px[p] - qx
                        dy = py[p] - qy
                        d2 = dx * dx + dy * dy
                        if d2 > r2max:
                            continue
                        angle = math.atan2(dy, dx)
                        if angle < 0.0:
                            angle += two_pi
                        s = int(angle * sectors / two_pi)
                        if s >= sectors:
                            s = sectors - 1
                        sec_count[s] = _insert(sec_d2[s], sec_i[s], sec_count[s], per_sector, d2, p)
                if step == 0:
                    break
                col += step
        r += 1
    count = 0
    for s in range(sectors):
        for t in range(sec_count[s]):
            out_d2[count] = sec_d2[s, t]
            out_i[count] = sec_i[s, t]
            count += 1
    return count


@njit(nogil=True, cache=True)
def _query_many(px, py, offsets, x0, y0, size, nbx, nby, qx, qy, k, r2max, skip, best_d2,
                best_i, out_d2, out_i):
    for q in range(len(qx)):
        count = knn_one(px, py, offsets, x0, y0, size, nbx, nby, qx[q], qy[q], k, r2max,
                        skip[q], best_d2, best_i)
        for t in range(count):
            out_d2[q, t] = best_d2[t]
            out_i[q, t] = best_i[t]


@njit(nogil=True, cache=True)
def _in_rect(px, py, offsets, nbx, c0, c1, r0, r1, xmin, ymin, xmax, ymax, out):
    """Binned positions of the points of bins ``rows r0..r1 x cols c0..c1`` inside the
    rectangle, into ``out[:m]``; returns ``m``."""
    m = 0
    for row in range(r0, r1 + 1):
        for p in range(offsets[row * nbx + c0], offsets[row * nbx + c1 + 1]):
            if xmin <= px[p] <= xmax and ymin <= py[p] <= ymax:
                out[m] = p
                m += 1
    return m


def block_scratch(npts: int, k: int, block: int) -> tuple:
    """Work arrays of :func:`block_knn`, in its argument order: the k best of the ring search,
    candidate x, y, index and distance (one per point) and, per cell of a block, the k best
    distances and indices, the count found and the nearest distance."""
    cells = block * block
    return (np.empty(k), np.empty(k, dtype=np.int64),
            np.empty(npts), np.empty(npts), np.empty(npts, dtype=np.int64), np.empty(npts),
            np.empty((cells, k)), np.empty((cells, k), dtype=np.int64),
            np.empty(cells, dtype=np.int64), np.empty(cells))


@njit(nogil=True, cache=True)
def block_knn(px, py, offsets, x0, y0, size, nbx, nby, xs, ys, c0, c1, r0, r1, mask, k, r2max,
              best_d2, best_i, cand_x, cand_y, cand_p, cand_d, out_d2, out_i, out_n, out_near):
    """k nearest points of every masked cell centre of the block ``rows r0:r1 x cols c0:c1``.

    One ring search at the block centre bounds the k-th distance of every cell of the block
    (the k-th distance is 1-Lipschitz: ``d_k(c) <= d_k(centre) + |c - centre|``); the points
    within that bound of the block are gathered once, sorted by their distance to the centre,
    and each cell scans them keeping its k nearest (replacing the farthest kept), stopping when
    the triangle inequality shows no later candidate can enter. Results go to
    ``out_d2[t, :out_n[t]]``, ``out_i[t, :out_n[t]]`` (binned positions, **in no particular
    order**) and ``out_near[t]`` (the smallest squared distance) for the block's cells in
    row-major order ``t``; unmasked cells get ``out_n[t] = 0``. ``best_*`` and ``cand_*`` are
    work arrays (see :func:`block_scratch`). Among equal distances the candidate nearer the
    block centre wins.
    """
    bw = c1 - c0
    any_cell = False
    for r in range(r0, r1):
        for c in range(c0, c1):
            out_n[(r - r0) * bw + (c - c0)] = 0
            if mask[r, c]:
                any_cell = True
    if not any_cell or len(px) == 0:
        return
    xa, xb = xs[c0], xs[c1 - 1]
    if xb < xa:
        xa, xb = xb, xa
    ya, yb = ys[r0], ys[r1 - 1]
    if yb < ya:
        ya, yb = yb, ya
    cx = 0.5 * (xa + xb)
    cy = 0.5 * (ya + yb)
    half_diag = 0.5 * math.sqrt((xb - xa) * (xb - xa) + (yb - ya) * (yb - ya))
    # np.int64(-1), not -1: a literal argument would compile a second knn_one
    count = knn_one(px, py, offsets, x0, y0, size, nbx, nby, cx, cy, k, r2max, np.int64(-1),
                    best_d2, best_i)
    radius = math.sqrt(r2max)
    reach = radius
    if count == k:  # (slack for the rounding of sqrt and of the squares below)
        bound = (math.sqrt(best_d2[k - 1]) + half_diag) * (1.0 + 1e-9) + 1e-9 * size
        if bound < reach:
            reach = bound
    # gather the candidates within reach of the block, sorted by distance to its centre
    m = 0
    bc0, bc1, br0, br1 = 0, nbx - 1, 0, nby - 1
    circle2 = math.inf
    if reach != math.inf:
        circle2 = (reach + half_diag) * (reach + half_diag)
        bc0 = math.floor((xa - reach - x0) / size)
        bc1 = math.floor((xb + reach - x0) / size)
        br0 = math.floor((ya - reach - y0) / size)
        br1 = math.floor((yb + reach - y0) / size)
        bc0 = bc0 if bc0 > 0 else 0
        bc1 = bc1 if bc1 < nbx - 1 else nbx - 1
        br0 = br0 if br0 > 0 else 0
        br1 = br1 if br1 < nby - 1 else nby - 1
    if bc1 >= bc0:
        for row in range(br0, br1 + 1):
            for p in range(offsets[row * nbx + bc0], offsets[row * nbx + bc1 + 1]):
                dx = px[p] - cx
                dy = py[p] - cy
                dd = dx * dx + dy * dy
                if dd <= circle2:
                    j = m
                    while j > 0 and cand_d[j - 1] > dd:
                        cand_d[j] = cand_d[j - 1]
                        cand_x[j] = cand_x[j - 1]
                        cand_y[j] = cand_y[j - 1]
                        cand_p[j] = cand_p[j - 1]
                        j -= 1
                    cand_d[j] = dd
                    cand_x[j] = px[p]
                    cand_y[j] = py[p]
                    cand_p[j] = p
                    m += 1
    for j in range(m):
        cand_d[j] = math.sqrt(cand_d[j])
    for r in range(r0, r1):
        qy = ys[r]
        for c in range(c0, c1):
            if not mask[r, c]:
                continue
            t = (r - r0) * bw + (c - c0)
            qx = xs[c]
            e = math.sqrt((qx - cx) * (qx - cx) + (qy - cy) * (qy - cy))
            n = 0
            worst = -1.0
            wpos = 0
            near = math.inf
            for j in range(m):
                lower = cand_d[j] - e  # |c - p| >= |p - centre| - |c - centre|
                if lower > radius:
                    break
                if n == k and lower > 0.0 and lower * lower >= worst:
                    break
                dx = cand_x[j] - qx
                dy = cand_y[j] - qy
                d2 = dx * dx + dy * dy
                if d2 > r2max:
                    continue
                if n < k:
                    out_d2[t, n] = d2
                    out_i[t, n] = cand_p[j]
                    if d2 > worst:
                        worst = d2
                        wpos = n
                    n += 1
                elif d2 < worst:
                    out_d2[t, wpos] = d2
                    out_i[t, wpos] = cand_p[j]
                    worst = out_d2[t, 0]
                    wpos = 0
                    for u in range(1, k):
                        if out_d2[t, u] > worst:
                            worst = out_d2[t, u]
                            wpos = u
                else:
                    continue
                if d2 < near:
                    near = d2
            out_n[t] = n
            out_near[t] = near


def block_size(bins: PointBins, k: int, cell: float) -> int:
    """Cells per block side for :func:`block_knn`: about the expected k-th neighbour distance
    plus a cell, 1 to 16 cells (measured best on uniform data)."""
    n = max(len(bins), 1)
    area = bins.nbx * bins.nby * bins.size ** 2
    d_k = math.sqrt(max(k, 1) * area / (math.pi * n))
    return int(min(16, max(1, round(d_k / cell + 0.75))))


@njit(nogil=True, cache=True)
def _grid_knn(px, py, offsets, x0, y0, size, nbx, nby, xs, ys, mask, k, r2max, block,
              best_d2, best_i, cand_x, cand_y, cand_p, cand_d, bd2, bi, bn, bnear, out_d2,
              out_i):
    h, w = mask.shape
    for r0 in range(0, h, block):
        r1 = r0 + block if r0 + block < h else h
        for c0 in range(0, w, block):
            c1 = c0 + block if c0 + block < w else w
            block_knn(px, py, offsets, x0, y0, size, nbx, nby, xs, ys, c0, c1, r0, r1, mask, k,
                      r2max, best_d2, best_i, cand_x, cand_y, cand_p, cand_d, bd2, bi, bn, bnear)
            for r in range(r0, r1):
                for c in range(c0, c1):
                    t = (r - r0) * (c1 - c0) + (c - c0)
                    for j in range(bn[t]):
                        out_d2[r, c, j] = bd2[t, j]
                        out_i[r, c, j] = bi[t, j]


def grid_knn(bins: PointBins, xs: np.ndarray, ys: np.ndarray, k: int, radius: float = math.inf,
             mask: np.ndarray | None = None, block: int | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """k nearest points of every cell centre of the grid ``xs`` x ``ys`` (block search).

    Returns ``(d2 (h, w, k), index (h, w, k))`` with input indices, nearest first; ``inf`` /
    ``-1`` where missing or masked out. Mainly for tests: the gridding kernels fuse this search
    with the interpolation.
    """
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
