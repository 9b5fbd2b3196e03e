"""Gridding a LAS/LAZ point cloud too large to hold: two streamed passes and per-tile buckets
spilled to disk; the same tiles, kernels and cell values as the in-memory path.

    pass 1 (scan)   read the cloud by chunks: points kept, exact bounds, convex hull, a count
                    raster of the kept points on square buckets over the header's bounds
    plan            the output grid and its tiles; per tile the reach ``h`` within which every
                    computed cell finds its k nearest points, bounded from the count raster
                    (tiles are halved while the densest one would hold over TILE_POINTS)
    pass 2 (spill)  read the cloud again by chunks; every point is appended (file order) to
                    the bucket file of each tile whose box grown by its ``h`` holds it
    tiles           per tile: its bucket is loaded, duplicate XY merged (DUPLICATES rule; a
                    position's points are all in the same buckets), the reach checked against
                    the bucket's own k-th distances, and the method's kernel runs as in memory

Exact: a cell's k nearest points all lie within ``h`` of it, so its bucket holds them, and the
kernel computes the cell from the same points in the same local origin. Streams: nearest,
idw (with SECTORS: every point within RADIUS), plane, quadratic, cubic; tin_linear by its own
tiles (:mod:`toolbox.terrain.gridding.stream_tin`: each bucket's Delaunay triangles whose
circumcircle the bucket holds). QUALITY (leave-one-out) by one more pass, tile by tile
(:mod:`toolbox.terrain.gridding.stream_quality`), for every method. Not: LINES / BREAKLINES,
DUPLICATE_TOLERANCE > 0.

Memory: one chunk (CHUNK_POINTS records, about 100 MB at 1 M), the count raster (8 bytes a
bucket, at most about 1 M buckets) and the hull, then per tile in flight its bucket and the
kernel's bins (at most TILE_POINTS points, about 100 bytes each): independent of the cloud's
size. Disk: 24 bytes a kept point (times the halo overlap) in a temporary folder, freed tile by
tile.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.terrain.gridding.request import GriddingRequest
from toolbox.terrain.points import DuplicateReport

#: point clouds whose header counts more points than this are gridded by streaming
#: (environment TOOLBOX_STREAM_POINTS overrides)
STREAM_POINTS = 10_000_000
#: a tile's bucket holds at most about this many points: denser tiles are halved
TILE_POINTS = 3_000_000
MIN_TILE = 64
#: the count raster has at most about this many buckets
MAX_BUCKETS = 1_000_000
STREAMING_METHODS = ("nearest", "idw", "plane", "quadratic", "cubic", "tin_linear")
#: measured by bench/surface_bench.py: dem:nearest (dem:tin_linear) in memory, bytes a kept point
IN_MEMORY_BYTES = 190
TIN_MEMORY_BYTES = 250


def stream_threshold() -> int:
    """Points above which a point cloud INPUT is streamed (TOOLBOX_STREAM_POINTS)."""
    value = os.environ.get("TOOLBOX_STREAM_POINTS")
    return int(value) if value else STREAM_POINTS


def wants_stream(request: GriddingRequest) -> bool:
    """True when the run's INPUT is a point cloud over :func:`stream_threshold` points."""
    from toolbox.io.pointcloud import PointCloudRef

    points = request.sources.points
    return isinstance(points, PointCloudRef) and points.point_count > stream_threshold()


def check_streamable(method: Any, request: GriddingRequest) -> None:
    """:class:`ParameterError` naming what keeps a run from streaming, with the numbers."""
    sources, n = request.sources, request.sources.points.point_count
    per_point = TIN_MEMORY_BYTES if method.name == "tin_linear" else IN_MEMORY_BYTES
    held = f"{n:,} points of INPUT would need about {n * per_point / 1e9:.1f} GB in memory"
    limit = f"above TOOLBOX_STREAM_POINTS = {stream_threshold():,} points"
    if method.name not in STREAMING_METHODS:
        raise ParameterError("INPUT", f"dem:{method.name} holds every point: the {held}; "
                             f"{limit} only dem:"
                             f"{', dem:'.join(STREAMING_METHODS)} grid a point cloud by "
                             "streaming (raise TOOLBOX_STREAM_POINTS if the memory is there)")
    for name, value in (("LINES", sources.lines), ("BREAKLINES", sources.breaklines)):
        if value is not None:
            raise ParameterError(name, f"cannot be combined with a point cloud INPUT {limit} "
                                 f"(it is gridded by streaming, points only): the {held}")
    if sources.duplicate_tolerance:
        raise ParameterError("DUPLICATE_TOLERANCE", f"must be 0 for a point cloud INPUT {limit}"
                             f" (streamed gridding merges identical XY only), got "
                             f"{sources.duplicate_tolerance}")


