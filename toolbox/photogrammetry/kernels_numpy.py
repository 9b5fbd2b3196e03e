"""NumPy versions of two collinearity kernels of :mod:`toolbox.photogrammetry.kernels`, for
rays without distortion (``dmode == 0``: a model camera's normalised coordinates, a film camera
without distortion): :func:`image_to_ground_at_z` and the ``march`` method of :func:`monoplot`.

Same signatures, same arithmetic in the same order, vectorised over the points (the march and
the regula falsi step all unfinished rays together). For the few hundred rays of a footprint
they cost a few milliseconds and spare the process numba's start-up (about 0.8 s CPU and 120 MB
the first time a compiled kernel is loaded); :func:`toolbox.photogrammetry.collinearity` picks
them for small, distortion-free point sets. The numba kernels are their test oracle.
"""

from __future__ import annotations

import numpy as np

OK, OUTSIDE, NODATA, NOT_CONVERGED, RAY_UPWARD, NO_INTERSECTION = 0, 1, 2, 3, 4, 5
MARCH_BLOCK = 32  # steps of every ray evaluated together in the march (some past its crossing)


def supports(dmode: int, method: int = 0) -> bool:
    """True when these kernels compute what the compiled ones would: no distortion, march."""
    return dmode == 0 and method == 0


def _ray(u, v, rot, c, pp, m):
    """Ground-parallel direction R·(x̄, ȳ, -c) of the rays through (u, v) (no distortion)."""
    w = m[2, 0] * u + m[2, 1] * v + m[2, 2]
    xc = (m[0, 0] * u + m[0, 1] * v + m[0, 2]) / w - pp[0]
    yc = (m[1, 0] * u + m[1, 1] * v + m[1, 2]) / w - pp[1]
    return tuple(rot[k, 0] * xc + rot[k, 1] * yc - rot[k, 2] * c for k in range(3))


def image_to_ground_at_z(u, v, z, centre, rot, c, pp, dmode, dr, dd, dk, di, m, out):
    """As the compiled kernel (``dmode`` must be 0): rays cut at ``Z = z``; NaN X, Y for rays
    parallel to the plane or meeting it behind the camera; returns their count."""
    if dmode != 0:
        raise ValueError("the NumPy collinearity kernels take no distortion (dmode 0)")
    with np.errstate(divide="ignore", invalid="ignore"):
        dx, dy, dz = _ray(u, v, rot, c, pp, m)
        zi = np.broadcast_to(z if z.shape[0] > 1 else z[0], u.shape)
        t = np.where(dz != 0.0, (zi - centre[2]) / np.where(dz != 0.0, dz, 1.0), -1.0)
    bad = ~(t > 0.0)
    out[:, 0] = np.where(bad, np.nan, centre[0] + t * dx)
    out[:, 1] = np.where(bad, np.nan, centre[1] + t * dy)
    if out.shape[1] > 2:
        out[:, 2] = zi
    return int(np.count_nonzero(bad))


def _dem_height(x, y, dem, gx0, gy0, cx, cy):
    """Bilinear heights between cell centres, the edge value held across the outer half cell
    (as the compiled ``_dem_height``), and their codes (OK, OUTSIDE, NODATA)."""
    rows, cols = dem.shape
    fx = (x - gx0) / cx
    fy = (gy0 - y) / cy
    inside = (fx >= -0.5) & (fy >= -0.5) & (fx <= cols - 0.5) & (fy <= rows - 0.5)
    fx, fy = np.clip(fx, 0.0, cols - 1.0), np.clip(fy, 0.0, rows - 1.0)
    j = np.minimum(np.where(inside, fx, 0.0).astype(np.int64), cols - 2)
    i = np.minimum(np.where(inside, fy, 0.0).astype(np.int64), rows - 2)
    tx, ty = fx - j, fy - i
    h = (dem[i, j] * (1.0 - tx) + dem[i, j + 1] * tx) * (1.0 - ty) + \
        (dem[i + 1, j] * (1.0 - tx) + dem[i + 1, j + 1] * tx) * ty
    code = np.where(inside, np.where(np.isnan(h), NODATA, OK), OUTSIDE).astype(np.int8)
    return np.where(code == OK, h, np.nan), code


