"""NumPy versions of the per-window kernels a camera model's ortho uses: bilinear DEM heights
on a grid or at points (:func:`heights_on_grid`, :func:`heights_at_points`, as
:mod:`toolbox.ortho.heights`) and the coordinate map of a
:class:`~toolbox.cameras.frame.FrameCamera` (:func:`frame_grid_to_pixels`, as
:func:`toolbox.cameras.kernels.grid_to_pixels`).

Same arithmetic in the same order as the compiled kernels (their test oracle), vectorised in
row chunks of about :data:`CHUNK_CELLS` cells, so that the temporaries stay in the cache and
the memory small. A job small enough that numba's start-up (about 0.8 s CPU and 120 MB the
first time a compiled kernel is loaded) outweighs the kernels' speed runs on these
(:data:`toolbox.ortho.run.OrthoOptions.compiled`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

CHUNK_CELLS = 1 << 14  # cells per chunk of rows (float64 temporaries of 128 kB; measured fastest)


def _axis(coords: np.ndarray, origin: float, step: float, n: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """DEM index and weight along one axis of the grid points (``(coords - origin) / step``):
    index ``min(int(f), n - 2)``, weight ``f - index``, ``f`` clamped to ``[0, n - 1]`` in the
    outer half cell (the edge value held); outside ``[-0.5, n - 0.5]`` index 0 and weight NaN
    (so that the height is NaN)."""
    f = (coords - origin) / step
    inside = (f >= -0.5) & (f <= n - 0.5)
    f = np.clip(f, 0.0, n - 1.0)
    index = np.minimum(np.where(inside, f, 0.0).astype(np.int64), n - 2)
    return index, np.where(inside, f - index, np.nan)


def heights_on_grid(dem: np.ndarray, gx0: float, gy0: float, cx: float, cy: float,
                    xs: np.ndarray, ys: np.ndarray, out: np.ndarray) -> None:
    """Bilinear heights at the grid points ``(xs[j], ys[i])`` into ``out`` (h, w): the DEM rows
    the grid needs interpolated along x once, then each grid row a blend of its two."""
    rows, cols = dem.shape
    jj, tx = _axis(xs, gx0, cx, cols)
    ii, ty = _axis(-ys, -gy0, cy, rows)  # (gy0 - y) / cy
    inside = np.isfinite(ty)
    if not inside.any():
        out[:] = np.nan
        return
    r0, r1 = int(ii[inside].min()), int(ii[inside].max()) + 2
    part = dem[r0:r1]
    along = part[:, jj] * (1.0 - tx) + part[:, jj + 1] * tx  # (DEM rows, w)
    top, wy = ii - r0, ty[:, None]
    step = max(1, CHUNK_CELLS // max(len(xs), 1))
    for i in range(0, len(ys), step):
        s = slice(i, i + step)
        out[s] = along[top[s]] * (1.0 - wy[s]) + along[top[s] + 1] * wy[s]
    out[~inside] = np.nan


def heights_at_points(dem: np.ndarray, gx0: float, gy0: float, cx: float, cy: float,
                      x: np.ndarray, y: np.ndarray, out: np.ndarray) -> None:
    """As :func:`heights_on_grid` at scattered points ``(x[k], y[k])`` (1-D arrays)."""
    from toolbox.photogrammetry.kernels_numpy import _dem_height

    out[:] = _dem_height(x, y, dem, gx0, gy0, cx, cy)[0]


def frame_grid_to_pixels(camera: Any, gx: np.ndarray, gy: np.ndarray, z: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`~toolbox.cameras.frame.FrameCamera.project_grid` in NumPy: ground cells
    ``(gx, gy, z)`` (broadcastable to z's (h, w)) -> float32 maps ``(cols, rows)`` (NaN: no
    image) and ``box`` (col_min, row_min, col_max, row_max, NaN count)."""
    m = camera.intrinsics
    fisheye = m.kind == "fisheye"
    k = np.zeros(12)
    k[:4 if fisheye else 12] = m.opencv_coefficients()
    z = np.asarray(z, dtype="float64")
    gx = np.broadcast_to(np.asarray(gx, dtype="float64"), z.shape)
    gy = np.broadcast_to(np.asarray(gy, dtype="float64"), z.shape)
    cols = np.empty(z.shape, dtype="float32")
    rows = np.empty(z.shape, dtype="float32")
    model = (np.asarray(camera.centre, dtype="float64"),
             np.asarray(camera.exterior.rotation, dtype="float64"),
             fisheye, k, np.array(m.focal_px, dtype="float64"),
             np.array(m.principal_point_px, dtype="float64"), min(float(m.valid_radius), 1e300))
    h, w = z.shape
    step = max(1, CHUNK_CELLS // max(w, 1))
    for i in range(0, h, step):
        s = slice(i, i + step)
        terms = _plane_terms(gx[s], gy[s], model[0], model[1])
        _grid_rows(terms, z[s] - model[0][2], *model[1:], cols[s], rows[s])
    finite = ~np.isnan(cols)
    missing = z.size - int(np.count_nonzero(finite))
    if missing == z.size:
        box = np.array([np.inf, np.inf, -np.inf, -np.inf, missing])
    else:
        box = np.array([np.fmin.reduce(cols, axis=None), np.fmin.reduce(rows, axis=None),
                        np.fmax.reduce(cols, axis=None), np.fmax.reduce(rows, axis=None),
                        missing], dtype="float64")
    return cols, rows, box


def _plane_terms(gx: np.ndarray, gy: np.ndarray, centre: np.ndarray, rot: np.ndarray
                 ) -> list[np.ndarray]:
    """The camera frame's x, y, z without their height terms, ``Rᵀ·(X - X0, Y - Y0)`` with y
    and z negated (OpenCV's frame), each as ``a·dx + b·dy`` (broadcastable to (h, w)). A grid of
    cell centres (``gx`` constant down the columns, ``gy`` along the rows: broadcast views)
    gets them as a row plus a column, computed once per row and column: the same sums in the
    same order as per cell (negation is exact, so ``-(a + b) == -a + -b``)."""
    if gx.strides[0] == 0 and gy.strides[1] == 0:  # the broadcast grid of cell centres
        dx, dy = gx[:1] - centre[0], gy[:, :1] - centre[1]
    else:
        dx, dy = gx - centre[0], gy - centre[1]
    sign = (1.0, -1.0, -1.0)
    return [(sign[k] * rot[0, k]) * dx + (sign[k] * rot[1, k]) * dy for k in range(3)]


def _grid_rows(terms, dz, rot, fisheye, k, focal, pp, valid, cols, rows) -> None:
    """A chunk of :func:`frame_grid_to_pixels` (the arithmetic of ``grid_to_pixels``, in
    place where it can be: each product and sum is the kernel's, in its order; IEEE addition
    and multiplication commute exactly): ``terms`` of :func:`_plane_terms`, ``dz`` the
    heights minus the centre's."""
    x = np.multiply(dz, rot[2, 0])
    x += terms[0]
    y = np.multiply(dz, -rot[2, 1])
    y += terms[1]
    zc = np.multiply(dz, -rot[2, 2])
    zc += terms[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        if fisheye:
            rho = np.sqrt(x * x + y * y)
            theta = np.arctan2(rho, zc)
            ok = theta <= valid
            t2 = theta * theta
            td = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
            s = np.where(rho > 0, td / rho, 1.0)
            xd, yd = x * s, y * s
        else:
            xn, yn = np.divide(x, zc, out=x), np.divide(y, zc, out=y)
            r2 = xn * xn
            t = yn * yn
            r2 += t
            ok = zc > 0
            ok &= r2 <= valid * valid
            # terms whose coefficients are all zero are left out: they add exactly 0 (or
            # divide by exactly 1) to finite values, so the results stay the kernel's
            more = k[2] != 0.0 or k[3] != 0.0 or k[8:].any()
            if k[[0, 1, 4]].any():
                ratio = np.multiply(r2, k[4], out=t)  # 1 + r2·(k1 + r2·(k2 + r2·k3))
                ratio += k[1]
                ratio *= r2
                ratio += k[0]
                ratio *= r2
                ratio += 1.0
                if k[5:8].any():
                    den = r2 * k[7]
                    den += k[6]
                    den *= r2
                    den += k[5]
                    den *= r2
                    den += 1.0
                    ratio /= den
                xd, yd = xn * ratio, yn * ratio
            else:
                xd, yd = (xn.copy(), yn.copy()) if more else (xn, yn)
            if k[2] != 0.0 or k[3] != 0.0:  # tangential: xd + 2·p1·xy + p2·(r2 + 2·xn²), ...
                xy = xn * yn
                t = xy * (2.0 * k[2])
                xd += t
                t = xn * 2.0
                t *= xn
                t += r2
                t *= k[3]
                xd += t
                t = yn * 2.0
                t *= yn
                t += r2
                t *= k[2]
                yd += t
                t = xy * (2.0 * k[3])
                yd += t
            if k[8:].any():  # thin prism: + r2·(s1 + r2·s2), + r2·(s3 + r2·s4)
                t = r2 * k[9]
                t += k[8]
                t *= r2
                xd += t
                t = r2 * k[11]
                t += k[10]
                t *= r2
                yd += t
        xd *= focal[0]
        xd += pp[0]
        yd *= focal[1]
        yd += pp[1]
        cols[...] = xd
        rows[...] = yd
    bad = np.isnan(cols)
    bad |= np.isnan(rows)
    bad |= ~ok
    np.copyto(cols, np.float32(np.nan), where=bad)
    np.copyto(rows, np.float32(np.nan), where=bad)