# -- pass 1 ---------------------------------------------------------------------------------------
@dataclass
class CloudScan:
    """What pass 1 learnt: kept points, exact XY bounds, hull candidates (map XY), the count
    raster of kept points on square buckets of side ``size`` (row 0 at the south edge ``y0``)."""

    kept: int
    bounds: tuple[float, float, float, float]
    ring: np.ndarray
    counts: np.ndarray
    x0: float
    y0: float
    size: float
    report: Any


def bucket_raster(bounds: tuple[float, float, float, float], points: int
                  ) -> tuple[float, float, float, int, int]:
    """(x0, y0, size, nx, ny) of a square-bucket raster over ``bounds`` with one bucket of
    margin on every side and about one bucket per 16 ``points``, at most about
    :data:`MAX_BUCKETS`."""
    wide, high = bounds[2] - bounds[0], bounds[3] - bounds[1]
    span = max(wide, high, 1e-9)
    buckets = min(MAX_BUCKETS, max(16, points // 16))
    area = max(wide * high, span * span / buckets)
    size = max(math.sqrt(area / buckets), span / max(1.0, math.sqrt(MAX_BUCKETS) - 2.0))
    nx = int(math.ceil((bounds[2] - bounds[0]) / size)) + 2
    ny = int(math.ceil((bounds[3] - bounds[1]) / size)) + 2
    return bounds[0] - size, bounds[1] - size, size, nx, ny


def scan_cloud(ref: Any, flt: Any, z_field: str | None, chunk_points: int,
               name: str = "INPUT") -> CloudScan:
    """Pass 1 over the cloud (never more than one chunk held). The buckets cover the header's
    bounds; when points lie outside them (a header not updated after an edit) the kept points'
    own bounds are read in one more pass and the scan is redone over them."""
    from toolbox.io.pointcloud import iter_xyz

    try:
        return _scan(ref, flt, z_field, chunk_points, name, ref.bounds)
    except _OutsideHeader:
        pass
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for xyz in iter_xyz(ref, flt, z_field, name, chunk_points):
        lo = np.minimum(lo, xyz[:, :2].min(axis=0))
        hi = np.maximum(hi, xyz[:, :2].max(axis=0))
    bounds = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    return _scan(ref, flt, z_field, chunk_points, name, bounds)


class _OutsideHeader(Exception):
    """A point of the cloud lies outside the bounds its header states."""


def _scan(ref: Any, flt: Any, z_field: str | None, chunk_points: int, name: str,
          bounds: tuple[float, float, float, float]) -> CloudScan:
    from toolbox.io.pointcloud import ReadReport, iter_xyz, warn_noise_classes
    from toolbox.terrain.gridding.inputs import check_heights_fit
    from toolbox.terrain.gridding.masks import convex_hull

    x0, y0, size, nx, ny = bucket_raster(bounds, ref.point_count)
    counts = np.zeros(ny * nx, dtype=np.int64)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    ring = np.zeros((0, 2))
    report = ReadReport(0, 0, {}, flt.describe())
    for xyz in iter_xyz(ref, flt, z_field, name, chunk_points, report):
        check_heights_fit(xyz[:, 2], name)
        ix = np.floor((xyz[:, 0] - x0) / size).astype(np.int64)
        iy = np.floor((xyz[:, 1] - y0) / size).astype(np.int64)
        if ix.min() < 0 or iy.min() < 0 or ix.max() >= nx or iy.max() >= ny:
            raise _OutsideHeader
        counts += np.bincount(iy * nx + ix, minlength=ny * nx)
        lo = np.minimum(lo, xyz[:, :2].min(axis=0))
        hi = np.maximum(hi, xyz[:, :2].max(axis=0))
        candidates = np.vstack([ring, xyz[:, :2]])
        hull = convex_hull(candidates)
        if hull is None:  # collinear so far: the two ends of the line keep it
            ends = [candidates[:, 0].argmin(), candidates[:, 0].argmax(),
                    candidates[:, 1].argmin(), candidates[:, 1].argmax()]
            hull = candidates[np.unique(ends)]
        ring = hull
    warn_noise_classes(report, flt, ref, name)
    return CloudScan(report.kept, (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])),
                     ring, counts.reshape(ny, nx), x0, y0, size, report)


