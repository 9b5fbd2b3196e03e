"""Which cells of a tile are computed: inside the data's convex hull, inside a mask polygon.

A cell belongs to a region when its *centre* does (thesis par. 2.5.2: the value belongs to the
cell's centre), the rule GDAL's rasteriser follows without ``ALL_TOUCHED``. Centres exactly on
the hull's boundary are inside (the hull is closed), with a tolerance for rounding (1e-9 cell,
more at large map coordinates: :func:`toolbox.io.grid.cell_slack`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.cache import njit_on_first_call


def convex_hull(xy: np.ndarray) -> np.ndarray | None:
    """Vertices of the convex hull of ``xy`` ((n, 2) float), counter-clockwise, as an (m, 2)
    array; ``None`` when the points are collinear or fewer than 3 (the hull has no area).

    GEOS's hull (shapely, already loaded by every gridding run): the vertices Qhull gives
    (scipy's ``ConvexHull``, the test oracle; collinear boundary points left out by both), in
    the same counter-clockwise order, so the cells inside are the same; importing
    ``scipy.spatial`` was 0.1 s of a 1.5 s ``dem:idw`` run (``bench/results/round3.md``).
    """
    import shapely

    xy = np.asarray(xy, dtype="float64")[:, :2]
    if len(xy) < 3:
        return None
    xy = xy[_hull_candidates(xy)]
    hull = shapely.convex_hull(shapely.multipoints(xy))
    if hull.geom_type != "Polygon":  # collinear or coincident points: a line or a point
        return None
    ring = shapely.get_coordinates(hull.exterior)[:-1]
    area = 0.5 * np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
    if area < 0:  # GEOS's rings run clockwise
        ring, area = ring[::-1].copy(), -area
    if not area > 0:
        return None
    return ring


#: below this many points GEOS takes every point (about 50 ms at 50,000): the compiled filter
#: would cost a numba compilation (about a second) on a first run with small data
HULL_FILTER_MIN_POINTS = 50_000


def _hull_candidates(xy: np.ndarray) -> np.ndarray:
    """Indices of the points that may be convex-hull vertices: those not strictly inside the
    polygon of the extreme points in 8 directions (Akl-Toussaint); exact, and it leaves Qhull a
    few hundred points instead of millions."""
    if len(xy) < HULL_FILTER_MIN_POINTS:
        return np.arange(len(xy))
    return _akl_toussaint(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]))


@njit_on_first_call(nogil=True, cache=True)
def _akl_toussaint(x, y):
    n = len(x)
    best = np.full(8, -np.inf)
    arg = np.zeros(8, dtype=np.int64)
    for i in range(n):
        for d in range(8):  # directions counter-clockwise from east
            if d == 0:
                v = x[i]
            elif d == 1:
                v = x[i] + y[i]
            elif d == 2:
                v = y[i]
            elif d == 3:
                v = y[i] - x[i]
            elif d == 4:
                v = -x[i]
            elif d == 5:
                v = -x[i] - y[i]
            elif d == 6:
                v = -y[i]
            else:
                v = x[i] - y[i]
            if v > best[d]:
                best[d] = v
                arg[d] = i
    keep = np.ones(n, dtype=np.bool_)
    for i in range(n):
        inside = True
        for d in range(8):
            a = arg[d]
            b = arg[(d + 1) % 8]
            if a == b:
                continue
            ex = x[b] - x[a]
            ey = y[b] - y[a]
            cross = ex * (y[i] - y[a]) - ey * (x[i] - x[a])
            # strictly inside by a margin larger than rounding: a candidate when in doubt
            if cross <= 1e-9 * (abs(ex) + abs(ey)) * (abs(x[i] - x[a]) + abs(y[i] - y[a]) + 1.0):
                inside = False
                break
        keep[i] = not inside
    return np.flatnonzero(keep)


def hull_vertex_indices(xy: np.ndarray) -> np.ndarray:
    """Indices of the points that are vertices of the convex hull: the points outside the hull
    of the others. Collinear points have a segment as hull: its two ends (every point sitting
    on one of them)."""
    from scipy.spatial import ConvexHull, QhullError

    xy = np.asarray(xy, dtype="float64")[:, :2]
    if len(xy) < 3:
        return np.arange(len(xy))
    candidates = _hull_candidates(xy)
    try:
        return np.sort(candidates[ConvexHull(xy[candidates]).vertices])
    except QhullError:  # collinear (or coincident): the ends of the segment
        centred = xy - xy.mean(axis=0)
        direction = np.linalg.svd(centred, full_matrices=False)[2][0]
        t = centred @ direction
        return np.flatnonzero((t == t.min()) | (t == t.max()))


def convex_row_spans(ring: np.ndarray, ys: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """For each row centre ``ys[r]``, the x span ``[left[r], right[r]]`` of a convex polygon
    (NaN when the row misses it). ``tol`` widens the polygon slightly for rounding."""
    ys = np.asarray(ys, dtype="float64")
    left = np.full(len(ys), np.inf)
    right = np.full(len(ys), -np.inf)
    x1, y1 = ring[:, 0], ring[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    ylo, yhi = float(y1.min()), float(y1.max())
    yq = np.clip(ys, ylo, yhi)  # rows within tol of the top/bottom vertex touch it
    inside_rows = (ys >= ylo - tol) & (ys <= yhi + tol)
    for a_x, a_y, b_x, b_y in zip(x1, y1, x2, y2, strict=True):
        lo, hi = min(a_y, b_y), max(a_y, b_y)
        rows = (yq >= lo) & (yq <= hi)
        if not rows.any():
            continue
        if a_y == b_y:
            xa, xb = min(a_x, b_x), max(a_x, b_x)
            left[rows] = np.minimum(left[rows], xa)
            right[rows] = np.maximum(right[rows], xb)
            continue
        x = a_x + (yq[rows] - a_y) * (b_x - a_x) / (b_y - a_y)
        left[rows] = np.minimum(left[rows], x)
        right[rows] = np.maximum(right[rows], x)
    valid = inside_rows & (left <= right)
    left = np.where(valid, left - tol, np.nan)
    right = np.where(valid, right + tol, np.nan)
    return left, right


def hull_mask(ring: np.ndarray, xs: np.ndarray, ys: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """(h, w) bool: cell centres ``xs`` x ``ys`` inside the closed convex polygon ``ring``."""
    left, right = convex_row_spans(ring, ys, tol)
    xs = np.asarray(xs, dtype="float64")
    with np.errstate(invalid="ignore"):
        return (xs[None, :] >= left[:, None]) & (xs[None, :] <= right[:, None])


def polygon_mask(geometry: Any, transform: Any, shape: tuple[int, int]) -> np.ndarray:
    """(h, w) bool: cells of a window (``transform``, ``shape``) whose centre is inside the
    (multi)polygon ``geometry`` (map coordinates), by GDAL's rasteriser."""
    from rasterio.features import geometry_mask

    if geometry is None or geometry.is_empty:
        return np.zeros(shape, dtype=bool)
    return geometry_mask([geometry], out_shape=shape, transform=transform, invert=True)
