"""The bundle's reduced normal matrix built point by point (compiled, both cores).

Each image observation ``i`` (photo ``j``, point ``p``) couples the photo's 6 exterior
unknowns with the point: ``W_i = Jc_iᵀ·Jp_i`` (6 x 3, weighted Jacobians of its two rows). With
``C_p⁻¹`` the inverse point block, the photo-photo part of the Schur complement is::

    S_jk = A_jk - Σ_p Σ_{i on j, l on k, both of p} W_i·C_p⁻¹·W_lᵀ

a sum over the pairs of observations of the same point, which are grouped by photo pair
(:func:`pair_structure`) so that each 6 x 6 block is summed by one thread
(:func:`pair_blocks`, ``prange``): no shared writes, no general sparse products (these took
most of a large block's time, single-threaded). Calibration and GNSS/IMU unknowns (few columns)
stay with scipy's sparse products (:mod:`toolbox.triangulation.solver`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _pairs(order, starts, photo):
    """Observation pairs (a, b) of each point, photo(a) <= photo(b), a == b included."""
    total = 0
    for q in range(len(starts) - 1):
        n = starts[q + 1] - starts[q]
        total += n * (n + 1) // 2
    obs_a = np.empty(total, dtype=np.int64)
    obs_b = np.empty(total, dtype=np.int64)
    t = 0
    for q in range(len(starts) - 1):
        for u in range(starts[q], starts[q + 1]):
            for v in range(u, starts[q + 1]):
                a, b = order[u], order[v]
                if photo[a] > photo[b]:
                    a, b = b, a
                obs_a[t] = a
                obs_b[t] = b
                t += 1
    return obs_a, obs_b


def pair_structure(obs_photo: np.ndarray, obs_point: np.ndarray, n_photos: int):
    """Observation pairs sharing a point, grouped by photo pair: ``(obs_a, obs_b, starts,
    photo_a, photo_b)``: the pairs of group ``g`` are ``starts[g]:starts[g + 1]`` of
    ``obs_a``/``obs_b`` (indices into the given observations), photo pair
    ``(photo_a[g], photo_b[g])``, ``photo_a <= photo_b``."""
    order = np.argsort(obs_point, kind="stable")
    pts = obs_point[order]
    starts = np.flatnonzero(np.r_[True, pts[1:] != pts[:-1], True])
    obs_a, obs_b = _pairs(order, starts, obs_photo)
    key = obs_photo[obs_a] * np.int64(n_photos) + obs_photo[obs_b]
    sort = np.argsort(key, kind="stable")
    obs_a, obs_b, key = obs_a[sort], obs_b[sort], key[sort]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    group_starts = np.r_[first, len(key)]
    return obs_a, obs_b, group_starts, key[first] // n_photos, key[first] % n_photos


@njit(cache=True, parallel=True)
def pair_blocks(y, w, obs_a, obs_b, starts):
    """``Σ Y_a·W_bᵀ`` (6 x 6) over the pairs of each group; ``y = W·C⁻¹``, ``w``: (m, 6, 3)."""
    groups = len(starts) - 1
    out = np.zeros((groups, 6, 6))
    for g in prange(groups):
        for t in range(starts[g], starts[g + 1]):
            a, b = obs_a[t], obs_b[t]
            for r in range(6):
                for c in range(6):
                    out[g, r, c] += y[a, r, 0] * w[b, c, 0] + y[a, r, 1] * w[b, c, 1] \
                        + y[a, r, 2] * w[b, c, 2]
    return out


def photo_schur(w: np.ndarray, cinv: np.ndarray, point: np.ndarray, structure, n_photos: int):
    """``Σ W·C⁻¹·Wᵀ`` of the photo-photo part (6n x 6n, both triangles) as COO triplets
    (rows, cols, values), from ``w`` (m, 6, 3), the point blocks' ``C⁻¹`` (P, 3, 3) and each
    observation's point."""
    obs_a, obs_b, starts, pa, pb = structure
    y = times_blocks(w, cinv, point)
    blocks = pair_blocks(y, w, obs_a, obs_b, starts)
    off = pa != pb  # a diagonal group holds only a == b (one measurement per point and photo)
    # off-diagonal photo pairs also give their transpose
    rows_b = np.concatenate([pa, pb[off]])
    cols_b = np.concatenate([pb, pa[off]])
    vals = np.concatenate([blocks, np.transpose(blocks[off], (0, 2, 1))])
    k = np.arange(6)
    rows = (6 * rows_b[:, None, None] + k[None, :, None]).repeat(6, axis=2)
    cols = (6 * cols_b[:, None, None] + k[None, None, :]).repeat(6, axis=1)
    return rows.ravel(), cols.ravel(), vals.ravel()