def knn_reach(counts: np.ndarray, k: int, size: float) -> np.ndarray:
    """Per bucket, a distance within which every point of the bucket has ``k`` counted points:
    ``(r + 1)·size·√2`` for the smallest square block of (2r + 1)² buckets around it holding
    ``k``; inf when the whole raster holds fewer."""
    ny, nx = counts.shape
    table = np.zeros((ny + 1, nx + 1), dtype=np.int64)
    table[1:, 1:] = counts.cumsum(axis=0).cumsum(axis=1)
    reach = np.full(ny * nx, np.inf)
    todo = np.arange(ny * nx)
    iy, ix = np.divmod(todo, nx)
    for r in range(max(ny, nx)):
        ya, yb = np.maximum(iy - r, 0), np.minimum(iy + r + 1, ny)
        xa, xb = np.maximum(ix - r, 0), np.minimum(ix + r + 1, nx)
        held = table[yb, xb] - table[ya, xb] - table[yb, xa] + table[ya, xa]
        ok = held >= max(k, 1)
        reach[todo[ok]] = (r + 1) * size * math.sqrt(2.0)
        todo, iy, ix = todo[~ok], iy[~ok], ix[~ok]
        if len(todo) == 0:
            break
    return reach.reshape(ny, nx)


# -- the tiles' reach ---------------------------------------------------------------------------
@dataclass
class TileBoxes:
    """Per tile (engine order): the box of its cell centres (map units) and its reach ``h``."""

    tile: int
    boxes: np.ndarray  # (n, 4) xmin, ymin, xmax, ymax
    reach: np.ndarray  # (n,)
    estimate: np.ndarray  # (n,) points counted in each grown box (an upper bound)
    tiles: list = field(default_factory=list)

    @property
    def rects(self) -> np.ndarray:
        h = self.reach[:, None]
        return self.boxes + np.hstack([-h, -h, h, h])


def tile_boxes(grid: Any, tile: int, scan: CloudScan, reach: np.ndarray,
               radius: float, floor: float = 0.0) -> TileBoxes:
    """The boxes and reaches of the tiles of ``grid``; ``reach`` from :func:`knn_reach` (None:
    every point within ``radius``)."""
    from toolbox.raster.tile import iter_tiles

    table = count_table(scan.counts)
    tiles = list(iter_tiles(grid, tile))
    boxes, reaches, estimate = [], [], []
    for t in tiles:
        xs, ys = t.cell_centres(halo=False)
        box = (float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max()))
        h = max(radius if reach is None else box_reach(box, scan, reach, radius), floor)
        boxes.append(box)
        reaches.append(h)
        estimate.append(count_within(scan, table, box, h))
    return TileBoxes(tile, np.array(boxes), np.array(reaches), np.array(estimate), tiles)


def count_table(counts: np.ndarray) -> np.ndarray:
    """The summed-area table of a count raster (one row and column of zeros first)."""
    ny, nx = counts.shape
    table = np.zeros((ny + 1, nx + 1), dtype=np.int64)
    table[1:, 1:] = counts.cumsum(axis=0).cumsum(axis=1)
    return table


def count_within(scan: CloudScan, table: np.ndarray, box: Any, h: float) -> int:
    """Kept points counted in the buckets that meet ``box`` grown by ``h`` (an upper bound of
    the points in the grown box); every kept point when ``h`` is infinite."""
    if not math.isfinite(h):
        return scan.kept
    ny, nx = scan.counts.shape
    a0 = _index(box[0] - h, scan.x0, scan.size, nx)
    a1 = _index(box[2] + h, scan.x0, scan.size, nx) + 1
    b0 = _index(box[1] - h, scan.y0, scan.size, ny)
    b1 = _index(box[3] + h, scan.y0, scan.size, ny) + 1
    return int(table[b1, a1] - table[b0, a1] - table[b1, a0] + table[b0, a0])


