"""Local least-squares polynomial surfaces on the k nearest points (thesis eq. [46]-[48]).

Each cell gets the value at its centre of the polynomial of order 1, 2 or 3 fitted by least
squares to its k nearest data points (S002 par. 2.5.2: plane ``z = a·x + b·y + c`` [46], 2nd-order
surface [47], 3rd-order surface [48]; at least 3, 6 and 10 points; domain brief section 14).

Numerics (domain brief "Impl. note"): coordinates are centred on the cell and scaled by the
farthest neighbour's distance, ``u = (x - xc)/s``, ``v = (y - yc)/s``, so the monomials are at most
1 in size and the height at the centre is simply the constant coefficient. The design matrix
(columns ``1, u, v, u², uv, v², u³, u²v, uv², v³``, each scaled to unit length) has the triangular
factor ``R`` of its QR factorisation computed by Cholesky from the normal equations (``AᵀA = RᵀR``;
about three times cheaper than Householder for these small systems, and accurate enough for the
decisions below since the threshold is far above sqrt(eps)). ``|R_ii|`` is the part of monomial
``i`` independent of the previous ones;
when the smallest ``|R_ii|`` of an order is below ``min_rcond`` (or there are fewer neighbours than
coefficients) the neighbourhood is ill-conditioned for that order and the fit falls back to the
next lower order (cubic -> quadratic -> plane -> mean) on the same neighbours, with the leading
block of the same factorisation. The orders actually used are counted for the report.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from toolbox.terrain.gridding.bin_kernels import block_knn, knn_one
from toolbox.terrain.gridding.idw_kernel import _cell
from toolbox.terrain.gridding.neighbours import PointBins, block_scratch, block_size
from toolbox.terrain.gridding.request import (  # noqa: F401 - part of this module's API
    DEFAULT_MIN_RCOND,
    ORDER_NAMES,
    TERMS,
)

TERMS_NB = np.array(TERMS, dtype=np.int64)


@njit(nogil=True, cache=True, inline="always")
def _moments0(z, n, gram, rhs):
    total = 0.0
    for i in range(n):
        total += z[i]
    gram[0, 0] = n
    rhs[0] = total


@njit(nogil=True, cache=True, inline="always")
def _moments1(dx, dy, z, n, inv, gram, rhs):
    s10 = s01 = s20 = s11 = s02 = 0.0
    z00 = z10 = z01 = 0.0
    for i in range(n):
        u = dx[i] * inv
        v = dy[i] * inv
        zi = z[i]
        s10 += u
        s01 += v
        s20 += u * u
        s11 += u * v
        s02 += v * v
        z00 += zi
        z10 += zi * u
        z01 += zi * v
    gram[0, 0] = n
    gram[0, 1] = s10
    gram[0, 2] = s01
    gram[1, 1] = s20
    gram[1, 2] = s11
    gram[2, 2] = s02
    rhs[0] = z00
    rhs[1] = z10
    rhs[2] = z01


# duplicate-ok: _moments1/2/3 unroll the normal-equation sums of each order by hand, so
# that numba compiles straight-line code (not re-measured in this change)
@njit(nogil=True, cache=True, inline="always")
def _moments2(dx, dy, z, n, inv, gram, rhs):
    s10 = s01 = s20 = s11 = s02 = 0.0
    s30 = s21 = s12 = s03 = s40 = s31 = s22 = s13 = s04 = 0.0
    z00 = z10 = z01 = z20 = z11 = z02 = 0.0
    for i in range(n):
        u = dx[i] * inv
        v = dy[i] * inv
        zi = z[i]
        u2 = u * u
        uv = u * v
        v2 = v * v
        s10 += u
        s01 += v
        s20 += u2
        s11 += uv
        s02 += v2
        s30 += u2 * u
        s21 += u2 * v
        s12 += u * v2
        s03 += v2 * v
        s40 += u2 * u2
        s31 += u2 * uv
        s22 += u2 * v2
        s13 += uv * v2
        s04 += v2 * v2
        z00 += zi
        z10 += zi * u
        z01 += zi * v
        z20 += zi * u2
        z11 += zi * uv
        z02 += zi * v2
    gram[0, 0] = n
    gram[0, 1] = s10
    gram[0, 2] = s01
    gram[0, 3] = s20
    gram[0, 4] = s11
    gram[0, 5] = s02
    gram[1, 1] = s20
    gram[1, 2] = s11
    gram[1, 3] = s30
    gram[1, 4] = s21
    gram[1, 5] = s12
    gram[2, 2] = s02
    gram[2, 3] = s21
    gram[2, 4] = s12
    gram[2, 5] = s03
    gram[3, 3] = s40
    gram[3, 4] = s31
    gram[3, 5] = s22
    gram[4, 4] = s22
    gram[4, 5] = s13
    gram[5, 5] = s04
    rhs[0] = z00
    rhs[1] = z10
    rhs[2] = z01
    rhs[3] = z20
    rhs[4] = z11
    rhs[5] = z02


@njit(nogil=True, cache=True, inline="always")
def _moments3(dx, dy, z, n, inv, gram, rhs):
    s10 = s01 = s20 = s11 = s02 = 0.0
    s30 = s21 = s12 = s03 = s40 = s31 = s22 = s13 = s04 = 0.0
    s50 = s41 = s32 = s23 = s14 = s05 = 0.0
    s60 = s51 = s42 = s33 = s24 = s15 = s06 = 0.0
    z00 = z10 = z01 = z20 = z11 = z02 = z30 = z21 = z12 = z03 = 0.0
    for i in range(n):
        u = dx[i] * inv
        v = dy[i] * inv
        zi = z[i]
        u2 = u * u
        uv = u * v
        v2 = v * v
        u3 = u2 * u
        u2v = u2 * v
        uv2 = u * v2
        v3 = v2 * v
        s10 += u
        s01 += v
        s20 += u2
        s11 += uv
        s02 += v2
        s30 += u3
        s21 += u2v
        s12 += uv2
        s03 += v3
        s40 += u2 * u2
        s31 += u3 * v
        s22 += u2 * v2
        s13 += u * v3
        s04 += v2 * v2
        s50 += u3 * u2
        s41 += u3 * uv
        s32 += u3 * v2
        s23 += u2 * v3
        s14 += uv * v3
        s05 += v3 * v2
        s60 += u3 * u3
        s51 += u3 * u2v
        s42 += u3 * uv2
        s33 += u3 * v3
        s24 += u2v * v3
        s15 += uv2 * v3
        s06 += v3 * v3
        z00 += zi
        z10 += zi * u
        z01 += zi * v
        z20 += zi * u2
        z11 += zi * uv
        z02 += zi * v2
        z30 += zi * u3
        z21 += zi * u2v
        z12 += zi * uv2
        z03 += zi * v3
    gram[0, 0] = n
    gram[0, 1] = s10
    gram[0, 2] = s01
    gram[0, 3] = s20
    gram[0, 4] = s11
    gram[0, 5] = s02
    gram[0, 6] = s30
    gram[0, 7] = s21
    gram[0, 8] = s12
    gram[0, 9] = s03
    gram[1, 1] = s20
    gram[1, 2] = s11
    gram[1, 3] = s30
    gram[1, 4] = s21
    gram[1, 5] = s12
    gram[1, 6] = s40
    gram[1, 7] = s31
    gram[1, 8] = s22
    gram[1, 9] = s13
    gram[2, 2] = s02
    gram[2, 3] = s21
    gram[2, 4] = s12
    gram[2, 5] = s03
    gram[2, 6] = s31
    gram[2, 7] = s22
    gram[2, 8] = s13
    gram[2, 9] = s04
    gram[3, 3] = s40
    gram[3, 4] = s31
    gram[3, 5] = s22
    gram[3, 6] = s50
    gram[3, 7] = s41
    gram[3, 8] = s32
    gram[3, 9] = s23
    gram[4, 4] = s22
    gram[4, 5] = s13
    gram[4, 6] = s41
    gram[4, 7] = s32
    gram[4, 8] = s23
    gram[4, 9] = s14
    gram[5, 5] = s04
    gram[5, 6] = s32
    gram[5, 7] = s23
    gram[5, 8] = s14
    gram[5, 9] = s05
    gram[6, 6] = s60
    gram[6, 7] = s51
    gram[6, 8] = s42
    gram[6, 9] = s33
    gram[7, 7] = s42
    gram[7, 8] = s33
    gram[7, 9] = s24
    gram[8, 8] = s24
    gram[8, 9] = s15
    gram[9, 9] = s06
    rhs[0] = z00
    rhs[1] = z10
    rhs[2] = z01
    rhs[3] = z20
    rhs[4] = z11
    rhs[5] = z02
    rhs[6] = z30
    rhs[7] = z21
    rhs[8] = z12
    rhs[9] = z03


@njit(nogil=True, cache=True, inline="always")
def _moments(dx, dy, z, n, inv, top, gram, rhs):
    """The normal equations ``gram`` (upper triangle) and ``rhs`` of the polynomial of order
    ``top`` in the scaled offsets ``u = dx·inv``, ``v = dy·inv``, from the power sums
    ``Σ u^a v^b`` (a + b <= 2·top) and ``Σ z u^a v^b`` (a + b <= top), accumulated in registers
    in one pass (no design matrix; one small function per order, which compiles to much tighter
    loops than one function with four branches)."""
    if top == 0:
        _moments0(z, n, gram, rhs)
    elif top == 1:
        _moments1(dx, dy, z, n, inv, gram, rhs)
    elif top == 2:
        _moments2(dx, dy, z, n, inv, gram, rhs)
    else:
        _moments3(dx, dy, z, n, inv, gram, rhs)


@njit(nogil=True, cache=True, inline="always")
def fit_at_centre(dx, dy, z, n, order, min_rcond, gram, rhs, diag, coef):
    """Value at (0, 0) of the least-squares polynomial through ``n`` points.

    The normal equations of the column-normalised design matrix ``A`` (columns ``1, u, v, u²,
    uv, v², u³, u²v, uv², v³`` with ``u = dx/s``, ``v = dy/s``, ``s`` the farthest point's
    distance) are factored by Cholesky, ``AᵀA = RᵀR``: ``R`` is the triangular factor of the QR
    factorisation of ``A``, so ``|R_ii|`` (at most 1) is the part of monomial ``i`` independent
    of the previous ones. The fit of a lower order uses the leading block of the same factor.

    Parameters
    ----------
    dx, dy, z : (>= n,) float64
        Point offsets from the evaluation point (CRS units) and heights.
    order : int
        Highest order to try (0-3).
    min_rcond : float
        Smallest acceptable ``|R_ii|``; below it (or with fewer points than coefficients) the
        order is ill-conditioned and the next lower one is used.
    gram, rhs, diag, coef : work arrays
        ``gram`` (10, 10), the others (10,).

    Returns
    -------
    value : float
        NaN when ``n == 0``.
    used : int
        Order actually used (0 = mean of the neighbours).
    """
    if n == 0:
        return math.nan, 0
    top = order
    while top > 0 and TERMS_NB[top] > n:
        top -= 1
    scale = 0.0
    for i in range(n):
        d = dx[i] * dx[i] + dy[i] * dy[i]
        if d > scale:
            scale = d
    scale = math.sqrt(scale)
    if scale == 0.0:
        top = 0
        scale = 1.0
    m = TERMS_NB[top]
    _moments(dx, dy, z, n, 1.0 / scale, top, gram, rhs)
    # Cholesky AᵀA = R'ᵀR' of the unnormalised matrix: R' = R·D with D the column norms, so
    # |R_jj| = R'_jj / sqrt(G_jj); Cholesky is unaffected by that diagonal scaling (van der
    # Sluis), so normalising first would change nothing but the cost. Stop at the first column
    # whose independent part is below min_rcond: no order using it is well conditioned.
    rc2 = min_rcond * min_rcond
    good = m
    for j in range(m):
        g = gram[j, j]
        piv = g
        for t in range(j):
            piv -= gram[t, j] * gram[t, j]
        if not piv > rc2 * g:
            good = j
            break
        rjj = math.sqrt(piv)
        inv = 1.0 / rjj
        diag[j] = inv
        gram[j, j] = rjj
        for c in range(j + 1, m):
            acc = gram[j, c]
            for t in range(j):
                acc -= gram[t, j] * gram[t, c]
            gram[j, c] = acc * inv
    used = top
    while TERMS_NB[used] > good:
        used -= 1
    mu = TERMS_NB[used]
    # R'ᵀy = rhs, then R'c = y (leading mu x mu block); c[0] is the height at the centre
    for i in range(mu):
        acc = rhs[i]
        for t in range(i):
            acc -= gram[t, i] * coef[t]
        coef[i] = acc * diag[i]
    for i in range(mu - 1, -1, -1):
        acc = coef[i]
        for t in range(i + 1, mu):
            acc -= gram[i, t] * coef[t]
        coef[i] = acc * diag[i]
    return coef[0], used


# duplicate-ok: the block-of-cells loop of idw_kernel._grid and bin_kernels._grid_knn; numba
# cached kernels cannot take the per-cell step as an argument without a dispatch per cell
@njit(nogil=True, cache=True)
def _grid(px, py, offsets, x0, y0, size, nbx, nby, pz, xs, ys, mask, k, r2max, order,
          min_rcond, min_neighbours, max_d2, block, best_d2, best_i, cand_x, cand_y, cand_p,
          cand_d, bd2, bi, bn, bnear, dx, dy, zz, gram, rhs, diag, coef, out, used_counts):
    """Work arrays: ``block_scratch``, then :func:`_fit_scratch`."""
    h, w = mask.shape
    for r0 in range(0, h, block):
        r1 = r0 + block if r0 + block < h else h
        for c0 in range(0, w, block):
            c1 = c0 + block if c0 + block < w else w
            block_knn(px, py, offsets, x0, y0, size, nbx, nby, xs, ys, c0, c1, r0, r1, mask, k,
                      r2max, best_d2, best_i, cand_x, cand_y, cand_p, cand_d, bd2, bi, bn,
                      bnear)
            for r in range(r0, r1):
                qy = ys[r]
                for c in range(c0, c1):
                    t = (r - r0) * (c1 - c0) + (c - c0)
                    n = bn[t]
                    if n == 0 or n < min_neighbours or bnear[t] > max_d2:
                        continue
                    qx = xs[c]
                    for j in range(n):
                        p = bi[t, j]
                        dx[j] = px[p] - qx
                        dy[j] = py[p] - qy
                        zz[j] = pz[p]
                    value, used = fit_at_centre(dx, dy, zz, n, order, min_rcond, gram, rhs,
                                                diag, coef)
                    out[r, c] = value
                    used_counts[used] += 1


@njit(nogil=True, cache=True)
def _loo(px, py, offsets, x0, y0, size, nbx, nby, pz, targets, k, r2max, order,
         min_rcond, min_neighbours, max_d2, best_d2, best_i, dx, dy, zz, gram, rhs, diag, coef,
         out, used):
    """Work arrays: the k best of the search, then :func:`_fit_scratch`."""
    for t_ in range(len(targets)):
        i = targets[t_]
        n = knn_one(px, py, offsets, x0, y0, size, nbx, nby, px[i], py[i], k, r2max, i,
                    best_d2, best_i)
        if n < min_neighbours or n == 0 or best_d2[0] > max_d2:
            used[t_] = -1
            continue
        for t in range(n):
            j = best_i[t]
            dx[t] = px[j] - px[i]
            dy[t] = py[j] - py[i]
            zz[t] = pz[j]
        out[t_], used[t_] = fit_at_centre(dx, dy, zz, n, order, min_rcond, gram, rhs, diag,
                                          coef)


def _fit_scratch(k: int) -> tuple:
    """Work arrays of :func:`fit_at_centre` for up to k points: offsets dx, dy and heights,
    then ``gram``, ``rhs``, ``diag``, ``coef``."""
    return (np.empty(k), np.empty(k), np.empty(k), np.empty((10, 10)), np.empty(10),
            np.empty(10), np.empty(10))


def polynomial_grid(xyz: np.ndarray, xs: np.ndarray, ys: np.ndarray, mask: np.ndarray,
                    order: int, neighbours: int, radius: float = math.inf,
                    min_neighbours: int = 1, max_distance: float = math.inf,
                    min_rcond: float = DEFAULT_MIN_RCOND) -> tuple[np.ndarray, np.ndarray]:
    """Local polynomial heights at the cell centres ``xs`` x ``ys`` (local coordinates).

    Parameters
    ----------
    xyz : (n, 3) float64
        Data points, local origin.
    xs, ys : (w,), (h,) float64
        Column and row centres; row 0 is ``ys[0]``.
    mask : (h, w) bool
        Cells to compute; the others stay NaN.
    order : {1, 2, 3}
        Plane, quadratic or cubic (eq. [46]-[48]).
    neighbours : int
        k nearest points used (within ``radius`` when finite).
    min_neighbours : int
        Cells with fewer neighbours found stay NaN.
    max_distance : float
        Cells whose nearest point is farther stay NaN.

    Returns
    -------
    values : (h, w) float64, NaN where not computed
    used : (4,) int64
        Cells fitted with order 0 (mean), 1, 2 and 3.
    """
    bins = PointBins.build(xyz[:, :2])
    out = np.full((len(ys), len(xs)), np.nan)
    counts = np.zeros(4, dtype=np.int64)
    xs = np.asarray(xs, "float64")
    ys = np.asarray(ys, "float64")
    k = int(neighbours)
    block = block_size(bins, k, _cell(xs, ys))
    _grid(*bins.args(), bins.binned(xyz[:, 2]), xs, ys, np.ascontiguousarray(mask, dtype=np.bool_),
          k, _sq(radius), int(order), float(min_rcond), int(min_neighbours), _sq(max_distance),
          block, *block_scratch(len(bins), k, block), *_fit_scratch(k), out, counts)
    return out, counts


def polynomial_loo(bins: PointBins, z: np.ndarray, targets: np.ndarray, order: int,
                   neighbours: int, radius: float = math.inf, min_neighbours: int = 1,
                   max_distance: float = math.inf,
                   min_rcond: float = DEFAULT_MIN_RCOND) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-out prediction at the data points ``targets`` (indices into ``bins``).

    Returns ``(predicted (t,), order used (t,))``; NaN and -1 where no prediction was possible.
    """
    targets = np.asarray(targets, dtype=np.int64)
    out = np.full(len(targets), np.nan)
    used = np.full(len(targets), -1, dtype=np.int64)
    k = int(neighbours)
    _loo(*bins.args(), bins.binned(z), bins.positions()[targets], k, _sq(radius), int(order),
         float(min_rcond), int(min_neighbours), _sq(max_distance), np.empty(k),
         np.empty(k, dtype=np.int64), *_fit_scratch(k), out, used)
    return out, used


def _sq(distance: float | None) -> float:
    if distance is None or not math.isfinite(distance):
        return math.inf
    return float(distance) ** 2
