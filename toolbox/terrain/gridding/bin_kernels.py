"""Compiled (numba) kernels of the bin search of :mod:`toolbox.terrain.gridding.neighbours`
(kept apart so that the bins themselves, and a small run, need no numba import).

Arguments are :meth:`PointBins.args() <toolbox.terrain.gridding.neighbours.PointBins.args>` (the
binned x, y, bin offsets, corner, bin side and counts) followed by the query; see the
conventions of :mod:`toolbox.terrain.gridding.neighbours`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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
def _has_duplicates(x, y, offsets, pairwise_max):
    """``(found, comparisons)``: two points of a bin with at most ``pairwise_max`` points share
    x and y, and the number of point pairs compared. Bins with more points are skipped (the
    caller sorts them), so the work is at most ``n * pairwise_max / 2`` comparisons whatever the
    points' distribution (pairwise over every bin is quadratic in a crowded bin)."""
    comparisons = 0
    for b in range(len(offsets) - 1):
        start, stop = offsets[b], offsets[b + 1]
        if stop - start > pairwise_max:
            continue
        for i in range(start, stop):
            for j in range(i + 1, stop):
                comparisons += 1
                if x[i] == x[j] and y[i] == y[j]:
                    return True, comparisons
    return False, comparisons


#: relative slack of the "no farther point can still enter" bounds: a point at exactly the
#: k-th distance (a tie, e.g. on a lattice) may still rank before the k-th (:func:`_xy_before`),
#: so the bounds must not cut it off by a rounding
SLACK = 1e-12


@njit(nogil=True, cache=True)
def _xy_before(xa, ya, xb, yb):
    """Among points at the same distance from a query the lower x, then the lower y ranks
    first: a total order of distinct points that depends on nothing else (not on the bins,
    blocks, tiles or the input order). Called only on an exact tie of squared distances."""
    if xa != xb:
        return xa < xb
    return ya < yb


@njit(nogil=True, cache=True, inline="always")
def _insert(best_d2, best_i, count, k, d2, index, px, py):
    """Insert (d2, index) into the best list of capacity k, sorted by squared distance then
    :func:`_xy_before` (``px``, ``py``: the binned coordinates ``index`` points into); return
    the new count. The coordinates are compared only on an exact tie."""
    if count == k:
        last = best_d2[k - 1]
        if d2 > last or (d2 == last and not _xy_before(px[index], py[index],
                                                       px[best_i[k - 1]], py[best_i[k - 1]])):
            return count
    pos = count if count < k else k - 1
    while pos > 0 and best_d2[pos - 1] > d2:
        best_d2[pos] = best_d2[pos - 1]
        best_i[pos] = best_i[pos - 1]
        pos -= 1
    if pos > 0 and best_d2[pos - 1] == d2:  # a tie: rank by the coordinates
        while pos > 0 and best_d2[pos - 1] == d2 and _xy_before(
                px[index], py[index], px[best_i[pos - 1]], py[best_i[pos - 1]]):
            best_d2[pos] = best_d2[pos - 1]
            best_i[pos] = best_i[pos - 1]
            pos -= 1
    best_d2[pos] = d2
    best_i[pos] = index
    return count + 1 if count < k else count


@njit(nogil=True, cache=True, inline="always")
def _ring_start(x0, y0, size, nbx, nby, qx, qy):
    """Bin (ix, iy) of the query (possibly outside the grid), the distance from the query to
    that bin's border (less its rounding error: a lower bound), and the first and last ring of
    bins worth searching."""
    fx = (qx - x0) / size
    fy = (qy - y0) / size
    ix = math.floor(fx)
    iy = math.floor(fy)
    mx = fx - ix if fx - ix < ix + 1 - fx else ix + 1 - fx
    my = fy - iy if fy - iy < iy + 1 - fy else iy + 1 - fy
    margin = (mx if mx < my else my) * size - SLACK * size * (abs(fx) + abs(fy) + 2.0)
    margin = margin if margin > 0.0 else 0.0
    ox = -ix if ix < 0 else (ix - (nbx - 1) if ix > nbx - 1 else 0)  # rings outside the grid
    oy = -iy if iy < 0 else (iy - (nby - 1) if iy > nby - 1 else 0)
    fx_ = ix if ix > nbx - 1 - ix else nbx - 1 - ix  # ring reaching the farthest bin column
    fy_ = iy if iy > nby - 1 - iy else nby - 1 - iy
    return ix, iy, margin, (ox if ox > oy else oy), (fx_ if fx_ > fy_ else fy_)