def box_reach(box: Any, scan: CloudScan, reach: np.ndarray, radius: float,
              offset: tuple[int, int] = (0, 0)) -> float:
    """A distance within which every point of ``box`` (xmin, ymin, xmax, ymax) has its k
    nearest points (``reach`` per bucket of ``scan``'s raster, from :func:`knn_reach`; or of
    a window of it starting at bucket row, column ``offset``), at most ``radius``.
    1-Lipschitz: d_k(p) <= d_k(q) + |p - q|, q = p clipped to the raster."""
    ny, nx = scan.counts.shape
    gx1, gy1 = scan.x0 + nx * scan.size, scan.y0 + ny * scan.size
    cx0, cx1 = np.clip([box[0], box[2]], scan.x0, gx1)
    cy0, cy1 = np.clip([box[1], box[3]], scan.y0, gy1)
    outside = math.hypot(max(cx0 - box[0], box[2] - cx1), max(cy0 - box[1], box[3] - cy1))
    i0, i1 = _index(cx0, scan.x0, scan.size, nx), _index(cx1, scan.x0, scan.size, nx)
    j0, j1 = _index(cy0, scan.y0, scan.size, ny), _index(cy1, scan.y0, scan.size, ny)
    r0, c0 = offset
    block = reach[max(j0 - r0, 0):j1 - r0 + 1, max(i0 - c0, 0):i1 - c0 + 1]
    return min(float(block.max()) + outside, radius) if block.size else radius


def _index(value: float, origin: float, size: float, n: int) -> int:
    return int(min(max(math.floor((value - origin) / size), 0), n - 1))


