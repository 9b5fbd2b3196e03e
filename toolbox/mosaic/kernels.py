"""Compiled kernels of the seam cost surface (:func:`toolbox.mosaic.seams.cost_surface`): the
image terms in one pass, and "within a Euclidean radius of a set of cells".

Test oracles: ``scipy.ndimage.sobel`` (mode ``reflect``) for :func:`image_cost` and
``scipy.ndimage.distance_transform_edt`` for :func:`within_radius`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _row_mean(x, r, out):
    """Band mean of row ``r`` of ``x`` (clamped to the image: scipy's ``reflect`` edge, the
    edge row repeated) into ``out[1:-1]``, its end cells repeated into ``out[0]``, ``out[-1]``."""
    bands, rows, cols = x.shape
    rr = min(max(r, 0), rows - 1)
    for c in range(cols):
        out[c + 1] = 0.0
    for k in range(bands):
        for c in range(cols):
            out[c + 1] += x[k, rr, c]
    for c in range(cols):
        out[c + 1] /= bands
    out[0] = out[1]
    out[cols + 1] = out[cols]


@njit(cache=True, nogil=True)
def _sobel(up, mid, dn, c):
    """Sobel derivatives / 8 ``(d/dy, d/dx)`` at image column ``c`` (padded column ``c + 1``)
    of the band means of three rows."""
    dy = (dn[c] + 2.0 * dn[c + 1] + dn[c + 2] - up[c] - 2.0 * up[c + 1] - up[c + 2]) * 0.125
    dx = (up[c + 2] + 2.0 * mid[c + 2] + dn[c + 2] - up[c] - 2.0 * mid[c] - dn[c]) * 0.125
    return dy, dx


def image_cost(a, b, scale, difference, base, gradient, workers=None):
    """The image terms of the seam cost of orthos ``a`` and ``b`` (``(bands, rows, cols)``,
    the same shape) in one pass: ``(base + difference x diff + gradient x grad, gdiff)``,
    float64 ``(rows, cols)`` each, where, on the band means ``ma`` and ``mb``, ``diff`` is the
    mean absolute band difference, ``grad`` the larger Sobel gradient magnitude (scipy's
    ``sobel / 8``, edges ``reflect``) of the two, ``gdiff`` the magnitude of the gradients'
    difference, each times ``scale``. Rows in bands on threads (``workers``)."""
    from toolbox.executor import in_row_bands

    bands, rows, cols = a.shape
    cost = np.empty((rows, cols), np.float64)
    gdiff = np.empty((rows, cols), np.float64)
    weights = (float(difference), float(base), float(gradient))
    in_row_bands(lambda r0, r1: image_cost_rows(a, b, scale, weights, r0, r1, cost, gdiff),
                 rows, cols, workers=workers)
    return cost, gdiff


@njit(cache=True, nogil=True)
def image_cost_rows(a, b, scale, weights, r0, r1, cost, gdiff):
    """Rows ``r0`` to ``r1`` (excluded) of :func:`image_cost`. One pass over the rows, with
    the band means of three rows at a time (row ``r`` in slot ``(r + 3) % 3``)."""
    w_diff, base, w_grad = weights
    bands, rows, cols = a.shape
    ma = np.empty((3, cols + 2), np.float64)
    mb = np.empty((3, cols + 2), np.float64)
    for r in (r0 - 1, r0):
        _row_mean(a, r, ma[(r + 3) % 3])
        _row_mean(b, r, mb[(r + 3) % 3])
    diffs = np.empty(cols, np.float64)  # the row's band differences, summed band by band
    inv = scale / bands
    for r in range(r0, r1):
        _row_mean(a, r + 1, ma[(r + 1) % 3])
        _row_mean(b, r + 1, mb[(r + 1) % 3])
        up_a, mid_a, dn_a = ma[(r + 2) % 3], ma[r % 3], ma[(r + 1) % 3]
        up_b, mid_b, dn_b = mb[(r + 2) % 3], mb[r % 3], mb[(r + 1) % 3]
        diffs[:] = 0.0
        for k in range(bands):
            for c in range(cols):
                diffs[c] += abs(np.float64(a[k, r, c]) - np.float64(b[k, r, c]))
        for c in range(cols):
            diff = diffs[c] * inv
            ay, ax = _sobel(up_a, mid_a, dn_a, c)
            by, bx = _sobel(up_b, mid_b, dn_b, c)
            ga = ay * ay + ax * ax
            gb = by * by + bx * bx
            grad = np.sqrt(max(ga, gb)) * scale
            grad *= w_grad
            value = diff * w_diff
            value += base
            value += grad
            cost[r, c] = value
            gdiff[r, c] = np.sqrt((ay - by) * (ay - by) + (ax - bx) * (ax - bx)) * scale


@njit(cache=True, nogil=True)
def _push_parabola(q, fq, vp, vf, z, m):
    """Add the parabola of cell ``q`` (value ``fq``, finite) to the lower envelope of the
    ``m + 1`` parabolas ``vp`` (cells), ``vf`` (values), ``z`` (their boundaries; ``m = -1``:
    none yet), those it hides dropped (Felzenszwalb and Huttenlocher 2012, "Distance transforms
    of sampled functions", algorithm DT(f)). Returns the index of the envelope's last one."""
    if m < 0:
        vp[0] = q
        vf[0] = fq
        z[0] = -np.inf
        z[1] = np.inf
        return 0
    while True:
        p = vp[m]
        s = ((fq + q * q) - (vf[m] + p * p)) / (2.0 * q - 2.0 * p)
        if s <= z[m]:
            m -= 1
            continue
        break
    m += 1
    vp[m] = q
    vf[m] = fq
    z[m] = s
    z[m + 1] = np.inf
    return m


@njit(cache=True, nogil=True)
def _lower_envelope(f, n, out, vp, vf, z):
    """1-D squared Euclidean distance transform of ``f[:n]`` into ``out`` (infinite cells are
    no sites; all infinite: infinity)."""
    m = -1
    for q in range(n):
        if f[q] < np.inf:
            m = _push_parabola(q, f[q], vp, vf, z, m)
    if m < 0:
        for q in range(n):
            out[q] = np.inf
        return
    m = 0
    for q in range(n):
        while z[m + 1] < q:
            m += 1
        p = vp[m]
        out[q] = (q - p) * (q - p) + vf[m]


def within_radius(mask, radius, workers=None):
    """True where the Euclidean distance (in cells) to the nearest True cell of ``mask`` is at
    most ``radius``: the exact squared distance transform, columns then rows, each pass in
    bands on ``workers`` local threads for large masks (:func:`toolbox.executor.in_row_bands`).

    Only the columns holding a True cell are transformed (the others are at an infinite column
    distance, which the row pass skips): a sparse mask (a seam's structured differences: 16 of
    1000 columns) costs a fraction of the whole grid, for the same distances."""
    from toolbox.executor import in_row_bands

    rows, cols = mask.shape
    result = np.zeros((rows, cols), np.bool_)
    held = np.flatnonzero(mask.any(axis=0))  # the columns with a True cell
    if not len(held):
        return result
    d = np.empty((rows, len(held)), np.float64)
    in_row_bands(lambda j0, j1: _column_distances(mask, held, j0, j1, d), len(held), rows,
                 workers=workers)
    in_row_bands(lambda r0, r1: _row_within(d, held, radius * radius, r0, r1, result), rows,
                 cols, workers=workers)
    return result


@njit(cache=True, nogil=True)
def _envelope_scratch(n):
    """The arrays :func:`_lower_envelope` works in, for lines of ``n`` cells."""
    return (np.empty(n, np.float64), np.empty(n, np.float64), np.empty(n, np.int64),
            np.empty(n, np.float64), np.empty(n + 1, np.float64))


@njit(cache=True, nogil=True)
def _column_distances(mask, held, j0, j1, d):
    """Squared distances along the columns ``held[j0:j1]`` to the nearest True cell of
    ``mask`` in each, into ``d[:, j0:j1]``."""
    rows = mask.shape[0]
    f, out, vp, vf, z = _envelope_scratch(rows)
    for j in range(j0, j1):
        c = held[j]
        for r in range(rows):
            f[r] = 0.0 if mask[r, c] else np.inf
        _lower_envelope(f, rows, out, vp, vf, z)
        for r in range(rows):
            d[r, j] = out[r]


@njit(cache=True, nogil=True)
def _row_within(d, held, r2, r0, r1, result):
    """Rows ``r0`` to ``r1`` (excluded): ``result`` True where the squared distance of the
    column distances ``d`` (of the columns ``held``, every other column at infinity) completed
    along the row is at most ``r2``: :func:`_lower_envelope` of the whole row, its infinite
    cells skipped, the same operations."""
    cols = result.shape[1]
    k = len(held)
    vp = np.empty(k, np.int64)  # the envelope's parabolas: column, value
    vf = np.empty(k, np.float64)
    z = np.empty(k + 1, np.float64)
    for r in range(r0, r1):
        m = -1
        for j in range(k):
            if d[r, j] < np.inf:
                m = _push_parabola(held[j], d[r, j], vp, vf, z, m)
        if m < 0:  # no finite cell in the row: nothing within reach
            continue
        m = 0
        for c in range(cols):
            while z[m + 1] < c:
                m += 1
            p = vp[m]
            result[r, c] = (c - p) * (c - p) + vf[m] <= r2


@njit(cache=True, nogil=True)
def add_centre_term(cost, x0, dx, y0, dy, ax, ay, bx, by, weight):
    """``cost += weight x |‖p − a‖ − ‖p − b‖| / ‖a − b‖`` at the cell centres ``p = (x0 + (col
    + 0.5) dx, y0 + (row + 0.5) dy)``, in place (the centre term of
    :func:`toolbox.mosaic.seams.centre_term`, its oracle)."""
    rows, cols = cost.shape
    scale = weight / max(np.hypot(ax - bx, ay - by), 1e-9)
    for r in range(rows):
        y = y0 + (r + 0.5) * dy
        ya = (y - ay) * (y - ay)
        yb = (y - by) * (y - by)
        for c in range(cols):
            x = x0 + (c + 0.5) * dx
            da = np.sqrt((x - ax) * (x - ax) + ya)
            db = np.sqrt((x - bx) * (x - bx) + yb)
            cost[r, c] += scale * abs(da - db)