# duplicate-ok: sector_one scans the rings of bins the same way (see there)
@njit(nogil=True, cache=True)
def knn_one(px, py, offsets, x0, y0, size, nbx, nby, qx, qy, k, r2max, skip,
            best_d2, best_i):
    """The k nearest points of (qx, qy) within sqrt(r2max), skipping index ``skip``.

    Fills ``best_d2[:count]``, ``best_i[:count]`` (nearest first, equal distances by
    :func:`_xy_before`) and returns ``count``. Rings of bins around the query's bin are scanned
    outwards, each in bin order (:func:`_ring_start` and :func:`_insert` are inlined by numba).
    """
    count = 0
    if len(px) == 0 or k <= 0:
        return count
    ix, iy, margin, r, rmax = _ring_start(x0, y0, size, nbx, nby, qx, qy)
    while r <= rmax:
        if r > 0:  # nearest possible point of ring r
            lower = (r - 1) * size + margin
            lower2 = lower * lower
            if lower2 > r2max or (count == k and best_d2[k - 1] * (1.0 + SLACK) < lower2):
                break  # (a point of ring r at exactly the k-th distance may still enter)
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
                    if d2 <= r2max:
                        count = _insert(best_d2, best_i, count, k, d2, p, px, py)
                col += 1
            row += 1
        r += 1
    return count


# duplicate-ok: the ring-of-bins scan of knn_one, with a per-sector best list instead of one
@njit(nogil=True, cache=True)
def sector_one(px, py, offsets, x0, y0, size, nbx, nby, qx, qy, sectors, per_sector,
               r2max, skip, sec_d2, sec_i, sec_count, out_d2, out_i):
    """Sector search: the ``per_sector`` nearest points in each of ``sectors`` equal angular
    sectors (sector 0 starts east, counter-clockwise) within sqrt(r2max) (finite); equal
    distances rank by :func:`_xy_before`.

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
                if sec_count[s] < per_sector or \
                        sec_d2[s, per_sector - 1] * (1.0 + SLACK) >= lower2:
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
                        sec_count[s] = _insert(sec_d2[s], sec_i[s], sec_count[s], per_sector, d2,
                                               p, px, py)
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


@njit(nogil=True, cache=True)
def _tie(d2s, index, k, d2, p, px, py):
    """Binned position ``p`` at the largest squared distance ``d2`` of a full, unordered list
    (``d2s``, ``index``: k slots) takes the slot of the one that ranks last among the slots
    at ``d2`` (:func:`_xy_before`) if it ranks before that one; that one leaves the list."""
    last = -1
    for u in range(k):
        if d2s[u] == d2 and (last < 0 or _xy_before(px[index[last]], py[index[last]],
                                                    px[index[u]], py[index[u]])):
            last = u
    if _xy_before(px[p], py[p], px[index[last]], py[index[last]]):
        index[last] = p


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
    work arrays (see :func:`block_scratch`). Among equal distances the lower x, then the lower
    y ranks first (:func:`_xy_before`, compared only on an exact tie: :func:`_tie`): the same
    neighbours whatever the blocks and tiles.
    """
    bw = c1 - c0
    any_cell = False
    for r in range(r0, r1):
        for c in range(c0, c1):
            out_n[(r - r0) * bw + (c - c0)] = 0
            if mask[r, c]:
                any_cell = True
    if not any_cell or len(px) == 0 or k <= 0:
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
    if count == k:
        reach = math.sqrt(best_d2[k - 1]) + half_diag
        reach = reach if reach < radius else radius
    # gather the candidates within reach of the block, sorted by distance to its centre (slack
    # for the rounding of sqrt and of the squares: a point at exactly the k-th distance of a
    # cell, a tie, must be a candidate)
    m = 0
    bc0, bc1, br0, br1 = 0, nbx - 1, 0, nby - 1
    circle2 = math.inf
    if reach != math.inf:
        reach = reach * (1.0 + 1e-9) + 1e-9 * size
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
    # the early stop's lower bound |p - centre| - |c - centre| loses a few ulps of those
    # lengths to rounding: this much less keeps a candidate at exactly the k-th distance
    tol = SLACK * (cand_d[m - 1] + 2.0 * half_diag) if m > 0 else 0.0
    for r in range(r0, r1):
        qy = ys[r]
        for c in range(c0, c1):
            if not mask[r, c]:
                continue
            t = (r - r0) * bw + (c - c0)
            qx = xs[c]
            e = math.sqrt((qx - cx) * (qx - cx) + (qy - cy) * (qy - cy)) + tol
            n = 0
            worst = -1.0
            wpos = 0
            near = math.inf
            for j in range(m):
                lower = cand_d[j] - e  # |c - p| >= |p - centre| - |c - centre|
                if lower > radius:
                    break
                if n == k and lower > 0.0 and lower * lower > worst:
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
                    gone = out_i[t, wpos]
                    out_d2[t, wpos] = d2
                    out_i[t, wpos] = cand_p[j]
                    farthest = worst
                    worst = out_d2[t, 0]
                    wpos = 0
                    for u in range(1, k):
                        if out_d2[t, u] > worst:
                            worst = out_d2[t, u]
                            wpos = u
                    if worst == farthest:  # the one that left tied with others (lattices)
                        _tie(out_d2[t], out_i[t], k, worst, gone, px, py)
                elif d2 == worst:  # a tie at the k-th distance (lattices)
                    _tie(out_d2[t], out_i[t], k, worst, cand_p[j], px, py)
                    continue
                else:
                    continue
                if d2 < near:
                    near = d2
            out_n[t] = n
            out_near[t] = near


# duplicate-ok: the block-of-cells loop of polynomial._grid (see there)
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
