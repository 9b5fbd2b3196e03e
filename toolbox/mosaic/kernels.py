"""Compiled kernels of the seam cost surface (:func:`toolbox.mosaic.seams.cost_surface`): the
image terms in one pass, and "within a Euclidean radius of a set of cells".

Test oracles: ``scipy.ndimage.sobel`` (mode ``reflect``) for :func:`image_terms` and
``scipy.ndimage.distance_transform_edt`` for :func:`within_radius`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _means(a, b):
    """Band means of ``a`` and ``b`` (with one reflected cell round the edges: scipy's
    ``reflect``, the edge cell repeated) and the mean over bands of ``|a − b|``."""
    bands, rows, cols = a.shape
    ma = np.zeros((rows + 2, cols + 2), np.float64)
    mb = np.zeros((rows + 2, cols + 2), np.float64)
    diff = np.zeros((rows, cols), np.float64)
    inv = 1.0 / bands
    for k in range(bands):
        for r in range(rows):
            for c in range(cols):
                x = np.float64(a[k, r, c])
                y = np.float64(b[k, r, c])
                ma[r + 1, c + 1] += x * inv
                mb[r + 1, c + 1] += y * inv
                diff[r, c] += abs(x - y) * inv
    for m in (ma, mb):
        m[0, :] = m[1, :]
        m[rows + 1, :] = m[rows, :]
        m[:, 0] = m[:, 1]
        m[:, cols + 1] = m[:, cols]
    return ma, mb, diff


@njit(cache=True, nogil=True)
def image_terms(a, b, scale):
    """The image terms of two co-registered images ``(bands, rows, cols)`` float32, each scaled
    by ``scale`` (1 / value range): ``diff`` = mean over bands of ``|a − b|``; ``grad`` = the
    larger Sobel gradient magnitude (derivatives / 8) of the two band means; ``gdiff`` = the
    magnitude of the difference of their Sobel gradients. Float64 ``(rows, cols)`` each."""
    bands, rows, cols = a.shape
    ma, mb, diff = _means(a, b)
    grad = np.empty((rows, cols), np.float64)
    gdiff = np.empty((rows, cols), np.float64)
    for r in range(rows):
        for c in range(cols):
            diff[r, c] *= scale
            # padded indexes: the cell is (r + 1, c + 1)
            ay = (ma[r + 2, c] + 2.0 * ma[r + 2, c + 1] + ma[r + 2, c + 2]
                  - ma[r, c] - 2.0 * ma[r, c + 1] - ma[r, c + 2]) * 0.125
            ax = (ma[r, c + 2] + 2.0 * ma[r + 1, c + 2] + ma[r + 2, c + 2]
                  - ma[r, c] - 2.0 * ma[r + 1, c] - ma[r + 2, c]) * 0.125
            by = (mb[r + 2, c] + 2.0 * mb[r + 2, c + 1] + mb[r + 2, c + 2]
                  - mb[r, c] - 2.0 * mb[r, c + 1] - mb[r, c + 2]) * 0.125
            bx = (mb[r, c + 2] + 2.0 * mb[r + 1, c + 2] + mb[r + 2, c + 2]
                  - mb[r, c] - 2.0 * mb[r + 1, c] - mb[r + 2, c]) * 0.125
            ga = ay * ay + ax * ax
            gb = by * by + bx * bx
            grad[r, c] = np.sqrt(max(ga, gb)) * scale
            gdiff[r, c] = np.sqrt((ay - by) * (ay - by) + (ax - bx) * (ax - bx)) * scale
    return diff, grad, gdiff


@njit(cache=True, nogil=True)
def _lower_envelope(f, n, out, v, z):
    """1-D squared Euclidean distance transform of ``f[:n]`` into ``out`` (Felzenszwalb and
    Huttenlocher 2012, "Distance transforms of sampled functions", algorithm DT(f))."""
    k = 0
    first = -1
    for q in range(n):
        if f[q] < np.inf:
            first = q
            break
    if first < 0:
        for q in range(n):
            out[q] = np.inf
        return
    v[0] = first
    z[0] = -np.inf
    z[1] = np.inf
    for q in range(first + 1, n):
        if f[q] == np.inf:
            continue
        while True:
            p = v[k]
            s = ((f[q] + q * q) - (f[p] + p * p)) / (2.0 * q - 2.0 * p)
            if s <= z[k]:
                k -= 1
                continue
            break
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = np.inf
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        p = v[k]
        out[q] = (q - p) * (q - p) + f[p]


@njit(cache=True, nogil=True)
def within_radius(mask, radius):
    """True where the Euclidean distance (in cells) to the nearest True cell of ``mask`` is at
    most ``radius``: the exact squared distance transform, columns then rows."""
    rows, cols = mask.shape
    n = max(rows, cols)
    d = np.empty((rows, cols), np.float64)
    f = np.empty(n, np.float64)
    out = np.empty(n, np.float64)
    v = np.empty(n, np.int64)
    z = np.empty(n + 1, np.float64)
    for c in range(cols):
        for r in range(rows):
            f[r] = 0.0 if mask[r, c] else np.inf
        _lower_envelope(f, rows, out, v, z)
        for r in range(rows):
            d[r, c] = out[r]
    r2 = radius * radius
    result = np.empty((rows, cols), np.bool_)
    for r in range(rows):
        for c in range(cols):
            f[c] = d[r, c]
        _lower_envelope(f, cols, out, v, z)
        for c in range(cols):
            result[r, c] = out[c] <= r2
    return result
