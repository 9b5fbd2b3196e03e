"""QUALITY (leave-one-out cross-validation) of a streamed gridding run, exactly as in memory
(:func:`toolbox.terrain.gridding.run.quality_report`), one tile of points at a time.

    tiles     square blocks of the count raster of pass 1 (:class:`~toolbox.terrain.gridding.
              stream.CloudScan`); every kept point falls in exactly one bucket of that raster,
              so in exactly one tile: its owner. A tile's reach ``h``: the distance within
              which every point of the block has its k + 1 nearest points (itself and the k
              nearest others; with a quarter more for duplicate XY), from the count raster;
              RADIUS when finite and smaller; RADIUS alone with SECTORS (every point within it)
    spill     one more pass over the cloud: each kept point, with its rank among the kept
              points, to the bucket of every tile whose block grown by ``h`` holds it
    per tile  the bucket's duplicate XY merged (DUPLICATES rule; a position's points are all in
              the same buckets), the reach checked again on the distinct points, then the
              method's leave-one-out kernel (``Method.loo_targets``) at the tile's own points
              with every point of the bucket a neighbour: the k nearest other points of a point
              lie within ``h``, so the bucket holds them and the prediction is the in-memory one
              (the same local origin, the same coordinates, the same kernel)
    summary   errors appended to a file and summed tile by tile (fsum of the tiles' sums), the
              standard deviation by a second pass over that file; the worst point by its
              in-memory index (the rank of its position's first point among the distinct
              positions, file order)

EXTRAPOLATE off: the vertices of the cloud's convex hull (pass 1's ring, the same Qhull hull of
the same points in the same local coordinates) are not predicted, as in memory.

tin_linear (its leave-one-out: the plane of p's triangle in the TIN of all the other points):
removing p changes only p's star, refilled from its ring, so a bucket whose TIN has p's star of
the whole cloud gives p the same triangle. A tile's bucket gets the rim (every point within
RIM_BUCKETS buckets of the hull's edge, one more pass, at most TILE_POINTS, else none) and a
target is settled when its star closes around it and each of its triangles' circumcircles
misses the points the bucket lacks (those of the hull, shrunk by the rim when held, outside the
bucket's rectangle: :func:`~toolbox.terrain.gridding.stream_tin.empty_outside`), or it is a
vertex of the cloud's hull (never predicted). A point on a straight edge of the hull (a survey
grid's or a LiDAR tile's border) has a star open in the whole cloud too: its star may stay open
along edges that lie on the hull's boundary (:func:`~toolbox.terrain.gridding.stream_tin.
supports_hull`); its triangles passing the circle test then cover the hull's straight angle at
it, so they are its whole star. A tile with an unsettled target is spilled again
with its reach doubled (capped as in :func:`~toolbox.terrain.gridding.stream_tin.
check_growth`). The plane is computed from the triangle's lowest vertex in the run's local
coordinates, in memory as here (:func:`~toolbox.terrain.gridding.tin_constrained.tin_loo`): the
same bits. Four or more cocircular points: either diagonal is Delaunay (as in the grid).

Memory: a tile's bucket (at most about TILE_POINTS points, 32 bytes each on disk; tin_linear
also the rim, at most TILE_POINTS points) and the method's bins; the summary keeps a few
numbers and the ranks of the duplicates merged away (8 bytes each). Disk: 32 bytes a kept
point (times the halo overlap) and 8 bytes an error.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

#: the first tile side, in buckets of the count raster (about 16 points each): ~1 M points
FIRST_BLOCK = 256
#: tin_linear: the width of the band along the hull's edge whose points are held, in buckets
RIM_BUCKETS = 2


class QualityTiles:
    """Square blocks of ``block`` x ``block`` buckets of the count raster, row-major from the
    north (the order :func:`~toolbox.terrain.gridding.stream.spill` assumes)."""

    def __init__(self, scan: Any, block: int):
        ny, nx = scan.counts.shape
        self.block, self.scan = block, scan
        self.nrows, self.ncols = -(-ny // block), -(-nx // block)
        boxes = []
        for r in range(self.nrows):
            top = ny - r * block
            bottom = max(top - block, 0)
            for c in range(self.ncols):
                left, right = c * block, min((c + 1) * block, nx)
                boxes.append((scan.x0 + left * scan.size, scan.y0 + bottom * scan.size,
                              scan.x0 + right * scan.size, scan.y0 + top * scan.size))
        self.boxes = np.array(boxes, dtype=np.float64)

    def owner(self, xy: np.ndarray) -> np.ndarray:
        """The tile of each point: the block of its bucket (pass 1's bucket formula)."""
        scan = self.scan
        ny = scan.counts.shape[0]
        ix = np.floor((xy[:, 0] - scan.x0) / scan.size).astype(np.int64)
        iy = np.floor((xy[:, 1] - scan.y0) / scan.size).astype(np.int64)
        return ((ny - 1 - iy) // self.block) * self.ncols + ix // self.block


def plan_quality(scan: Any, k: int, radius: float, tile_points: int) -> tuple[Any, Any]:
    """(QualityTiles, TileBoxes): blocks halved while the densest grown block would hold more
    than ``tile_points`` points. ``k``: neighbours of a prediction (0: every point within
    ``radius``)."""
    from toolbox.terrain.gridding.stream import TileBoxes, box_reach, count_table, count_within, knn_reach

    need = k + 1
    reach = None if k == 0 else knn_reach(scan.counts, need + max(1, need // 4), scan.size)
    table = count_table(scan.counts)
    block = FIRST_BLOCK
    while True:
        tiles = QualityTiles(scan, block)
        reaches = np.array([radius if reach is None else box_reach(b, scan, reach, radius)
                            for b in tiles.boxes])
        estimate = np.array([count_within(scan, table, b, h)
                             for b, h in zip(tiles.boxes, reaches, strict=True)])
        if estimate.max() <= tile_points or block == 1:
            return tiles, TileBoxes(block, tiles.boxes, reaches, estimate)
        block = max(1, block // 2)


def stream_quality(method: Any, scan: Any, cloud: tuple, origin: np.ndarray, options: dict,
                   extrapolate: bool, rule: str, crs: Any, folder: Path, feedback: Any,
                   workers: int | None = None) -> dict[str, Any]:
    """The QUALITY report of ``method`` on the kept points of a streamed run (the shape of
    :func:`toolbox.terrain.gridding.run.quality_report`). ``cloud`` = (ref, filter, z_field,
    chunk points); ``origin``: the run's local origin; ``rule``: DUPLICATES."""
    from toolbox.io.crs import crs_label
    from toolbox.terrain.gridding import stream
    from toolbox.terrain.gridding.neighbours import PointBins
    from toolbox.terrain.gridding.request import ORDER_NAMES
    from toolbox.terrain.gridding.run import jsonable_options
    from toolbox.terrain.points import merge_duplicate_xy

    ref, flt, z_field, chunk = cloud
    tin = method.name == "tin_linear"
    if tin:
        from toolbox.terrain.gridding.stream_tin import TIN_NEIGHBOURS

        k, radius = TIN_NEIGHBOURS, math.inf
    else:
        k, radius = method.halo_neighbours(options)
        radius = math.inf if radius is None else float(radius)
    tiles, boxes = plan_quality(scan, k, radius, stream.TILE_POINTS)
    width = tiles.block * scan.size
    folder = folder / "quality"
    folder.mkdir()
    ring = _hull_vertices(scan.ring, origin)
    hull = ring if not extrapolate else set()
    settle = _TinSettle(scan, ring, cloud, rule) if tin else None
    merged = stream.Merged(rule)
    errors_path = folder / "errors.f8"
    sums = {"n": 0, "points": 0, "hull": 0, "err": [], "err2": [], "abs": []}
    worst = (-1.0, math.inf, None)  # (|error|, rank of the first point, worst point)
    removed: list[np.ndarray] = []
    orders = np.zeros(4, dtype=np.int64)
    any_orders = False
    n_tiles = len(tiles.boxes)
    reach = boxes.reach.copy()
    todo, passes, spilled, bucket_max, retried, done = list(range(n_tiles)), 0, 0, 0, 0, 0
    while todo:  # one pass, or for tin_linear until every tile's stars are settled
        live = np.full(n_tiles, -np.inf)  # empty rectangles for the tiles already done
        live[todo] = reach[todo]
        current = replace(boxes, reach=live)
        bucket_dir = folder / f"pass{passes}"
        bucket_dir.mkdir()
        with feedback.timed("quality_spill"):
            written = stream.spill(ref, flt, z_field, chunk, current, bucket_dir,
                                   step=(width, width), index=True)
        passes += 1
        spilled += int(written.sum())
        bucket_max = max(bucket_max, int(written.max()))
        again = []
        for t in todo:
            feedback.check_canceled()
            path = bucket_dir / f"{t}.xyz"
            if not path.exists():
                done += 1
                continue
            bucket = np.fromfile(path, dtype=np.float64).reshape(-1, 4)
            path.unlink()
            own = tiles.owner(bucket[:, :2]) == t
            if not own.any():
                done += 1
                continue
            xyz, rank = bucket[:, :3], bucket[:, 3]
            report, gone_here = None, None
            merged_xyz, _, keep = stream.merge_exact_xy(xyz, rule)
            if keep is not None:  # (DUPLICATES 'error' raised there: the tile's own points merge)
                xyz = merged_xyz
                _, report, first = merge_duplicate_xy(bucket[own, :3], 0.0, rule)
                mine = rank[own]
                gone = np.ones(len(mine), dtype=bool)
                gone[first] = False
                gone_here = mine[gone].astype(np.int64)
                rank = rank[keep]
                if k > 0 and not tin:
                    rect = current.rects[t]
                    need = stream.tile_reach(boxes.boxes[t], rect, scan, xyz, k + 1, radius)
                    if need > reach[t] * (1 + 1e-12):
                        raise InputDataError(
                            f"streamed QUALITY: after merging duplicate XY, the points of tile "
                            f"{t} may need neighbours {need:.3f} away, its bucket holds those "
                            f"within {reach[t]:.3f}: over a quarter of the points share their "
                            "XY; raise TOOLBOX_STREAM_POINTS to grid in memory")
                own = tiles.owner(xyz[:, :2]) == t
            targets = np.flatnonzero(own)
            if tin:
                xyz, rank = settle.add_rim(xyz, rank, current.rects[t])
            local = np.array(xyz, dtype=np.float64)
            local[:, :2] -= origin
            if tin:
                if not settle.settled(xyz, targets, current.rects[t]):
                    again.append(t)
                    continue
                predicted, used = _tin_loo(local, targets, options), None
            else:
                bins = PointBins.build(local[:, :2])
                predicted, used = method.loo_targets(bins, local[:, 2], targets, options, None,
                                                     workers)
            if report is not None:
                merged.add(report)
                removed.append(gone_here)
            if hull:
                xy = xyz[targets, :2]
                at_hull = np.isin(xy[:, 0], [x for x, _ in hull])  # then the exact pairs
                at_hull[at_hull] = [(x, y) in hull for x, y in xy[at_hull]]
                predicted[at_hull] = np.nan
                sums["hull"] += int(at_hull.sum())
            if used is not None:
                any_orders = True
                used[np.isnan(predicted)] = -1
                orders += np.bincount(used[used >= 0], minlength=4)[:4]
            sums["points"] += len(targets)
            ok = np.isfinite(predicted)
            err = predicted[ok] - local[targets[ok], 2]
            sums["n"] += len(err)
            if len(err):
                with open(errors_path, "ab") as fh:
                    fh.write(err.tobytes())
                sums["err"].append(float(err.sum()))
                sums["err2"].append(float((err ** 2).sum()))
                sums["abs"].append(float(np.abs(err).sum()))
                a = np.abs(err)
                top = a.max()
                tied = np.flatnonzero(a == top)
                picks = targets[ok][tied]
                j = int(picks[np.argmin(rank[picks])])
                candidate = (float(top), float(rank[j]),
                             {"x": float(xyz[j, 0]), "y": float(xyz[j, 1]),
                              "z": float(xyz[j, 2]),
                              "predicted": float(predicted[np.flatnonzero(targets == j)[0]])})
                if candidate[0] > worst[0] or (candidate[0] == worst[0]
                                               and candidate[1] < worst[1]):
                    worst = candidate
            done += 1
            feedback.set_progress(100.0 * done / n_tiles)
        bucket_dir.rmdir()
        retried += len(again)
        reach[again] *= 2.0
        for t in again:
            settle.check_growth(boxes, t, reach[t])
        todo = again
    gone = np.sort(np.concatenate(removed)) if removed else np.zeros(0, dtype=np.int64)
    summary = _summary(sums, errors_path, worst, gone)
    if not extrapolate and sums["points"] >= 3:
        summary["hull_vertices_not_predicted"] = sums["hull"]
    if any_orders:
        summary["orders_used"] = {ORDER_NAMES[o]: int(orders[o]) for o in range(4)}
    summary["options"] = jsonable_options(options)
    summary["streamed"] = {"tiles": n_tiles, "block_buckets": tiles.block,
                           "bucket_points_max": bucket_max, "points_spilled": spilled,
                           "reach_max": float(reach.max())}
    if tin:
        summary["streamed"] |= {"passes": passes, "tiles_retried": retried,
                                "rim_points": None if settle.rim is None else len(settle.rim)}
    return {"what": "leave-one-out cross-validation: error = predicted - observed height",
            "crs": crs_label(crs), "points": sums["points"],
            "duplicates": merged.report.as_dict(), "methods": {method.name: summary}}


class _TinSettle:
    """The circumcircle test of :mod:`~toolbox.terrain.gridding.stream_tin` on a QUALITY tile's
    bucket (see the module)."""

    def __init__(self, scan: Any, ring: set, cloud: tuple, rule: str):
        from shapely.geometry import Polygon

        from toolbox.terrain.gridding.stream import count_table

        self.scan, self.ring, self.table = scan, ring, count_table(scan.counts)
        self.hull = Polygon(scan.ring) if len(scan.ring) >= 3 else None
        self.inner, self.rim = None, None
        if self.hull is not None:
            self._rim(cloud, rule)

    def _rim(self, cloud: tuple, rule: str) -> None:
        """The kept points within RIM_BUCKETS buckets of the hull's edge (:func:`~toolbox.
        terrain.gridding.stream_tin.hull_rim`)."""
        from toolbox.terrain.gridding import stream
        from toolbox.terrain.gridding.stream_tin import hull_rim

        self.inner, self.rim = hull_rim(self.scan, self.hull, cloud, rule, RIM_BUCKETS,
                                        stream.TILE_POINTS)

    def add_rim(self, xyz: np.ndarray, rank: np.ndarray, rect: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """The bucket with the rim points outside the closed ``rect`` appended (rank -1)."""
        if self.rim is None or not len(self.rim):
            return xyz, rank
        rim = self.rim
        out = ~((rim[:, 0] >= rect[0]) & (rim[:, 0] <= rect[2]) & (rim[:, 1] >= rect[1])
                & (rim[:, 1] <= rect[3]))
        return np.vstack([xyz, rim[out]]), np.r_[rank, np.full(int(out.sum()), -1.0)]

    def settled(self, xyz: np.ndarray, targets: np.ndarray, rect: np.ndarray) -> bool:
        """True when every target's star in the bucket's Delaunay TIN is its star in the TIN
        of the whole cloud (closed around it, or open only along the cloud's hull; each
        triangle's circumcircle empty of the points outside ``rect``), or the target is a
        vertex of the cloud's hull (never predicted)."""
        from shapely.geometry import box

        from toolbox.terrain.gridding.stream_tin import circumcircles, empty_outside, supports_hull
        from toolbox.terrain.tin.kernels import triangulate

        # the points not in the bucket: those of the hull (or, with the rim added, of the hull
        # shrunk by the rim) outside the rectangle
        outer = None if self.hull is None else \
            (self.hull if self.inner is None else self.inner).difference(box(*rect))
        if outer is None or outer.is_empty:  # the bucket holds every point
            return True
        try:
            tri = triangulate(xyz[:, :2]) if len(xyz) >= 3 else np.zeros((0, 3), np.int32)
        except ValueError:  # collinear bucket
            tri = np.zeros((0, 3), dtype=np.int32)
        unsettled = np.ones(len(xyz), dtype=bool)
        if len(tri):
            centres, radius = circumcircles(xyz[:, :2], tri)
            good = empty_outside(centres, radius, rect, self.scan.bounds, outer)
            unsettled[:] = False
            unsettled[tri[~good].ravel()] = True
            edges = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
            edges, count = np.unique(edges, axis=0, return_counts=True)
            open_ = edges[count == 1]  # on the bucket's hull: the star is open there
            # unless the edge lies on the cloud's hull (its star in the whole cloud is open
            # there too: a point on a straight edge of the hull, not a vertex of it)
            near = np.isin(open_, targets).any(axis=1)
            xy = xyz[:, :2]
            near[near] = ~supports_hull(xy[open_[near, 0]], xy[open_[near, 1]], self.scan.ring)
            unsettled[open_[near].ravel()] = True
        fails = targets[unsettled[targets]]
        return all((float(x), float(y)) in self.ring for x, y in xyz[fails, :2])

    def check_growth(self, boxes: Any, t: int, h: float) -> None:
        from toolbox.terrain.gridding import stream
        from toolbox.terrain.gridding.stream_tin import check_growth

        check_growth(self.scan, self.table, boxes, t, h, stream.TILE_POINTS)


def _tin_loo(local: np.ndarray, targets: np.ndarray, options: dict) -> np.ndarray:
    """tin_linear's leave-one-out (:meth:`~toolbox.terrain.gridding.methods.tin_linear.
    TinLinearMethod.loo`) at ``targets`` of a settled bucket (local coordinates)."""
    from toolbox.terrain.gridding.neighbours import PointBins
    from toolbox.terrain.gridding.tin_constrained import tin_loo

    predicted = tin_loo(local, None, targets=targets)[targets]
    max_distance = options.get("max_distance", math.inf)
    if math.isfinite(max_distance) and len(local) > 1:
        bins = PointBins.build(local[:, :2])
        d2, _ = bins.query(local[targets, 0], local[targets, 1], 1, skip=targets)
        predicted[d2[:, 0] > max_distance ** 2] = np.nan
    return predicted


def _hull_vertices(ring: np.ndarray, origin: np.ndarray) -> set:
    """Map XY of the convex hull's vertices, as :func:`~toolbox.terrain.gridding.masks.
    hull_vertex_indices` finds them in the local coordinates of the in-memory run."""
    from toolbox.terrain.gridding.masks import hull_vertex_indices

    ring = np.asarray(ring, dtype=np.float64)
    if len(ring) == 0:
        return set()
    local = ring - origin
    return {(float(x), float(y)) for x, y in ring[hull_vertex_indices(local)]}


def _summary(sums: dict, errors_path: Path, worst: tuple, gone: np.ndarray) -> dict[str, Any]:
    """:func:`~toolbox.terrain.gridding.validation.error_summary` from the tiles' sums and the
    errors file (read back by chunks for the standard deviation)."""
    n, points = sums["n"], sums["points"]
    summary: dict[str, Any] = {"points": points, "predicted": n, "not_predicted": points - n}
    if n == 0:
        return summary | {"rmse": None, "mean_error": None, "max_abs_error": None,
                          "mean_abs_error": None, "std_error": None}
    mean = math.fsum(sums["err"]) / n
    spread = []
    with open(errors_path, "rb") as fh:
        while True:
            part = np.frombuffer(fh.read(8 * 1_000_000), dtype=np.float64)
            if len(part) == 0:
                break
            spread.append(float(((part - mean) ** 2).sum()))
    rank = int(worst[1])
    index = rank - int(np.searchsorted(gone, rank))  # the in-memory index of its position
    return summary | {"rmse": math.sqrt(math.fsum(sums["err2"]) / n), "mean_error": mean,
                      "max_abs_error": worst[0], "mean_abs_error": math.fsum(sums["abs"]) / n,
                      "std_error": math.sqrt(math.fsum(spread) / (n - 1)) if n > 1 else None,
                      "worst_point_index": index, "worst_point": worst[2]}