def _entry(xc0, yc0, ex, ey, s_lo, s_hi, gx0, gy0, cx, cy, rows, cols):
    """The compiled kernel's ``_entry`` for arrays of rays: the first ray parameter in ``[s_lo,
    s_hi]`` over the DEM's cells (their outer edges, by 1e-7 cells), -1 where there is none."""
    lo = np.array(np.broadcast_to(np.asarray(s_lo, dtype=float), ex.shape))
    hi = np.array(np.broadcast_to(np.asarray(s_hi, dtype=float), ex.shape))
    margin = 1e-7
    for f0, df, top in (((xc0 - gx0) / cx, ex / cx, cols - 1.0),
                        ((gy0 - yc0) / cy, -ey / cy, rows - 1.0)):
        flat = df == 0.0
        lo[flat & ((f0 < margin - 0.5) | (f0 > top + 0.5 - margin))] = np.inf
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (margin - 0.5 - f0) / np.where(flat, 1.0, df)
            t2 = (top + 0.5 - margin - f0) / np.where(flat, 1.0, df)
        lo = np.where(flat, lo, np.maximum(lo, np.minimum(t1, t2)))
        hi = np.where(flat, hi, np.minimum(hi, np.maximum(t1, t2)))
    return np.where(lo <= hi, lo, -1.0)


