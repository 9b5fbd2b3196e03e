"""Streamed ``dem:tin_linear``: the cells of the Delaunay TIN of a point cloud too large to hold,
tile by tile from the per-tile buckets of :mod:`toolbox.terrain.gridding.stream`, exactly.

Per tile, its bucket (every kept point within the tile's box grown by ``h``: the rectangle R)
is triangulated alone. A triangle of that local TIN whose circumcircle holds no point of the
cloud outside R is a Delaunay triangle of the whole cloud: its circle is empty of the bucket's
points, and every other point of the cloud lies outside R, hence (by the test) outside the
circle. The test, conservative: the open disc misses the part of the cloud's convex hull
outside R (a half-plane test per side of R first, then shapely's distance to ``hull - R`` for
the discs that fail it), with a relative margin of 1e-9 for the rounding of the circumcentre.

A cell takes the plane of a local triangle that passes (the same triangle as in the TIN of the
whole cloud, hence the same plane: cell values equal to the in-memory path's up to the
rounding of the plane through the same three nodes in another vertex order, about 1e-12
relative). When a computed cell lies in a triangle that fails, or inside the cloud's hull but
in no triangle of the bucket, the whole tile is done again from a new bucket with ``h``
doubled (one more pass over the cloud for all such tiles at once), until every cell passes;
once R holds the whole hull every triangle passes, so it ends. Once a tile is redone, one more
pass reads the hull's rim (the points within RIM_BUCKETS buckets of its edge, at most
TILE_POINTS, else none) and a redone tile's bucket also gets the rim's points within RIM_REACH
reaches of R, so that the test's "outside R" shrinks by that band: the long thin triangles along
a straight hull, whose circles cut a long shallow cap off the hull, pass without growing the
tile along the whole edge. Capped: a redone tile's grown
box may hold at most TILE_POINTS points (or its first bucket's count when larger); a cloud
that needs more (a dense cluster among far sparse points, points on a circle or a line) stops
with an :class:`InputDataError` naming TOOLBOX_STREAM_POINTS (:func:`check_growth`).

Ties: with four or more points on one empty circle (cocircular) the Delaunay TIN is not unique,
and the triangulator breaks the tie by its insertion order, which is not the same in a bucket
as in the whole cloud; such a circle's cells are then a valid Delaunay TIN's but may come from
the other diagonal than the in-memory run's. Points in general position (the tests' clouds:
uniform random on the LAS 1 mm lattice) have one Delaunay TIN and the streamed cells equal the
in-memory ones.

MAX_DISTANCE: ``h`` is at least MAX_DISTANCE, so the nearest point within it of every cell is
in the bucket (the same test as in memory).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

#: the first reach of a tile: the distance within which every cell has this many points
#: (Delaunay circumcircles in a cloud of even density are a few spacings across)
TIN_NEIGHBOURS = 32
#: relative margin of the circumcircle test (the circumcentre's rounding)
MARGIN = 1e-9


def circumcircles(xy: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (T, 2) and radii (T,) of the triangles' circumcircles (computed relative to
    each triangle's first node)."""
    a = xy[triangles[:, 0]]
    b = xy[triangles[:, 1]] - a
    c = xy[triangles[:, 2]] - a
    d = 2.0 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
    bb, cc = (b * b).sum(axis=1), (c * c).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = (c[:, 1] * bb - b[:, 1] * cc) / d
        uy = (b[:, 0] * cc - c[:, 0] * bb) / d
    radius = np.hypot(ux, uy)
    return np.column_stack([a[:, 0] + ux, a[:, 1] + uy]), radius


def empty_outside(centres: np.ndarray, radius: np.ndarray, rect: np.ndarray,
                  bounds: tuple[float, float, float, float], outer: Any) -> np.ndarray:
    """(T,) bool: the open disc holds no point of the cloud outside the closed ``rect``
    (xmin, ymin, xmax, ymax); the cloud lies within ``bounds`` and the polygon ``outer`` (its
    convex hull minus ``rect``; None or empty: nothing outside)."""
    r = radius * (1.0 + MARGIN) + MARGIN * (np.abs(centres).max(axis=1) + 1.0)
    ok = np.isfinite(r)
    cx, cy = centres[:, 0], centres[:, 1]
    if rect[0] > bounds[0]:
        ok &= cx - r >= rect[0]
    if rect[1] > bounds[1]:
        ok &= cy - r >= rect[1]
    if rect[2] < bounds[2]:
        ok &= cx + r <= rect[2]
    if rect[3] < bounds[3]:
        ok &= cy + r <= rect[3]
    if outer is None or outer.is_empty:  # the bucket is the whole cloud
        return np.ones(len(r), dtype=bool)
    retry = np.flatnonzero(~ok & np.isfinite(r))
    if len(retry):
        import shapely

        far = shapely.distance(shapely.points(centres[retry]), outer) >= r[retry]
        ok[retry[far]] = True
    return ok


