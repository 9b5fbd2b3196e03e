"""Compiled (numba) collinearity kernels; use them through :mod:`toolbox.photogrammetry.collinearity`.

Every kernel takes the sensor model as plain arrays and numbers (no Python objects):

``centre (3,)``, ``rot (3, 3)`` = R(omega, phi, kappa), ``c`` principal distance (mm),
``pp (2,)`` principal point (mm), ``dmode`` distortion mode (0 none, 1 table, 2 polynomial),
``dr (K,)`` / ``dd (K,)`` the distortion table (radius mm -> Δr mm, ``dr[0] = 0``),
``dk (6,)`` k1, k2, the table's bin width, k3, p1, p2, ``di (B,)`` the table segment at the
start of each bin (see :meth:`toolbox.photogrammetry.camera.RadialDistortion.kernel_arguments`;
the distortion's correction form: :mod:`toolbox.photogrammetry.camera`), and
``m (3, 3)`` a plane projective matrix between image mm and the input/output coordinates
(fiducial -> pixel for ground -> image, pixel -> fiducial for image -> ground; the identity for
mm).

Loops run in parallel (``prange``) with ``fastmath`` off, so results are bit-for-bit those of
IEEE double arithmetic in the order written (formulas: domain brief sections 2 and 4).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

OK, OUTSIDE, NODATA, NOT_CONVERGED, RAY_UPWARD, NO_INTERSECTION = 0, 1, 2, 3, 4, 5
_DISTORT_ITERATIONS = 20  # as camera.DISTORT_ITERATIONS, DISTORT_TOLERANCE_MM
_DISTORT_TOLERANCE = 1e-9


@njit(cache=True, inline="always")
def _delta_r(r, dmode, dr, dd, dk, di):
    """Radial displacement Δr(r) (mm) and its derivative dΔr/dr: linear in the table (last value
    held), or the polynomial k1·r³ + k2·r⁵ + k3·r⁷.

    The table segment is found through ``di``: ``di[b]`` is the segment holding radius
    ``b·dk[2]`` (uniform bins), then a short forward scan; exact, without a binary search.
    """
    if dmode == 1:
        n = dr.shape[0]
        if r >= dr[n - 1]:
            return dd[n - 1], 0.0
        if r <= 0.0:
            return dd[0], 0.0
        b = int(r / dk[2])
        j = di[b] if b < di.shape[0] else n - 2
        while j + 2 < n and dr[j + 1] <= r:
            j += 1
        slope = (dd[j + 1] - dd[j]) / (dr[j + 1] - dr[j])
        return dd[j] + (r - dr[j]) * slope, slope
    if dmode == 2:
        r2 = r * r
        return ((dk[0] + r2 * (dk[1] + r2 * dk[3])) * r2 * r,
                (3.0 * dk[0] + r2 * (5.0 * dk[1] + 7.0 * r2 * dk[3])) * r2)
    return 0.0, 0.0


@njit(cache=True, inline="always")
def _undistort(x, y, dmode, dr, dd, dk, di):
    """Measured -> ideal (coordinates relative to the principal point, mm)."""
    if dmode == 0:
        return x, y
    r2 = x * x + y * y
    if r2 == 0.0:
        return x, y
    p1, p2 = dk[4], dk[5]
    r = math.sqrt(r2)
    f = 1.0 - _delta_r(r, dmode, dr, dd, dk, di)[0] / r
    if p1 == 0.0 and p2 == 0.0:
        return x * f, y * f
    return (x * f - (p1 * (r2 + 2.0 * x * x) + 2.0 * p2 * x * y),
            y * f - (p2 * (r2 + 2.0 * y * y) + 2.0 * p1 * x * y))


@njit(cache=True, inline="always")
def _distort(x, y, dmode, dr, dd, dk, di):
    """Ideal -> measured (NaN when not converged). Radial only: g(r) = r - Δr(r) - r_ideal = 0
    by Newton's method from r = r_ideal (|dΔr/dr| << 1: two or three steps); with decentring:
    Newton's method on the 2-D correction ``_undistort(m) = (x, y)`` from m = (x, y). Both stop
    at a step <= ``_DISTORT_TOLERANCE`` mm."""
    if dmode == 0:
        return x, y
    ri = math.sqrt(x * x + y * y)
    p1, p2 = dk[4], dk[5]
    if p1 == 0.0 and p2 == 0.0:
        if ri == 0.0:
            return x, y
        r = ri
        for _ in range(_DISTORT_ITERATIONS):
            value, slope = _delta_r(r, dmode, dr, dd, dk, di)
            step = (r - value - ri) / (1.0 - slope)
            r -= step
            if abs(step) <= _DISTORT_TOLERANCE:
                f = r / ri
                return x * f, y * f
        return np.nan, np.nan
    u, v = x, y
    for _ in range(_DISTORT_ITERATIONS):
        r2 = u * u + v * v
        r = math.sqrt(r2)
        g, h = 0.0, 0.0
        if r > 0.0:
            value, slope = _delta_r(r, dmode, dr, dd, dk, di)
            g = value / r
            h = (slope - g) / r2
        # residual correct(m) - ideal and its Jacobian (1 - dδ/dm)
        fx = u - u * g - (p1 * (r2 + 2.0 * u * u) + 2.0 * p2 * u * v) - x
        fy = v - v * g - (p2 * (r2 + 2.0 * v * v) + 2.0 * p1 * u * v) - y
        a = 1.0 - (g + u * u * h + 6.0 * p1 * u + 2.0 * p2 * v)
        b = -(u * v * h + 2.0 * p1 * v + 2.0 * p2 * u)
        c = -(u * v * h + 2.0 * p2 * u + 2.0 * p1 * v)
        d = 1.0 - (g + v * v * h + 6.0 * p2 * v + 2.0 * p1 * u)
        det = a * d - b * c
        su = (d * fx - b * fy) / det
        sv = (a * fy - c * fx) / det
        u -= su
        v -= sv
        if math.sqrt(su * su + sv * sv) <= _DISTORT_TOLERANCE:
            return u, v
    return np.nan, np.nan


@njit(cache=True, inline="always")
def _project2d(m, u, v):
    """Plane projective map; ``m`` a 9-tuple (row-major 3 x 3)."""
    w = m[6] * u + m[7] * v + m[8]
    return (m[0] * u + m[1] * v + m[2]) / w, (m[3] * u + m[4] * v + m[5]) / w


@njit(cache=True, inline="always")
def _tuple9(a):
    return (a[0, 0], a[0, 1], a[0, 2], a[1, 0], a[1, 1], a[1, 2], a[2, 0], a[2, 1], a[2, 2])


@njit(parallel=True, cache=True)
def ground_to_image(x, y, z, centre, rot, c, pp, dmode, dr, dd, dk, di, m, out):
    """Collinearity ground -> image (S000 l.401-446, brief section 4), then distortion and ``m``.

    ``x, y, z`` (N,) ground coordinates; writes ``out`` (N, 2). Points on or behind the plane of
    the projection centre (``Rᵀ·(X - X0)`` with z >= 0) get NaN; returns their count.
    The model is copied to scalars first so the loop keeps it in registers.
    """
    n = x.shape[0]
    behind = 0
    x0, y0, z0 = centre[0], centre[1], centre[2]
    r = _tuple9(rot)
    mt = _tuple9(m)
    px, py = pp[0], pp[1]
    for i in prange(n):
        dx = x[i] - x0
        dy = y[i] - y0
        dz = z[i] - z0
        den = r[2] * dx + r[5] * dy + r[8] * dz
        if not den < 0.0:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            behind += 1
            continue
        xi = -c * (r[0] * dx + r[3] * dy + r[6] * dz) / den
        eta = -c * (r[1] * dx + r[4] * dy + r[7] * dz) / den
        xi, eta = _distort(xi, eta, dmode, dr, dd, dk, di)
        u, v = _project2d(mt, xi + px, eta + py)
        out[i, 0] = u
        out[i, 1] = v
    return behind


@njit(cache=True, inline="always")
def _ray(u, v, r, c, px, py, dmode, dr, dd, dk, di, mt):
    """Ground-parallel direction R·(x̄, ȳ, -c) of the ray through input point (u, v)."""
    xf, yf = _project2d(mt, u, v)
    xc, yc = _undistort(xf - px, yf - py, dmode, dr, dd, dk, di)
    dx = r[0] * xc + r[1] * yc - r[2] * c
    dy = r[3] * xc + r[4] * yc - r[5] * c
    dz = r[6] * xc + r[7] * yc - r[8] * c
    return dx, dy, dz


@njit(parallel=True, cache=True)
def image_to_ground_at_z(u, v, z, centre, rot, c, pp, dmode, dr, dd, dk, di, m, out):
    """Collinearity image -> ground on the plane(s) ``Z = z`` (brief section 4, second form).

    ``u, v`` (N,) input coordinates (pixels or mm, see ``m``); ``z`` (N,) or (1,) heights;
    writes ``out`` (N, 2 or 3): X, Y (and Z when there is a third column). Rays parallel to the
    plane or meeting it behind the camera get NaN X, Y; returns their count.
    """
    n = u.shape[0]
    bad = 0
    with_z = out.shape[1] > 2
    nz = z.shape[0]
    x0, y0, z0 = centre[0], centre[1], centre[2]
    r = _tuple9(rot)
    mt = _tuple9(m)
    px, py = pp[0], pp[1]
    z_all = z[0]
    for i in prange(n):
        dx, dy, dz = _ray(u[i], v[i], r, c, px, py, dmode, dr, dd, dk, di, mt)
        zi = z[i] if nz > 1 else z_all
        t = (zi - z0) / dz if dz != 0.0 else -1.0
        if not t > 0.0:
            out[i, 0] = np.nan
            out[i, 1] = np.nan
            if with_z:
                out[i, 2] = zi
            bad += 1
            continue
        out[i, 0] = x0 + t * dx
        out[i, 1] = y0 + t * dy
        if with_z:
            out[i, 2] = zi
    return bad


@njit(cache=True)
def _dem_height(x, y, dem, gx0, gy0, cx, cy):
    """Bilinear height between cell centres, the edge value held across the outer half cell
    (a point inside the DEM's cells but beyond its outer centres takes the height of the
    nearest point of the centres' hull, as GDAL's bilinear resampling:
    :func:`toolbox.raster.bilinear.bilinear` with ``half_cell``); NaN with a code: 0 ok,
    OUTSIDE (beyond the DEM's outer cell edges), NODATA."""
    rows, cols = dem.shape
    fx = (x - gx0) / cx
    fy = (gy0 - y) / cy
    if not (fx >= -0.5 and fy >= -0.5 and fx <= cols - 0.5 and fy <= rows - 0.5):
        return np.nan, OUTSIDE
    fx = min(max(fx, 0.0), cols - 1.0)
    fy = min(max(fy, 0.0), rows - 1.0)
    j = min(int(fx), cols - 2)
    i = min(int(fy), rows - 2)
    tx = fx - j
    ty = fy - i
    z00, z01 = dem[i, j], dem[i, j + 1]
    z10, z11 = dem[i + 1, j], dem[i + 1, j + 1]
    h = (z00 * (1.0 - tx) + z01 * tx) * (1.0 - ty) + (z10 * (1.0 - tx) + z11 * tx) * ty
    if math.isnan(h):
        return np.nan, NODATA
    return h, OK


@njit(cache=True, inline="always")
def _entry(xc0, yc0, ex, ey, s_lo, s_hi, gx0, gy0, cx, cy, rows, cols):
    """The first ray parameter in ``[s_lo, s_hi]`` where the ray's track ``(xc0 + s·ex, yc0 +
    s·ey)`` is inside the DEM's cells (their outer edges, by 1e-7 cells), or -1 if it never is:
    a camera beside the DEM (an oblique photo of it from outside) starts its march there."""
    lo = s_lo
    hi = s_hi
    margin = 1e-7
    for axis in range(2):
        if axis == 0:
            f0 = (xc0 - gx0) / cx
            df = ex / cx
            top = cols - 1.0
        else:
            f0 = (gy0 - yc0) / cy
            df = -ey / cy
            top = rows - 1.0
        if df == 0.0:
            if f0 < margin - 0.5 or f0 > top + 0.5 - margin:
                return -1.0
            continue
        t1 = (margin - 0.5 - f0) / df
        t2 = (top + 0.5 - margin - f0) / df
        lo = max(lo, min(t1, t2))
        hi = min(hi, max(t1, t2))
    if not lo <= hi:
        return -1.0
    return lo


@njit(parallel=True, cache=True)
def monoplot(u, v, centre, rot, c, pp, dmode, dr, dd, dk, di, m, dem, gx0, gy0, cx, cy, zmin,
             zmax, method, z_start, tolerance, max_iterations, out, status, iterations):
    """Intersect the rays of (u, v) with a DEM (bilinear between cell centres).

    ``dem`` (rows, cols) heights with NaN for nodata; ``gx0, gy0`` the centre of cell [0, 0];
    ``cx, cy`` cell sizes (> 0, rows go south); ``zmin, zmax`` the DEM's height range.

    ``method`` 0 (march): walk down the ray from ``zmax`` in steps of half a cell and refine the
    first sign change of ``Z_ray - Z_dem`` by Illinois regula falsi until ``|Z_ray - Z_dem| <=
    tolerance``; it finds the first visible intersection and converges on any slope. A rising
    ray (a camera below ``zmax``) is walked up from the camera to ``zmax`` (RAY_UPWARD if it
    meets nothing); a ray whose start is off the DEM starts where it comes over the DEM.
    ``method`` 1 (fixed point): the classical iteration ``Z_{k+1} = DEM(X(Z_k), Y(Z_k))`` from
    ``z_start``; it diverges where ``slope·tan(off-nadir angle) > 1`` and then reports
    NOT_CONVERGED.

    Writes ``out`` (N, 3) X, Y, Z (NaN when failed), ``status`` (N,) int8 (OK, OUTSIDE, NODATA,
    NOT_CONVERGED, RAY_UPWARD, NO_INTERSECTION), ``iterations`` (N,) int32.
    """
    n = u.shape[0]
    xc0, yc0, zc0 = centre[0], centre[1], centre[2]
    r = _tuple9(rot)
    mt = _tuple9(m)
    px, py = pp[0], pp[1]
    hcell = 0.5 * min(cx, cy)
    for i in prange(n):
        out[i, 0] = np.nan
        out[i, 1] = np.nan
        out[i, 2] = np.nan
        iterations[i] = 0
        dx, dy, dz = _ray(u[i], v[i], r, c, px, py, dmode, dr, dd, dk, di, mt)
        if not (dz < 0.0 or dz > 0.0 and method == 0):
            status[i] = RAY_UPWARD
            continue
        ex = dx / -dz  # ground displacement per metre of descent
        ey = dy / -dz
        if method == 1:
            zk = z_start
            st = NOT_CONVERGED
            for k in range(max_iterations):
                s = zc0 - zk
                h, code = _dem_height(xc0 + s * ex, yc0 + s * ey, dem, gx0, gy0, cx, cy)
                iterations[i] = k + 1
                if code != OK:
                    st = code
                    break
                if abs(h - zk) <= tolerance:
                    s = zc0 - h
                    out[i, 0] = xc0 + s * ex
                    out[i, 1] = yc0 + s * ey
                    out[i, 2] = h
                    st = OK
                    break
                zk = h
            status[i] = st
            continue
        # march along the ray from where it comes down to (or, rising from a camera in a
        # valley, up to) the DEM's height range: the parameter q is the height the ray has
        # descended (risen), the ground point (xc0, yc0) + q·(gx, gy), the ray's height
        # zc0 + gz·q
        if dz < 0.0:
            gx, gy, gz = ex, ey, -1.0
            s_lo = max(0.0, zc0 - zmax)
            s_hi = zc0 - zmin
        else:
            gx, gy, gz = -ex, -ey, 1.0
            s_lo = max(0.0, zmin - zc0)
            s_hi = zmax - zc0
        if s_hi < s_lo:  # the camera is below the lowest terrain (above the highest, rising)
            status[i] = NO_INTERSECTION if dz < 0.0 else RAY_UPWARD
            continue
        a = s_lo
        h, code = _dem_height(xc0 + a * gx, yc0 + a * gy, dem, gx0, gy0, cx, cy)
        entered = False
        if code == OUTSIDE:  # beside the DEM: start where the ray comes over it
            a = _entry(xc0, yc0, gx, gy, s_lo, s_hi, gx0, gy0, cx, cy, dem.shape[0],
                       dem.shape[1])
            if a < 0.0:
                status[i] = OUTSIDE
                continue
            entered = True
            h, code = _dem_height(xc0 + a * gx, yc0 + a * gy, dem, gx0, gy0, cx, cy)
        if code != OK:
            status[i] = code
            continue
        speed = math.sqrt(gx * gx + gy * gy)
        step = s_hi - a if speed * (s_hi - a) <= hcell else hcell / speed
        fa = (zc0 + gz * a) - h
        if fa < -tolerance:  # camera below the terrain surface, or (entered) the ray comes
            status[i] = OUTSIDE if entered else NO_INTERSECTION  # over the DEM's edge below it
            continue
        if fa <= tolerance:  # on the surface at the top of the range (e.g. a flat DEM)
            fa = 0.0
        st = NO_INTERSECTION
        found = fa == 0.0
        b = a
        fb = fa
        while not found and step > 0.0:
            b = min(a + step, s_hi)
            h, code = _dem_height(xc0 + b * gx, yc0 + b * gy, dem, gx0, gy0, cx, cy)
            if code != OK:
                st = code
                break
            fb = (zc0 + gz * b) - h
            if fb <= 0.0:
                found = True
                break
            if b >= s_hi:
                break
            a = b
            fa = fb
        if not found:
            status[i] = st if dz < 0.0 or st != NO_INTERSECTION else RAY_UPWARD
            continue
        # Illinois regula falsi on [a, b], fa > 0 >= fb
        root = b
        froot = fb
        k = 0
        while abs(froot) > tolerance and k < max_iterations:
            k += 1
            s = (a * fb - b * fa) / (fb - fa)
            h, code = _dem_height(xc0 + s * gx, yc0 + s * gy, dem, gx0, gy0, cx, cy)
            if code != OK:  # cannot happen inside a bracket of valid samples, unless NaN cells
                break
            fs = (zc0 + gz * s) - h
            root = s
            froot = fs
            if fs * fb < 0.0:
                a = b
                fa = fb
            else:
                fa *= 0.5
            b = s
            fb = fs
            if abs(b - a) <= 1e-15 * (1.0 + abs(b)):
                break
        iterations[i] = k
        if abs(froot) > tolerance and abs(b - a) > 1e-15 * (1.0 + abs(b)):
            status[i] = NOT_CONVERGED
            continue
        out[i, 0] = xc0 + root * gx
        out[i, 1] = yc0 + root * gy
        out[i, 2] = zc0 + gz * root
        status[i] = OK