def monoplot(u, v, centre, rot, c, pp, dmode, dr, dd, dk, di, m, dem, gx0, gy0, cx, cy, zmin,
             zmax, method, z_start, tolerance, max_iterations, out, status, iterations):
    """The compiled kernel's ``march`` (``method`` 0, ``dmode`` 0): walk down every ray from
    ``zmax`` (a rising ray up from the camera) in steps of half a cell, then refine the first
    sign change of ``Z_ray - Z_dem`` by Illinois regula falsi; writes ``out``, ``status``,
    ``iterations`` as it does."""
    if not supports(dmode, method):
        raise ValueError("the NumPy monoplot marches (method 0) rays without distortion")
    xc0, yc0, zc0 = centre[0], centre[1], centre[2]
    out[:] = np.nan
    iterations[:] = 0
    status[:] = NO_INTERSECTION
    dx, dy, dz = _ray(u, v, rot, c, pp, m)
    down, rise = dz < 0.0, dz > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        ex, ey = dx / -dz, dy / -dz
    # the parameter q: height descended (risen, for a ray rising from a camera in a valley);
    # ground point (xc0, yc0) + q·(gx, gy), the ray's height zc0 + gz·q
    gx, gy, gz = np.where(rise, -ex, ex), np.where(rise, -ey, ey), np.where(rise, 1.0, -1.0)
    lo = np.where(rise, max(0.0, zmin - zc0), max(0.0, zc0 - zmax))
    hi = np.where(rise, zmax - zc0, zc0 - zmin)
    status[~(down | rise) | rise & (hi < lo)] = RAY_UPWARD  # (rising above the highest)
    hcell = 0.5 * min(cx, cy)

    def f(idx, s):  # Z_ray - Z_dem at the ray parameters s of the rays idx, and the codes
        h, code = _dem_height(xc0 + s * gx[idx], yc0 + s * gy[idx], dem, gx0, gy0, cx, cy)
        return (zc0 + gz[idx] * s) - h, code

    live = np.flatnonzero((down | rise) & (hi >= lo))  # else below the lowest terrain
    a = lo.copy()
    fa = np.zeros(u.shape)
    fa[live], code = f(live, a[live])
    beside = live[code == OUTSIDE]  # beside the DEM: start where the ray comes over it
    entered = np.zeros(u.shape, dtype=bool)
    if beside.size:
        a[beside] = _entry(xc0, yc0, gx[beside], gy[beside], lo[beside], hi[beside], gx0, gy0,
                           cx, cy, *dem.shape)
        came = beside[a[beside] >= 0.0]
        entered[came] = True
        fa[came], code_in = f(came, a[came])
        code[np.isin(live, came)] = code_in
    status[live[code != OK]] = code[code != OK]
    live = live[code == OK]
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.sqrt(gx * gx + gy * gy)
        step = np.where(speed * (hi - a) <= hcell, hi - a, hcell / speed)
    below = fa[live] < -tolerance  # camera below the terrain surface, or (entered) the ray
    status[live[below & entered[live]]] = OUTSIDE  # comes over the DEM's edge below it
    live = live[~below]
    fa[live] = np.where(fa[live] <= tolerance, 0.0, fa[live])  # on the surface at the top
    b, fb = a.copy(), fa.copy()
    found = np.zeros(u.shape, dtype=bool)
    found[live[fa[live] == 0.0]] = True
    walk = live[(fa[live] != 0.0) & (step[live] > 0.0)]
    while walk.size:  # MARCH_BLOCK steps of every ray at a time
        # the samples b = a + step, (a + step) + step, ... as the kernel adds them (a cumulative
        # sum adds in order), then min(., hi)
        sums = np.empty((walk.size, MARCH_BLOCK + 1))
        sums[:, 0] = a[walk]
        sums[:, 1:] = step[walk, None]
        bb = np.minimum(np.cumsum(sums, axis=1)[:, 1:], hi[walk, None])
        fbb, code = f(walk[:, None], bb)
        failed = code != OK
        hit = ~failed & (fbb <= 0.0)
        event = failed | hit | (bb >= hi[walk, None])  # the kernel's loop stops at the first of these
        first = np.argmax(event, axis=1)
        rows = np.arange(walk.size)
        stops = event[rows, first]
        at = first[stops]
        done, r = walk[stops], rows[stops]
        b[done], fb[done] = bb[r, at], fbb[r, at]
        status[done[failed[r, at]]] = code[r, at][failed[r, at]]
        found[done[hit[r, at]]] = True
        later = at > 0  # the sample before the stop becomes a (else a stays)
        a[done[later]], fa[done[later]] = bb[r[later], at[later] - 1], fbb[r[later], at[later] - 1]
        go = walk[~stops]
        a[go], fa[go] = bb[~stops, -1], fbb[~stops, -1]
        walk = go
    # a rising ray that found no terrain up to the highest: the sky, as the kernel says
    status[live[rise[live] & ~found[live] & (status[live] == NO_INTERSECTION)]] = RAY_UPWARD
    # Illinois regula falsi on [a, b], fa > 0 >= fb
    idx = np.flatnonzero(found)
    root, froot = b.copy(), fb.copy()
    k = np.zeros(u.shape, dtype=np.int32)
    run = idx[np.abs(froot[idx]) > tolerance]
    while run.size:
        k[run] += 1
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (a[run] * fb[run] - b[run] * fa[run]) / (fb[run] - fa[run])
        fs, code = f(run, s)
        stop = code != OK  # cannot happen inside a bracket of valid samples, unless NaN cells
        go = run[~stop]
        s, fs = s[~stop], fs[~stop]
        root[go], froot[go] = s, fs
        flip = fs * fb[go] < 0.0
        a[go[flip]], fa[go[flip]] = b[go[flip]], fb[go[flip]]
        fa[go[~flip]] *= 0.5
        b[go], fb[go] = s, fs
        close = np.abs(b[go] - a[go]) <= 1e-15 * (1.0 + np.abs(b[go]))
        run = go[~close & (np.abs(froot[go]) > tolerance) & (k[go] < max_iterations)]
    iterations[idx] = k[idx]
    gap = np.abs(b[idx] - a[idx]) > 1e-15 * (1.0 + np.abs(b[idx]))
    failed = (np.abs(froot[idx]) > tolerance) & gap
    status[idx[failed]] = NOT_CONVERGED
    ok = idx[~failed]
    out[ok, 0] = xc0 + root[ok] * gx[ok]
    out[ok, 1] = yc0 + root[ok] * gy[ok]
    out[ok, 2] = zc0 + gz[ok] * root[ok]
    status[ok] = OK