#: the band along the hull's edge whose points a redone tile's bucket gets (in buckets of the
#: count raster), within RIM_REACH times the tile's reach of its rectangle
RIM_BUCKETS = 2
RIM_REACH = 4.0


def hull_rim(scan: Any, hull: Any, cloud: tuple, rule: str, width: int, cap: int
             ) -> tuple[Any, np.ndarray | None]:
    """(the hull shrunk by ``width`` buckets, the kept points not inside it: its rim, duplicate
    XY merged by ``rule``), one pass over the cloud; (None, None) when the shrunk hull is empty
    or the rim would hold more than ``cap`` points."""
    import shapely

    from toolbox.io.pointcloud import iter_xyz
    from toolbox.terrain.gridding.stream import merge_exact_xy

    inner = hull.buffer(-width * scan.size)
    if inner.is_empty:
        return None, None
    shapely.prepare(inner)
    ref, flt, z_field, chunk = cloud
    parts, held = [], 0
    for xyz in iter_xyz(ref, flt, z_field, "INPUT", chunk):
        part = xyz[~shapely.contains_xy(inner, xyz[:, 0], xyz[:, 1])]
        held += len(part)
        if held > cap:
            return None, None
        parts.append(part)
    rim = np.concatenate(parts) if parts else np.zeros((0, 3))
    if len(rim):
        rim = merge_exact_xy(rim, rule)[0]
    return inner, rim


def rim_bucket(xyz: np.ndarray, rect: np.ndarray, hull: Any, inner: Any, rim: np.ndarray,
               grow: float) -> tuple[np.ndarray, Any]:
    """(the bucket ``xyz`` of the closed ``rect`` with the ``rim`` points outside it and
    within ``rect`` grown by ``grow``, the polygon where the cloud's other points may lie:
    the hull shrunk to ``inner`` outside ``rect``, and the hull outside the grown rect)."""
    from shapely.geometry import box

    wide = np.asarray(rect, dtype=np.float64) + (-grow, -grow, grow, grow)
    x, y = rim[:, 0], rim[:, 1]
    inside = (x >= rect[0]) & (x <= rect[2]) & (y >= rect[1]) & (y <= rect[3])
    near = (x >= wide[0]) & (x <= wide[2]) & (y >= wide[1]) & (y <= wide[3])
    outer = inner.difference(box(*rect)).union(hull.difference(box(*wide)))
    return np.vstack([xyz, rim[near & ~inside]]), outer


#: Shewchuk's error bound of a 2D orientation determinant evaluated in floating point
_ORIENT_BOUND = (3.0 + 16.0 * 2.0 ** -53) * 2.0 ** -53


