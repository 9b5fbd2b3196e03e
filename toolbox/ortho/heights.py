"""Bilinear DEM heights (between DEM cell centres, the edge value held across the DEM's outer
half cell as GDAL's bilinear resampling does; NaN beyond the DEM's outer cell edges or on nodata)
on a grid of cell centres or at scattered points: the kernels of
:class:`toolbox.ortho.dem.DemSampler`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from toolbox.ortho.jit import FAST
from toolbox.photogrammetry.kernels import _dem_height


@njit(**FAST)
def heights_on_grid(dem, gx0, gy0, cx, cy, xs, ys, out):
    """Bilinear heights (between DEM cell centres, held across the outer half cell; NaN beyond
    the DEM's cells or on nodata) at the grid points
    ``(xs[j], ys[i])``; ``dem`` cell [0, 0] centred at ``(gx0, gy0)``, cells ``cx`` x ``cy``.
    Separable: the column and row of every point are found once per column and once per row
    (the same arithmetic as the per-point ``_dem_height`` of the monoplot kernel)."""
    w = xs.shape[0]
    jj = np.empty(w, dtype=np.uint64)
    tx = np.empty(w)
    _dem_columns(dem.shape[1], gx0, cx, xs, jj, tx)
    _heights_rows(dem, gy0, cy, ys, jj, tx, 0, ys.shape[0], 0, out)


@njit(**FAST)
def _dem_columns(cols, gx0, cx, xs, jj, tx):
    """DEM column ``jj`` (unsigned: no negative-index check) and weight ``tx`` of every grid
    column; in the outer half cell the edge column (clamped, as ``_dem_height``); beyond the
    DEM's cells column 0 and weight NaN, so that the height is NaN."""
    for j in range(xs.shape[0]):
        fx = (xs[j] - gx0) / cx
        if fx >= -0.5 and fx <= cols - 0.5:
            fx = min(max(fx, 0.0), cols - 1.0)
            jj[j] = min(int(fx), cols - 2)
            tx[j] = fx - jj[j]
        else:
            jj[j] = 0
            tx[j] = np.nan


@njit(**FAST)
def _heights_rows(dem, gy0, cy, ys, jj, tx, i0, i1, zoff, out):
    """Rows ``i0:i1`` of :func:`heights_on_grid` into ``out[i0 - zoff:i1 - zoff]``; returns the
    number of NaN heights. The two DEM rows around a grid row are interpolated along x once
    (kept while the grid rows stay between them), then every grid row is a blend of the two
    (vectorised, no gathers)."""
    rows = dem.shape[0]
    w = jj.shape[0]
    top = np.empty(w)
    bottom = np.empty(w)
    held = -2
    missing = 0
    for i in range(i0, i1):
        o = out[i - zoff]
        fy = (gy0 - ys[i]) / cy
        if not (fy >= -0.5 and fy <= rows - 0.5):
            o[:] = np.nan
            missing += w
            continue
        fy = min(max(fy, 0.0), rows - 1.0)  # the outer half cell: the edge row's heights
        r = min(int(fy), rows - 2)
        ty = fy - r
        if r == held + 1:  # the grid rows go south: the old bottom row is the new top
            top, bottom = bottom, top
            _dem_row_along_x(dem[r + 1], jj, tx, bottom)
        elif r != held:
            _dem_row_along_x(dem[r], jj, tx, top)
            _dem_row_along_x(dem[r + 1], jj, tx, bottom)
        held = r
        for j in range(w):
            o[j] = top[j] * (1.0 - ty) + bottom[j] * ty
            missing += 1 if math.isnan(o[j]) else 0
    return missing


@njit(**FAST)
def _dem_row_along_x(d, jj, tx, out):
    """One DEM row interpolated at the grid columns (``jj``, ``tx`` of :func:`_dem_columns`)."""
    for j in range(jj.shape[0]):
        c = jj[j]
        t = tx[j]
        out[j] = d[c] * (1.0 - t) + d[c + 1] * t


@njit(cache=True, nogil=True)
def heights_at_points(dem, gx0, gy0, cx, cy, x, y, out):
    """As :func:`heights_on_grid` at scattered points ``(x[k], y[k])`` (1-D arrays)."""
    for k in range(x.shape[0]):
        out[k] = _dem_height(x[k], y[k], dem, gx0, gy0, cx, cy)[0]