def plan_boxes(grid: Any, tile: int, scan: CloudScan, k: int, radius: float,
               floor: float = 0.0) -> TileBoxes:
    """Tile boxes whose reach counts k + max(1, k // 4) points (the margin keeps the reach
    valid when up to a quarter of the points share their XY with another), the tile side
    halved (multiples of 16, down to :data:`MIN_TILE`) while
    the densest grown box would hold more than :data:`TILE_POINTS` points. ``floor``: the
    smallest reach (tin_linear's MAX_DISTANCE)."""
    reach = None if k == 0 else knn_reach(scan.counts, k + max(1, k // 4), scan.size)
    while True:
        boxes = tile_boxes(grid, tile, scan, reach, radius, floor)
        if boxes.estimate.max() <= TILE_POINTS or tile <= MIN_TILE:
            return boxes
        tile = max(MIN_TILE, (tile // 2) // 16 * 16)


# -- pass 2 ---------------------------------------------------------------------------------------
def spill(ref: Any, flt: Any, z_field: str | None, chunk_points: int, boxes: TileBoxes,
          folder: Path, name: str = "INPUT", step: tuple[float, float] | None = None,
          index: bool = False) -> np.ndarray:
    """Pass 2: append each kept point (x, y, z float64, file order) to the bucket file
    ``folder/<tile>.xyz`` of every tile whose grown box holds it. Returns points per bucket.
    ``step``: the tiles' width and height (default: the grid tiles'); ``index``: a fourth
    column, the point's rank among the kept points (file order, from 0)."""
    from toolbox.io.pointcloud import iter_xyz

    rects = boxes.rects
    n = len(rects)
    written = np.zeros(n, dtype=np.int64)
    # a point can only be in the grown box of a tile near the one its XY falls in
    col0 = np.unique(boxes.boxes[:, 0])
    row0 = np.unique(boxes.boxes[:, 3])[::-1]
    ncols, nrows = len(col0), len(row0)
    if step is None:
        t = boxes.tiles[0].grid_transform
        width, height = boxes.tile * abs(t.a), boxes.tile * abs(t.e)
    else:
        width, height = step
    reach = boxes.reach.max()
    # home tile i (first cell centres col0[i] <= x < col0[i + 1]) and a tile j whose box grown
    # by h holds x: |i - j| <= floor(h / tile width) + 1
    reach_x = ncols if not math.isfinite(reach) else int(math.floor(reach / width)) + 1
    reach_y = nrows if not math.isfinite(reach) else int(math.floor(reach / height)) + 1
    seen = 0
    for xyz in iter_xyz(ref, flt, z_field, name, chunk_points):
        if index:
            xyz = np.column_stack([xyz, np.arange(seen, seen + len(xyz), dtype=np.float64)])
            seen += len(xyz)
        home_c = np.clip(np.searchsorted(col0, xyz[:, 0], side="right") - 1, 0, ncols - 1)
        home_r = np.clip(np.searchsorted(-row0, -xyz[:, 1], side="right") - 1, 0, nrows - 1)
        ids, idx = [], []
        for dr in range(-min(reach_y, nrows), min(reach_y, nrows) + 1):
            r = home_r + dr
            for dc in range(-min(reach_x, ncols), min(reach_x, ncols) + 1):
                c = home_c + dc
                ok = (r >= 0) & (r < nrows) & (c >= 0) & (c < ncols)
                t = np.where(ok, r * ncols + c, 0)
                rect = rects[t]
                ok &= (xyz[:, 0] >= rect[:, 0]) & (xyz[:, 0] <= rect[:, 2]) \
                    & (xyz[:, 1] >= rect[:, 1]) & (xyz[:, 1] <= rect[:, 3])
                hit = np.flatnonzero(ok)
                ids.append(t[hit])
                idx.append(hit)
        ids, idx = np.concatenate(ids), np.concatenate(idx)
        order = np.lexsort((idx, ids))  # by tile, then file order
        ids, idx = ids[order], idx[order]
        cuts = np.flatnonzero(np.diff(ids)) + 1
        for part in np.split(np.arange(len(ids)), cuts):
            if len(part) == 0:
                continue
            t = int(ids[part[0]])
            with open(folder / f"{t}.xyz", "ab") as fh:
                fh.write(np.ascontiguousarray(xyz[idx[part]]).tobytes())
            written[t] += len(part)
    return written


# -- the run --------------------------------------------------------------------------------------
@dataclass
class StreamData:
    """The stand-in of :class:`~toolbox.terrain.gridding.inputs.GriddingData` for
    :func:`~toolbox.terrain.gridding.grid.prepare_grid`: the hull candidates as its points
    (their bounds are the cloud's; the hull is the cloud's)."""

    xyz: np.ndarray
    origin: np.ndarray
    crs: Any
    counts: dict
    duplicates: DuplicateReport
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))

    @property
    def local(self) -> np.ndarray:
        out = np.array(self.xyz, dtype="float64")
        out[:, :2] -= self.origin
        return out

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        lo, hi = self.xyz[:, :2].min(axis=0), self.xyz[:, :2].max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def grid_dem_streamed(method: Any, request: GriddingRequest, feedback: Feedback,
                      chunk_points: int | None = None, planner: Any = None,
                      cross_validate: Any = None) -> dict[str, Any]:
    """Grid ``request`` (a point cloud INPUT) with ``method`` by streaming (see the module);
    writes ``request.output`` and returns the STATISTICS, as
    :func:`~toolbox.terrain.gridding.run.grid_dem`. ``planner``: computes the tiles itself
    (:func:`toolbox.terrain.gridding.stream_tin.plan_tin`; tin_linear needs it).
    ``cross_validate``: the QUALITY report of the run (QUALITY needs it:
    :func:`toolbox.terrain.gridding.stream_quality.stream_quality`)."""
    from toolbox.io.crs import common_crs
    from toolbox.io.pointcloud import CHUNK_POINTS, cloud_filter
    from toolbox.terrain.gridding.grid import prepare_grid
    from toolbox.terrain.gridding.methods.base import TilePlan
    from toolbox.terrain.gridding.run import grid_statistics, jsonable_options, other_crs, write_dem
    from toolbox.terrain.points import local_origin

    check_streamable(method, request)
    if planner is None and not hasattr(method, "halo_neighbours"):
        raise TypeError(f"dem:{method.name} streams through its own planner: "
                        "toolbox.terrain.gridding.stream_tin.grid_tin_streamed")
    if request.quality is not None and cross_validate is None:
        raise TypeError("a streamed QUALITY is computed by "
                        "toolbox.terrain.gridding.stream_quality.stream_quality: pass it as "
                        "cross_validate")
    sources = request.sources
    ref, chunk = sources.points, int(chunk_points or CHUNK_POINTS)
    flt = cloud_filter(ref, sources.classes, sources.returns, sources.crs)
    crs = common_crs({"INPUT": ref.crs} | {k: v for k, v in other_crs(request).items()
                                           if v is not None}, sources.crs)
    with feedback.timed("scan"):
        scan = scan_cloud(ref, flt, sources.z_field, chunk)
    feedback.set_progress(2)
    if scan.kept < method.min_points:
        raise InputDataError(f"dem:{method.name} needs at least {method.min_points} data "
                             f"points, got {scan.kept}")
    ring = np.column_stack([scan.ring, np.zeros(len(scan.ring))])
    origin = local_origin(ring)
    data = StreamData(ring, origin, crs, {"points": scan.kept,
                                          "point_cloud": scan.report.as_dict()},
                      DuplicateReport(0, 0, 0.0, sources.duplicates or "mean"))
    run = prepare_grid(request, data, limit_to_hull=method.limits_to_hull)
    options = method.options(request.method)
    merged = Merged(sources.duplicates or "mean")
    with tempfile.TemporaryDirectory(prefix="toolbox-stream-") as tmp:
        folder = Path(tmp)
        if planner is not None:  # tin_linear: its own tiles (stream_tin.grid_tin_streamed)
            tiles, boxes, streamed = planner(run, scan, (ref, flt, sources.z_field, chunk),
                                             options, folder, merged, feedback)
            start = 65
        else:
            k, radius = method.halo_neighbours(options)
            radius = math.inf if radius is None else float(radius)
            boxes = plan_boxes(run.grid, run.tile, scan, k, radius)
            run.tile = boxes.tile
            with feedback.timed("spill"):
                written = spill(ref, flt, sources.z_field, chunk, boxes, folder)
            streamed = {"tile_size": boxes.tile, "tiles": len(boxes.tiles),
                        "bucket_points_max": int(written.max()),
                        "points_spilled": int(written.sum()),
                        "reach_max": float(boxes.reach.max()),
                        "count_raster": list(scan.counts.shape), "bucket_size": scan.size}
            start = 5
            feedback.set_progress(start)
            plan = partial_plan(run, boxes, folder, scan, k, radius, merged)
            tiles = TilePlan(plan, _kernel(method, run.origin, options))
        quality = request.quality is not None
        result = write_dem(run, tiles, request, feedback, start=start, end=90 if quality else 98)
        if quality:
            from toolbox.terrain.gridding.run import write_quality

            with feedback.timed("cross_validation"):
                report = cross_validate(method, scan, (ref, flt, sources.z_field, chunk),
                                        run.origin, options, request.cells.extrapolate,
                                        merged.report.rule, crs, folder, feedback.step(90, 99),
                                        request.execution.workers)
    data.duplicates = merged.report
    stats = grid_statistics(run, request)
    stats["points_used"] = scan.kept - merged.report.removed
    stats["method"] = {"name": method.name, "options": jsonable_options(options),
                       **method.summarise(result.pop("counts"))}
    stats["cells"] = result
    stats["streamed"] = {"chunk_points": chunk, **streamed}
    if quality:
        write_quality(request.quality, report)
        stats["cross_validation"] = report["methods"][method.name]
    return stats


class Merged:
    """Duplicate XY over the tiles, each position counted in the tile its XY falls in."""

    def __init__(self, rule: str):
        self.report = DuplicateReport(0, 0, 0.0, rule)

    def add(self, report: DuplicateReport) -> None:
        self.report = DuplicateReport(self.report.groups + report.groups,
                                      self.report.removed + report.removed,
                                      max(self.report.max_z_spread, report.max_z_spread),
                                      self.report.rule)


def _kernel(method: Any, origin: tuple[float, float], options: dict) -> Any:
    from functools import partial

    return partial(type(method).tile_kernel, origin, dict(options))


def partial_plan(run: Any, boxes: TileBoxes, folder: Path, scan: CloudScan, k: int,
                 radius: float, merged: Merged) -> Any:
    """``plan(tile)`` of the streamed run: the tile's bucket, duplicate XY merged (then the
    reach is checked again on the distinct points), shifted to the run's local origin."""
    ox, oy = run.origin

    def plan(tile) -> dict | None:
        path = folder / f"{tile.index}.xyz"
        xyz = np.fromfile(path, dtype=np.float64).reshape(-1, 3) if path.exists() \
            else np.zeros((0, 3))
        if path.exists():
            path.unlink()
        xs, ys = tile.cell_centres(run.origin, halo=False)
        mask = run.cell_mask(tile, xs, ys)
        if not mask.any() or len(xyz) == 0:
            return None
        merged_xyz = _merge(xyz, boxes, tile.index, merged)
        if len(merged_xyz) < len(xyz) and k > 0:
            need = tile_reach(boxes.boxes[tile.index], boxes.rects[tile.index], scan,
                              merged_xyz, k, radius)
            have = boxes.reach[tile.index]
            if need > have * (1 + 1e-12):
                raise InputDataError(f"streamed gridding: after merging duplicate XY, tile "
                                     f"{tile.index}'s cells may need points {need:.3f} away, "
                                     f"its bucket holds those within {have:.3f}: over a quarter "
                                     "of the points share their XY; raise "
                                     "TOOLBOX_STREAM_POINTS to grid in memory")
        local = merged_xyz
        local[:, 0] -= ox
        local[:, 1] -= oy
        return {"xyz": np.ascontiguousarray(local), "mask": mask}

    return plan


def tile_reach(box: np.ndarray, rect: np.ndarray, scan: CloudScan, xyz: np.ndarray, k: int,
               radius: float) -> float:
    """The reach of a tile's ``box`` computed as in pass 1, from the (distinct) points ``xyz``
    of its bucket alone (every point within ``rect``), counted on the same buckets."""
    ny, nx = scan.counts.shape
    i0, i1 = _index(rect[0], scan.x0, scan.size, nx), _index(rect[2], scan.x0, scan.size, nx)
    j0, j1 = _index(rect[1], scan.y0, scan.size, ny), _index(rect[3], scan.y0, scan.size, ny)
    w, h = i1 - i0 + 1, j1 - j0 + 1
    ix = np.clip(np.floor((xyz[:, 0] - scan.x0) / scan.size).astype(np.int64) - i0, 0, w - 1)
    iy = np.clip(np.floor((xyz[:, 1] - scan.y0) / scan.size).astype(np.int64) - j0, 0, h - 1)
    window = np.bincount(iy * w + ix, minlength=w * h).reshape(h, w)
    return box_reach(box, scan, knn_reach(window, k, scan.size), radius, (j0, i0))


def merge_exact_xy(xyz: np.ndarray, rule: str) -> tuple[np.ndarray, Any, Any]:
    """``(merged, report, kept)`` of :func:`toolbox.terrain.points.merge_duplicate_xy` for the
    points of a bucket with exactly the same XY, merged by ``rule`` (DUPLICATES); ``(xyz, None,
    None)`` when every XY is distinct (a binned check, O(n)). DUPLICATES 'error' with duplicates:
    :class:`InputDataError`."""
    from toolbox.terrain.gridding.neighbours import PointBins
    from toolbox.terrain.points import merge_duplicate_xy

    if not PointBins.build(xyz[:, :2] - xyz[0, :2]).has_duplicates():
        return xyz, None, None
    try:
        return merge_duplicate_xy(xyz, 0.0, rule)
    except ValueError as exc:
        raise InputDataError(f"DUPLICATES is 'error' and {exc}") from None


def _merge(xyz: np.ndarray, boxes: TileBoxes, index: int, merged: Merged) -> np.ndarray:
    """The bucket with duplicate XY merged by ``rule``; the positions whose XY falls in this
    tile's core are counted in ``merged``."""
    out, report, _ = merge_exact_xy(xyz, merged.report.rule)
    if report is None:
        return xyz
    home = _home(xyz, boxes, index)
    if home.any():
        _, report, _ = merge_exact_xy(xyz[home], merged.report.rule)
        if report is not None:
            merged.add(report)
    return out


def _home(xyz: np.ndarray, boxes: TileBoxes, index: int) -> np.ndarray:
    """Points whose XY falls in tile ``index``'s own part of the plane (the tiles' cell
    boundaries; the outer tiles extend to infinity), so that each position is counted once."""
    tile = boxes.tiles[index]
    t = tile.grid_transform
    w = tile.window
    left = t.c + int(w.col_off) * t.a
    right = left + int(w.width) * t.a
    top = t.f + int(w.row_off) * t.e
    bottom = top + int(w.height) * t.e
    first_col, first_row = int(w.col_off) == 0, int(w.row_off) == 0
    last_col = not (boxes.boxes[:, 0] > boxes.boxes[index, 0]).any()
    last_row = not (boxes.boxes[:, 3] < boxes.boxes[index, 3]).any()
    x, y = xyz[:, 0], xyz[:, 1]
    ok = np.ones(len(xyz), dtype=bool)
    if not first_col:
        ok &= x >= left
    if not last_col:
        ok &= x < right
    if not first_row:
        ok &= y <= top
    if not last_row:
        ok &= y > bottom
    return ok