def supports_hull(a: np.ndarray, b: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """(E,) bool: the line through ``a[e]`` and ``b[e]`` ((E, 2), distinct points of the cloud)
    leaves every vertex of the convex ``ring`` ((R, 2)) on one closed side, so the segment
    lies on the hull's boundary. Exact signs: the floating-point orientation where its error
    bound decides it, rational arithmetic where not (points on the line)."""
    from fractions import Fraction

    if not len(a) or not len(ring):
        return np.zeros(len(a), dtype=bool)
    left = (a[:, None, 0] - ring[None, :, 0]) * (b[:, None, 1] - ring[None, :, 1])
    right = (a[:, None, 1] - ring[None, :, 1]) * (b[:, None, 0] - ring[None, :, 0])
    det = left - right
    sign = np.sign(det)
    unsure = np.abs(det) <= _ORIENT_BOUND * (np.abs(left) + np.abs(right))
    for e, v in zip(*np.nonzero(unsure), strict=True):
        ax, ay, bx, by = (Fraction(float(c)) for c in (*a[e], *b[e]))
        vx, vy = Fraction(float(ring[v, 0])), Fraction(float(ring[v, 1]))
        exact = (ax - vx) * (by - vy) - (ay - vy) * (bx - vx)
        sign[e, v] = (exact > 0) - (exact < 0)
    return ~((sign > 0).any(axis=1) & (sign < 0).any(axis=1))


def tile_values(xyz: np.ndarray, origin: tuple[float, float], tile: Any, mask: np.ndarray,
                rect: np.ndarray, bounds: tuple, hull_ring: np.ndarray, outer: Any,
                max_distance: float) -> np.ndarray | None:
    """Cells of ``tile`` (NaN: outside the TIN, MASK or MAX_DISTANCE) from its bucket ``xyz``
    (map XY, distinct), or None when a computed cell needs a larger bucket (see the module).
    ``rect``, ``bounds``, ``hull_ring`` and ``outer`` in map coordinates."""
    from toolbox.terrain.gridding.masks import hull_mask
    from toolbox.terrain.tin.kernels import rasterize_tin, triangulate

    t = tile.core_transform
    h, w = tile.shape
    x0, y0, cx, cy = t.c, t.f, t.a, -t.e
    try:
        triangles = triangulate(xyz[:, :2]) if len(xyz) >= 3 else np.zeros((0, 3), np.int32)
    except ValueError:  # collinear bucket: no triangle
        triangles = np.zeros((0, 3), dtype=np.int32)
    if len(triangles):  # the triangles whose box meets the tile's cells
        tx, ty = xyz[triangles, 0], xyz[triangles, 1]
        near = (tx.max(axis=1) >= x0) & (tx.min(axis=1) <= x0 + w * cx) \
            & (ty.max(axis=1) >= y0 - h * cy) & (ty.min(axis=1) <= y0)
        triangles = triangles[near]
    centres, radius = circumcircles(xyz[:, :2], triangles)
    good = empty_outside(centres, radius, rect, bounds, outer)
    local = np.array(xyz, dtype="float64")
    local[:, 0] -= origin[0]
    local[:, 1] -= origin[1]
    args = (x0 - origin[0], y0 - origin[1], cx, cy, w, h)
    far = max(abs(x0), abs(y0))
    values = rasterize_tin(local, triangles[good], *args, magnitude=far)
    hole = mask & np.isnan(values)
    if hole.any():
        bad = ~np.isnan(rasterize_tin(local, triangles[~good], *args, magnitude=far)) \
            if (~good).any() \
            else np.zeros_like(hole)
        xs, ys = tile.cell_centres(halo=False)
        if (hole & (bad | hull_mask(hull_ring, xs, ys))).any():
            return None
    values[~mask] = np.nan
    if math.isfinite(max_distance) and len(local):
        from toolbox.terrain.gridding.idw_kernel import nearest_grid

        xs, ys = tile.cell_centres(origin, halo=False)
        far = np.isnan(nearest_grid(np.ascontiguousarray(local), xs, ys, ~np.isnan(values),
                                    max_distance))
        values[far] = np.nan
    return values


def grid_tin_streamed(method: Any, request: Any, feedback: Any,
                      chunk_points: int | None = None,
                      cross_validate: Any = None) -> dict[str, Any]:
    """:func:`~toolbox.terrain.gridding.stream.grid_dem_streamed` for tin_linear
    (``cross_validate``: :func:`toolbox.terrain.gridding.stream_quality.stream_quality` for
    QUALITY)."""
    from toolbox.terrain.gridding.stream import grid_dem_streamed

    return grid_dem_streamed(method, request, feedback, chunk_points, planner=plan_tin,
                             cross_validate=cross_validate)


def plan_tin(run: Any, scan: Any, cloud: tuple, options: dict[str, Any], folder: Path,
             merged: Any, feedback: Any) -> tuple[Any, Any, dict[str, Any]]:
    """Compute every tile of a streamed tin_linear run into ``folder`` (see the module).
    ``cloud`` = (ref, filter, z_field, chunk points). Returns (the tiles' TilePlan reading
    them back, the final TileBoxes, STATISTICS of the streaming)."""
    import shapely
    from shapely.geometry import Polygon, box

    from toolbox.terrain.gridding import stream
    from toolbox.terrain.gridding.methods.base import TilePlan
    from toolbox.terrain.gridding.stream import Merged, _merge, count_table, plan_boxes, spill

    ref, flt, z_field, chunk = cloud
    max_distance = float(options["max_distance"])
    floor = max_distance * (1.0 + MARGIN) if math.isfinite(max_distance) else 0.0
    boxes = plan_boxes(run.grid, run.tile, scan, TIN_NEIGHBOURS, math.inf, floor)
    run.tile = boxes.tile
    hull = Polygon(scan.ring) if len(scan.ring) >= 3 else None
    todo = list(range(len(boxes.tiles)))
    done = np.zeros(len(boxes.tiles), dtype=bool)
    passes, spilled, bucket_max, retried = 0, 0, 0, 0
    inner, rim = None, None  # the hull's rim (hull_rim), read once a tile is redone
    reach = boxes.reach.copy()
    table = count_table(scan.counts)
    cap = stream.TILE_POINTS
    while todo:
        feedback.check_canceled()
        live = np.full(len(reach), -np.inf)  # empty rectangles for the tiles already done
        live[todo] = reach[todo]
        current = replace(boxes, reach=live)
        bucket = folder / f"pass{passes}"
        bucket.mkdir()
        with feedback.timed("spill"):
            written = spill(ref, flt, z_field, chunk, current, bucket)
        passes += 1
        spilled += int(written.sum())
        bucket_max = max(bucket_max, int(written.max()))
        again = []
        for i in todo:
            tile = boxes.tiles[i]
            path = bucket / f"{i}.xyz"
            xyz = np.fromfile(path, dtype=np.float64).reshape(-1, 3) if path.exists() \
                else np.zeros((0, 3))
            path.unlink(missing_ok=True)
            xs, ys = tile.cell_centres(run.origin, halo=False)
            mask = run.cell_mask(tile, xs, ys)
            if not mask.any():
                done[i] = True
                continue
            mine = Merged(merged.report.rule)
            if len(xyz):
                xyz = _merge(xyz, boxes, i, mine)
            rect = current.rects[i]
            outer = None if hull is None else hull.difference(box(*rect))
            if rim is not None and len(rim) and not shapely.is_empty(outer):
                xyz, outer = rim_bucket(xyz, rect, hull, inner, rim, RIM_REACH * reach[i])
            values = tile_values(xyz, run.origin, tile, mask, rect, scan.bounds, scan.ring,
                                 outer, max_distance)
            if values is None:
                if outer is None or shapely.is_empty(outer):
                    raise InputDataError(f"streamed dem:tin_linear: tile {i} is not covered "
                                         "by the TIN of every point (internal)")
                again.append(i)
                continue
            merged.add(mine.report)
            values.astype(np.float64).tofile(folder / f"{i}.tin")
            done[i] = True
            feedback.set_progress(5 + 60 * done.mean())
        retried += len(again)
        reach[again] *= 2.0
        for i in again:
            check_growth(scan, table, boxes, i, reach[i], cap)
        if again and hull is not None and rim is None and _near_rim(
                hull, scan.size, boxes.boxes[again], reach[again]):  # they get the rim
            inner, rim = hull_rim(scan, hull, cloud, merged.report.rule, RIM_BUCKETS, cap)
            rim = np.zeros((0, 3)) if rim is None else rim
        todo = again
        bucket.rmdir()

    def plan(tile) -> dict | None:
        path = folder / f"{tile.index}.tin"
        if not path.exists():
            return None
        values = np.fromfile(path, dtype=np.float64).reshape(tile.shape)
        path.unlink()
        return {"values": values}

    info = {"tile_size": boxes.tile, "tiles": len(boxes.tiles), "passes": passes,
            "tiles_retried": retried, "bucket_points_max": bucket_max,
            "rim_points": None if rim is None else len(rim),
            "points_spilled": spilled, "reach_max": float(reach.max()),
            "count_raster": list(scan.counts.shape), "bucket_size": scan.size}
    return TilePlan(plan, stored_tile), boxes, info


def _near_rim(hull: Any, size: float, tile_boxes: np.ndarray, reach: np.ndarray) -> bool:
    """Whether a redone tile's box grown by (1 + RIM_REACH) reaches meets the hull's rim."""
    import shapely

    band = hull.difference(hull.buffer(-RIM_BUCKETS * size))
    grow = (1.0 + RIM_REACH) * reach[:, None]
    wide = shapely.box(*(tile_boxes + np.hstack([-grow, -grow, grow, grow])).T)
    return bool(shapely.intersects(wide, band).any())


def check_growth(scan: Any, table: np.ndarray, boxes: Any, i: int, h: float, cap: int) -> None:
    """:class:`InputDataError` when tile ``i``'s box grown by the doubled reach ``h`` would
    hold more than ``cap`` (TILE_POINTS) points, or more than its first bucket when that was
    already larger (the smallest tiles of a dense cloud): the buckets of a streamed run stay
    bounded whatever the cloud (points on a circle or a line, a dense cluster among far sparse
    points: Delaunay triangles with circumcircles over most of the cloud)."""
    from toolbox.terrain.gridding.stream import count_within

    estimate = count_within(scan, table, boxes.boxes[i], h)
    limit = max(cap, int(boxes.estimate[i]))
    if estimate > limit:
        from toolbox.terrain.gridding.stream import TIN_MEMORY_BYTES

        raise InputDataError(
            f"streamed dem:tin_linear: tile {i}'s Delaunay triangles have circumcircles wider "
            f"than its bucket; grown by {h:.3f} it would hold about {estimate:,} points, over "
            f"the {limit:,} a tile's bucket may hold (the cloud is far from even: points on a "
            "line or a circle, or dense clusters among far sparse points); grid it in memory "
            f"by raising TOOLBOX_STREAM_POINTS above {scan.kept:,} (about "
            f"{scan.kept * TIN_MEMORY_BYTES / 1e9:.1f} GB), or thin or split the cloud")


def stored_tile(tile: Any, arrays: dict) -> np.ndarray:
    """Kernel of the write: the tile computed by :func:`plan_tin`."""
    return arrays["values"]
