"""Compiled film collinearity residuals and Jacobians, one observation per iteration (``prange``:
both cores): the arithmetic of :func:`toolbox.triangulation.model.image_residuals` (its numpy
form stays the readable reference; the tests hold both to finite differences and to scipy),
without the dozens of (m, 3, 3) temporaries numpy's einsums allocate (most of a large block's
linearisation time)."""

from __future__ import annotations

from numba import njit, prange


@njit(cache=True, parallel=True, error_model="numpy")
def film_residuals(xy, ext, pt, calib, r, dr, jacobians, f, depth, je, jp, jcal):
    """Fill ``f`` (m, 2), ``depth`` (m,) and, with ``jacobians``, ``je`` (m, 2, 6), ``jp``
    (m, 2, 3), ``jcal`` (m, 2, 8); arguments as :func:`~toolbox.triangulation.model.
    image_residuals` (``r``, ``dr``: each observation's photo rotation and its derivatives)."""
    m = xy.shape[0]
    for i in prange(m):
        dx = pt[i, 0] - ext[i, 0]
        dy = pt[i, 1] - ext[i, 1]
        dz = pt[i, 2] - ext[i, 2]
        d0 = r[i, 0, 0] * dx + r[i, 1, 0] * dy + r[i, 2, 0] * dz
        d1 = r[i, 0, 1] * dx + r[i, 1, 1] * dy + r[i, 2, 1] * dz
        d2 = r[i, 0, 2] * dx + r[i, 1, 2] * dy + r[i, 2, 2] * dz
        c = calib[i, 0]
        inv = 1.0 / d2
        px = -c * d0 * inv
        py = -c * d1 * inv
        u = xy[i, 0] - calib[i, 1]
        v = xy[i, 1] - calib[i, 2]
        k1, k2, k3, p1, p2 = calib[i, 3], calib[i, 4], calib[i, 5], calib[i, 6], calib[i, 7]
        r2 = u * u + v * v
        drad = k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        xb = u - u * drad - (p1 * (r2 + 2 * u * u) + 2 * p2 * u * v)
        yb = v - v * drad - (p2 * (r2 + 2 * v * v) + 2 * p1 * u * v)
        f[i, 0] = px - xb
        f[i, 1] = py - yb
        depth[i] = d2
        if not jacobians:
            continue
        # d(proj)/d(d)
        a00 = -c * inv
        a02 = c * d0 * inv * inv
        a12 = c * d1 * inv * inv
        for k in range(3):  # J_point = dp·Rᵀ: column k is row k of R
            jp[i, 0, k] = a00 * r[i, k, 0] + a02 * r[i, k, 2]
            jp[i, 1, k] = a00 * r[i, k, 1] + a12 * r[i, k, 2]
            je[i, 0, k] = -jp[i, 0, k]
            je[i, 1, k] = -jp[i, 1, k]
        for t in range(3):  # (dR/dt)ᵀ·(P - C)
            e0 = dr[i, t, 0, 0] * dx + dr[i, t, 1, 0] * dy + dr[i, t, 2, 0] * dz
            e1 = dr[i, t, 0, 1] * dx + dr[i, t, 1, 1] * dy + dr[i, t, 2, 1] * dz
            e2 = dr[i, t, 0, 2] * dx + dr[i, t, 1, 2] * dy + dr[i, t, 2, 2] * dz
            je[i, 0, 3 + t] = a00 * e0 + a02 * e2
            je[i, 1, 3 + t] = a00 * e1 + a12 * e2
        ddr = k1 + 2 * k2 * r2 + 3 * k3 * r2 * r2
        dxb_du = 1 - drad - u * ddr * 2 * u - (6 * p1 * u + 2 * p2 * v)
        dxb_dv = -u * ddr * 2 * v - (2 * p1 * v + 2 * p2 * u)
        dyb_du = -v * ddr * 2 * u - (2 * p2 * u + 2 * p1 * v)
        dyb_dv = 1 - drad - v * ddr * 2 * v - (6 * p2 * v + 2 * p1 * u)
        jcal[i, 0, 0] = px / c
        jcal[i, 1, 0] = py / c
        jcal[i, 0, 1], jcal[i, 0, 2] = dxb_du, dxb_dv
        jcal[i, 1, 1], jcal[i, 1, 2] = dyb_du, dyb_dv
        jcal[i, 0, 3], jcal[i, 0, 4], jcal[i, 0, 5] = u * r2, u * r2 * r2, u * r2 * r2 * r2
        jcal[i, 1, 3], jcal[i, 1, 4], jcal[i, 1, 5] = v * r2, v * r2 * r2, v * r2 * r2 * r2
        jcal[i, 0, 6], jcal[i, 0, 7] = r2 + 2 * u * u, 2 * u * v
        jcal[i, 1, 6], jcal[i, 1, 7] = 2 * u * v, r2 + 2 * v * v