@njit(cache=True, parallel=True)
def times_blocks(w, blocks, index):
    """``w[i]·blocks[index[i]]`` for (m, 6, 3) ``w`` and (P, 3, 3) ``blocks``."""
    m = w.shape[0]
    out = np.empty((m, 6, 3))
    for i in prange(m):
        b = blocks[index[i]]
        for r in range(6):
            for c in range(3):
                out[i, r, c] = w[i, r, 0] * b[0, c] + w[i, r, 1] * b[1, c] + w[i, r, 2] * b[2, c]
    return out


@njit(cache=True, parallel=True)
def coupling(je, jp, weight):
    """``W_i = Σ_a (w·je)[i, a]ᵀ·(w·jp)[i, a]`` (m, 6, 3) from the (m, 2, 6) and (m, 2, 3)
    Jacobians and the (m, 2) weights of the two rows."""
    m = je.shape[0]
    out = np.empty((m, 6, 3))
    for i in prange(m):
        w0, w1 = weight[i, 0] * weight[i, 0], weight[i, 1] * weight[i, 1]
        for r in range(6):
            for c in range(3):
                out[i, r, c] = w0 * je[i, 0, r] * jp[i, 0, c] + w1 * je[i, 1, r] * jp[i, 1, c]
    return out


@njit(cache=True, parallel=True)
def inverse_blocks(c, limit):
    """Inverses of symmetric 3 x 3 blocks (P, 3, 3) by their adjugates, and a flag per block:
    positive definite (leading minors > 0) with a Frobenius condition number below ``limit``
    (an upper bound of the 2-norm one)."""
    n = c.shape[0]
    out = np.empty((n, 3, 3))
    ok = np.empty(n, dtype=np.bool_)
    for p in prange(n):
        a = c[p]
        m00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
        m01 = a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0]
        m02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
        det = a[0, 0] * m00 - a[0, 1] * m01 + a[0, 2] * m02
        minor2 = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
        good = a[0, 0] > 0 and minor2 > 0 and det > 0
        if good:
            inv = 1.0 / det
            out[p, 0, 0] = m00 * inv
            out[p, 0, 1] = -(a[0, 1] * a[2, 2] - a[0, 2] * a[2, 1]) * inv
            out[p, 0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * inv
            out[p, 1, 0] = -m01 * inv
            out[p, 1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * inv
            out[p, 1, 2] = -(a[0, 0] * a[1, 2] - a[0, 2] * a[1, 0]) * inv
            out[p, 2, 0] = m02 * inv
            out[p, 2, 1] = -(a[0, 0] * a[2, 1] - a[0, 1] * a[2, 0]) * inv
            out[p, 2, 2] = minor2 * inv
            fa = 0.0
            fi = 0.0
            for r in range(3):
                for s in range(3):
                    fa += a[r, s] * a[r, s]
                    fi += out[p, r, s] * out[p, r, s]
            good = np.sqrt(fa * fi) < limit
        else:
            for r in range(3):
                for s in range(3):
                    out[p, r, s] = np.nan
        ok[p] = good
    return out, ok
