"""Least-cost seams ("PPD", paths by dynamic programming) in the overlaps of a cut partition.

For each pair of neighbouring cut polygons ``i``, ``j`` the region ``R = (cell_i ∪ cell_j) ∩ F_i ∩
F_j`` (their common overlap) is re-split by the minimum-cost path between the two ends of their
current (Voronoi) seam, over a cost surface (:func:`cost_surface`): where the orthos differ
radiometrically or have strong edges (buildings, trees, relief-displaced features) the path is
expensive. The path is found by a compiled A* on the 8-connected grid (:mod:`.route`; a move's
cost = length x mean cell cost, as scikit-image's ``graph.MCP_Geometric``, its test oracle),
coarse-to-fine in memory over :data:`COARSE_TO_FINE_CELLS` cells. Outside ``R`` and in forbidden
areas the cost is negative (impassable), so the seam stays inside the overlap.

Bounded memory: a region over ``max_cells`` cells is routed first on an overview (cells ``f``
times larger), then refined at full resolution chunk by chunk in a corridor around the coarse
path; each chunk grid has at most about ``max_cells`` cells.

The new cut polygons are ``(cell_i − R) ∪ pieces_i`` and ``(cell_j − R) ∪ pieces_j``, the pieces
of ``R`` split by the path: the partition stays exact by construction.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.mosaic.sources import OrthoSource, read_window

IMPASSABLE = -1.0


@dataclass
class CostWeights:
    """Weights of the cost surface terms (dimensionless: the terms are scaled to about 0-1)."""

    base: float = 0.1        # per unit length everywhere: keeps the path from wandering
    difference: float = 1.0  # mean absolute band difference / the images' value range
    gradient: float = 1.0    # largest Sobel gradient of the two images / the value range
    centre: float = 0.5      # |distance to centre a − distance to centre b| / their distance
    structure: float = 1.0   # within structure_radius of a strong, structured difference
    structure_radius: float = 20.0    # ground units
    structure_threshold: float = 0.1  # gradient difference / value range that counts as strong
    building: float = 10.0   # inside a building footprint
    height: float = 1.0      # per metre of DSM - DEM above HEIGHT_THRESHOLD
    height_threshold: float = 0.5


def cost_surface(a: np.ndarray, b: np.ndarray, weights: CostWeights,
                 value_range: float | None = None, cell_size: float = 1.0) -> np.ndarray:
    """Cost per unit length from two co-registered images ``(bands, rows, cols)``:
    ``base + w_d·mean|a−b|/range + w_g·max(|∇a|, |∇b|)/range + w_s·S`` (float64, ``(rows,
    cols)``); :class:`PairCost` adds the centre, building and height terms.

    ``S`` (:func:`structure_term`) is 1 within ``weights.structure_radius`` ground units
    (``cell_size`` per cell) of a strong, structured difference between the images, else 0: a
    building whose facades differ between the orthos is avoided as a whole, roof included,
    even where both show the same roof. ``value_range`` defaults to the 1-99 % percentile
    spread of both images.
    """
    from toolbox.mosaic.kernels import image_cost

    a = np.ascontiguousarray(a, dtype="float32")
    b = np.ascontiguousarray(b, dtype="float32")
    if value_range is None:
        # a regular sample of ~40,000 cells of each image (x bands): the 1 and 99 % points of
        # ~240,000 values of an RGB pair are within a grey level of the whole images' ones
        step = max(1, int(np.sqrt(a[0].size / 40_000)))
        sample = np.concatenate([a[:, ::step, ::step].ravel(), b[:, ::step, ::step].ravel()])
        lo, hi = np.percentile(_in_order(sample), [1, 99])
        value_range = float(hi - lo)
    scale = 1.0 / max(value_range, 1e-6)
    # base + w_d·diff + w_g·grad and the gradients' difference, in one pass
    cost, gdiff = image_cost(a, b, scale, weights.difference, weights.base, weights.gradient)
    if weights.structure > 0 and weights.structure_radius > 0:
        near = structured_near(gdiff, weights.structure_threshold,
                               weights.structure_radius / cell_size)
        np.add(cost, weights.structure, out=cost, where=near)
    return cost


def _in_order(sample: np.ndarray) -> np.ndarray:
    """``sample`` sorted by counting when its values are whole numbers 0-65535 (orthos of 8 or
    16 bits, as float32), else as it is: the same values for np.percentile, which partitions a
    sorted array about twice as fast (3.1 -> 1.7 ms for the 240,000 values of an RGB pair)."""
    if sample.size and sample.min() >= 0 and sample.max() <= 65535:  # NaN fails both
        levels = sample.astype(np.uint16)
        if np.array_equal(levels, sample):
            counts = np.bincount(levels)
            return np.repeat(np.arange(len(counts), dtype=sample.dtype), counts)
    return sample


def add_centre(cost: np.ndarray, transform: Any, a, b, weight: float) -> None:
    """``cost += weight x`` :func:`centre_term` in place (compiled, one pass)."""
    from toolbox.mosaic.kernels import add_centre_term

    add_centre_term(cost, transform.c, transform.a, transform.f, transform.e,
                    float(a[0]), float(a[1]), float(b[0]), float(b[1]), float(weight))


def structure_term(gradient_difference: np.ndarray, threshold: float,
                   radius_cells: float) -> np.ndarray:
    """1.0 within ``radius_cells`` of a strong, structured difference, else 0.0
    (:func:`structured_near` as float64)."""
    return structured_near(gradient_difference, threshold, radius_cells).astype("float64")


def structured_near(gradient_difference: np.ndarray, threshold: float,
                    radius_cells: float) -> np.ndarray:
    """True within ``radius_cells`` of a strong, structured difference.

    Strong: the difference of the two images' gradients (vector difference of their Sobel
    gradients, scaled by the value range) above ``threshold``, i.e. an edge in one ortho that
    the other does not have at the same place (a facade, a displaced roof edge). Structured:
    a connected group of such cells at least ``max(3, radius_cells / 2)`` cells large, so noise
    and single resampling differences do not count. The neighbourhood is a Euclidean distance
    (:func:`toolbox.mosaic.kernels.within_radius`), whatever the radius.
    """
    import cv2

    from toolbox.mosaic.kernels import within_radius

    strong = gradient_difference > threshold
    if not strong.any():
        return strong
    # the 8-connected groups: those of scipy's ndimage.label with a 3 x 3 structure (maybe
    # numbered otherwise: only their sizes count), in a third of its CPU (2.6 -> 0.8 ms on the
    # benchmark's 1000 x 1000 overlap)
    n, groups = cv2.connectedComponents(np.ascontiguousarray(strong).view(np.uint8),
                                        connectivity=8, ltype=cv2.CV_32S)
    sizes = np.bincount(groups[strong], minlength=n)  # sizes[0] (no group) is not used
    keep = sizes >= max(3.0, radius_cells / 2.0)
    keep[0] = False
    if not keep.any():
        return np.zeros(strong.shape, bool)
    kept = strong if keep[1:].all() else keep[groups]  # every group large enough: no gather
    return within_radius(kept, float(radius_cells))


@dataclass
class PairCost:
    """The cost of a seam between two orthos, on any north-up grid (``transform``, ``shape``)."""

    a: OrthoSource
    b: OrthoSource
    crs: Any
    weights: CostWeights = field(default_factory=CostWeights)
    buildings: list = field(default_factory=list)   # shapely polygons
    forbidden: list = field(default_factory=list)   # shapely polygons
    heights: OrthoSource | None = None              # DSM - DEM raster, metres
    centres: tuple | None = None                    # ((xa, ya), (xb, yb)) Voronoi centres
    value_range: float | None = None

    def __call__(self, transform: Any, shape: tuple[int, int]) -> np.ndarray:
        from rasterio.features import rasterize
        from rasterio.windows import Window

        win = Window(0, 0, shape[1], shape[0])
        da, va = read_window(self.a, transform, self.crs, win)
        db, vb = read_window(self.b, transform, self.crs, win)
        cost = cost_surface(da, db, self.weights, self.value_range, abs(transform.a))
        w = self.weights
        if self.centres is not None and w.centre > 0:
            add_centre(cost, transform, *self.centres, w.centre)
        if self.buildings:
            inside = rasterize(self.buildings, out_shape=shape, transform=transform,
                               all_touched=True, dtype="uint8") > 0
            cost[inside] += w.building
        if self.heights is not None:
            h, vh = read_window(self.heights, transform, self.crs, win)
            excess = np.where(vh, np.clip(h[0] - w.height_threshold, 0, None), 0)
            cost += w.height * excess
        cost[~(va & vb)] = IMPASSABLE
        if self.forbidden:
            banned = rasterize(self.forbidden, out_shape=shape, transform=transform,
                               all_touched=True, dtype="uint8") > 0
            cost[banned] = IMPASSABLE
        return cost


def centre_term(transform: Any, shape: tuple[int, int], a, b) -> np.ndarray:
    """``|‖p − a‖ − ‖p − b‖| / ‖a − b‖`` at the cell centres: 0 on the bisector of the two
    centres (the Voronoi seam), growing towards either centre; it keeps a seam near the middle
    where the images give no reason to leave it (each cell stays near its own nadir, where relief
    displacement is least)."""
    rows, cols = shape
    x = (transform.c + (np.arange(cols) + 0.5) * transform.a)[None, :]
    y = (transform.f + (np.arange(rows) + 0.5) * transform.e)[:, None]
    da = np.sqrt((x - a[0]) ** 2 + (y - a[1]) ** 2)  # (1, cols) + (rows, 1): one full-size sum
    db = np.sqrt((x - b[0]) ** 2 + (y - b[1]) ** 2)
    return np.abs(da - db) / max(float(np.hypot(a[0] - b[0], a[1] - b[1])), 1e-9)


def grid_for(bounds, cell: float, origin: tuple[float, float] = (0.0, 0.0)):
    """``(transform, (rows, cols))`` of a north-up grid of ``cell`` covering ``bounds``, edges on
    multiples of ``cell`` from ``origin``."""
    from affine import Affine

    xmin = origin[0] + math.floor((bounds[0] - origin[0]) / cell) * cell
    ymin = origin[1] + math.floor((bounds[1] - origin[1]) / cell) * cell
    xmax = origin[0] + math.ceil((bounds[2] - origin[0]) / cell) * cell
    ymax = origin[1] + math.ceil((bounds[3] - origin[1]) / cell) * cell
    cols, rows = max(1, round((xmax - xmin) / cell)), max(1, round((ymax - ymin) / cell))
    return Affine(cell, 0, xmin, 0, -cell, ymax), (rows, cols)


#: regions of more cells than this are routed coarse-to-fine in memory
#: (:func:`toolbox.mosaic.route.coarse_to_fine`): an overview path first, then full resolution
#: in a corridor round it
COARSE_TO_FINE_CELLS = 250_000
OVERVIEW_CELLS = 62_500  # cells of that overview (about 250 x 250)


def route(cost: np.ndarray, start: tuple[int, int], end: tuple[int, int]) -> np.ndarray | None:
    """Least-cost 8-connected path ``(n, 2)`` of (row, col) from ``start`` to ``end`` over
    ``cost`` (negative = impassable), None if unreachable: the exact optimum (A*,
    :func:`toolbox.mosaic.route.least_cost_path`, the cost of scikit-image's
    ``MCP_Geometric``) up to :data:`COARSE_TO_FINE_CELLS` cells, coarse-to-fine above."""
    from toolbox.mosaic.route import coarse_to_fine, least_cost_path

    if cost.size <= COARSE_TO_FINE_CELLS:
        return least_cost_path(cost, start, end)[0]
    factor = max(2, round(math.sqrt(cost.size / OVERVIEW_CELLS)))
    return coarse_to_fine(cost, start, end, factor)


def _nearest_passable(cost: np.ndarray, rc: tuple[int, int]) -> tuple[int, int] | None:
    """The passable cell nearest to ``rc`` (``rc`` itself if passable)."""
    from scipy import ndimage

    r = min(max(rc[0], 0), cost.shape[0] - 1)
    c = min(max(rc[1], 0), cost.shape[1] - 1)
    if cost[r, c] >= 0:  # the usual case: no pass over the whole grid
        return (r, c)
    passable = cost >= 0
    if not passable.any():
        return None
    _, (ri, ci) = ndimage.distance_transform_edt(~passable, return_indices=True)
    return (int(ri[r, c]), int(ci[r, c]))


def route_in_region(pair_cost: Callable, region, start_xy, end_xy, cell: float) -> list | None:
    """Least-cost path (list of (x, y), from ``start_xy`` to ``end_xy`` exactly) inside the
    polygon ``region`` on a grid of ``cell``; None when the ends are not connected in it."""
    from rasterio.features import rasterize
    from rasterio.transform import rowcol, xy

    transform, shape = grid_for(region.bounds, cell)
    cost = pair_cost(transform, shape)
    inside = rasterize([region], out_shape=shape, transform=transform, dtype="uint8") > 0
    cost[~inside] = IMPASSABLE
    ends = []
    for x, y in (start_xy, end_xy):
        r, c = rowcol(transform, x, y)
        rc = _nearest_passable(cost, (int(r), int(c)))
        if rc is None:
            return None
        ends.append(rc)
    path = route(cost, ends[0], ends[1])
    if path is None:
        return None
    xs, ys = xy(transform, path[:, 0], path[:, 1])
    return [tuple(start_xy), *zip(np.asarray(xs).tolist(), np.asarray(ys).tolist(),
                                  strict=True), tuple(end_xy)]


def seam_path(pair_cost: Callable, region, start_xy, end_xy, cell: float,
              max_cells: int = 4_000_000, feedback: Any = None) -> list | None:
    """Least-cost seam from ``start_xy`` to ``end_xy`` inside ``region`` at resolution ``cell``;
    overview first and a full-resolution corridor when the region exceeds ``max_cells``."""
    from shapely import LineString
    from shapely.ops import substring

    x0, y0, x1, y1 = region.bounds
    cells = (x1 - x0) * (y1 - y0) / (cell * cell)
    if cells <= max_cells:
        return route_in_region(pair_cost, region, start_xy, end_xy, cell)
    factor = math.ceil(math.sqrt(cells / max_cells))
    coarse = route_in_region(pair_cost, region, start_xy, end_xy, cell * factor)
    if coarse is None:
        return None
    line = LineString(coarse)
    corridor = 3 * factor * cell
    chunk = max(0.5 * math.sqrt(max_cells) * cell - 2 * corridor, 4 * factor * cell)
    n = max(1, math.ceil(line.length / chunk))
    path: list = [tuple(start_xy)]
    for k in range(n):
        if feedback is not None:
            feedback.check_canceled()
        piece = substring(line, k * line.length / n, (k + 1) * line.length / n)
        end = tuple(end_xy) if k == n - 1 else tuple(piece.coords[-1])
        zone = region.intersection(piece.buffer(corridor))
        part = route_in_region(pair_cost, zone, path[-1], end, cell)
        if part is None:  # the corridor pinched off: keep the coarse piece
            part = [path[-1], *piece.coords[1:-1], end]
        path.extend(part[1:])
    return path


def split_between(cells: list | dict, i: int, j: int, path: list, region, tol: float) -> tuple:
    """Split ``region`` (inside ``cells[i] ∪ cells[j]``) by the polyline ``path`` and give each
    piece to the cell it borders most outside ``region`` (to the one it held most of, when it
    borders both or neither); returns the new ``(cell_i, cell_j)``."""
    import shapely
    from shapely import LineString
    from shapely.ops import split

    rest_i = cells[i].difference(region)
    rest_j = cells[j].difference(region)
    # as an array: shapely reads a list of tuples point by point in Python (3 ms for the
    # 1000 vertices of the benchmark's seam); the same coordinates
    line = LineString(np.asarray(path, dtype="float64")).simplify(tol * 0.5)
    # a split cuts along the path: the pieces' perimeters exceed the region's by about twice
    # the path's length inside it (less where the path runs along the region's edge)
    along = 2 * SPLIT_ALONG * line.intersection(region).length
    pieces: list = []
    first = None
    for turns in END_TURNS:  # straight on first; then an end that runs along the boundary
        cut = [g for g in getattr(split(region, _extended(line, 4 * tol, turns)), "geoms", [])
               if g.area > 0]
        # slivers under a hundredth of a cell (a path running along the region's edge) do not
        # make a split (they are given away below all the same: the partition stays exact)
        if sum(g.area > SPLIT_PIECE * tol * tol for g in cut) < 2:
            continue
        first = cut if first is None else first
        if sum(g.length for g in cut) - region.length >= along:
            pieces = cut
            break
    pieces = pieces or first  # no split along the whole path: the first one that cuts
    if pieces is None:
        return None
    grow_i, grow_j = rest_i.buffer(tol), rest_j.buffer(tol)
    mine, yours = [rest_i], [rest_j]
    for piece in pieces:
        edge = piece.boundary
        # contacts shorter than a seam cell (1000 tol) are rounding, not borders
        touch_i, touch_j = (length if length > 1000 * tol else 0.0 for length in
                            (edge.intersection(grow_i).length, edge.intersection(grow_j).length))
        # a piece bordering both rests (the two cells also meet elsewhere) goes by its area
        if abs(touch_i - touch_j) <= tol or min(touch_i, touch_j) > 0:
            touch_i = piece.intersection(cells[i]).area
            touch_j = piece.intersection(cells[j]).area
        (mine if touch_i >= touch_j else yours).append(piece)
    return _clean(shapely.union_all(mine)), _clean(shapely.union_all(yours))


#: the least area of a piece that makes a split (:func:`split_between`), in ``tol²``: a
#: hundredth of a seam cell (``tol`` is a thousandth of a cell)
SPLIT_PIECE = 1e4


#: the share of the path's length a split must cut along to be taken before the other
#: ends are tried (:func:`split_between`): a straight end that leaves the region where it
#: meets the edge split off a 0.2 m² corner and gave one ortho a corner seam's whole overlap
SPLIT_ALONG = 0.9


#: how :func:`_extended` leaves the line's (start, end): 0 straight on, +1 / -1 turned left /
#: right (an end on the region's boundary whose last segment runs along it crosses it sideways)
END_TURNS = ((0, 0), (0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))


def _extended(line, length: float, turns: tuple[int, int] = (0, 0)):
    """``line`` with both end segments prolonged by ``length``: ends that lie on the region's
    boundary only to rounding still cross it, so that the split cuts. ``turns`` (start, end):
    0 prolongs the end segment; +1 / -1 adds a segment of ``length`` at right angles to it."""
    from shapely import LineString

    xy = np.asarray(line.coords, dtype="float64")
    if len(xy) < 2:
        return line
    head, tail = [], []
    for (end, inner), turn in zip(((0, 1), (-1, -2)), turns, strict=True):
        step = xy[end] - xy[inner]
        norm = float(np.hypot(*step))
        if norm == 0:
            continue
        step = step / norm * length
        if turn == 0:
            xy[end] = xy[end] + step
        else:
            side = xy[end] + turn * np.array([-step[1], step[0]])
            (head if end == 0 else tail).append(side)
    return LineString(np.vstack([*head, xy, *tail]))


def _clean(geom):
    from toolbox.mosaic.partition import _polygonal

    return _polygonal(geom)


def seam_ends(cell_i, cell_j, gap: float = 0.0):
    """``(start, end, parts)``: the two ends of the longest shared boundary line of two cut
    polygons, or None; parts of the boundary whose ends are within ``gap`` of each other are one
    line (:func:`_longest_chain`)."""
    from toolbox.mosaic.partition import merge_lines, shared_lines

    lines = shared_lines(cell_i, cell_j)
    if not lines:
        return None
    merged = merge_lines(lines)
    parts = list(getattr(merged, "geoms", [merged]))
    longest = max(parts, key=lambda g: g.length)
    if longest.length == 0 or longest.is_closed:
        return None
    start, end = _longest_chain(parts, parts.index(longest), gap) if gap > 0 and len(parts) > 1 \
        else (longest.coords[0], longest.coords[-1])
    if gap > 0 and math.dist(start, end) <= gap:  # a ring to rounding: no seam to route
        return None
    return start, end, len(parts)


#: parts of a shared boundary whose ends are closer than this fraction of a seam cell are one
#: line (:func:`seam_ends`): such a gap holds no cell, it is rounding
END_GAP_CELLS = 0.01


def _longest_chain(parts: list, first: int, gap: float) -> tuple:
    """The ends of the chain of ``parts`` joined end to end (ends within ``gap``) that holds the
    greatest length, oriented as its longest part; the ends of ``parts[first]`` (the longest
    part) when its chain is not a simple one (a branch, a ring).

    Cut polygons meet along edges that coincide only to rounding: their shared boundary can come
    in parts with gaps of 1e-4 m, and the seam then started at the end of the longest part, in
    the middle of the overlap, or at the real end, as a nadir point moved by a millimetre."""
    ends = np.array([[g.coords[0], g.coords[-1]] for g in parts], dtype="float64")  # (n, 2, 2)
    flat = ends.reshape(-1, 2)
    near = np.hypot(*(flat[:, None, :] - flat[None, :, :]).transpose(2, 0, 1)) <= gap
    np.fill_diagonal(near, False)
    for k in range(len(parts)):  # a part's own two ends are not a joint
        near[2 * k, 2 * k + 1] = near[2 * k + 1, 2 * k] = False
    if (near.sum(axis=1) > 1).any():
        return tuple(ends[first, 0]), tuple(ends[first, 1])

    def walk(end: int) -> tuple:
        seen = {end // 2}
        while True:
            joint = np.flatnonzero(near[end])
            if not len(joint) or joint[0] // 2 in seen:
                return tuple(flat[end])
            other = joint[0] ^ 1  # the far end of the next part
            seen.add(other // 2)
            end = other

    return walk(2 * first), walk(2 * first + 1)


def least_cost_cells(cells: list, footprints: list, cost_for: Callable[[int, int], Callable],
                     cell: float, max_cells: int = 4_000_000, feedback: Any = None,
                     executor: Any = None) -> tuple:
    """Re-route every seam of the partition ``cells`` along the least-cost path in its overlap.

    ``cost_for(i, j)`` returns the :class:`PairCost` of orthos i and j. Returns ``(cells,
    report)``: the new cut polygons (still an exact partition) and one dict per seam.

    The seams are re-routed one after the other, the longest first, each on the cut polygons
    its predecessors left; a seam reads and changes only its own two polygons, so the seams are
    run in waves (:func:`seam_waves`) of seams sharing no polygon, each seam after every earlier
    one sharing a polygon with it: the result is the one-by-one result exactly. On a Dask
    ``executor`` (default: the cluster of ``DASK_SCHEDULER_ADDRESS`` when set) a wave's seams
    run in parallel (:func:`toolbox.executor.map_tiles`); on a local one they run one after the
    other in this thread (threads cost about 25 % more CPU in the benchmark for no wall gain on
    the loaded 2-core machine).
    """
    from toolbox.executor import map_tiles, resolve_executor
    from toolbox.mosaic.partition import seamlines

    executor = executor or resolve_executor()
    cells = list(cells)
    # the longest seams first: a short one (a corner where two non-neighbours touch) re-routed
    # early can take a neighbour's whole side and leave the main seams nothing to route
    pairs = [(i, j) for i, j, _ in sorted(seamlines(cells), key=lambda s: -s[2].length)]
    report: list = [None] * len(pairs)
    done = 0
    for wave in seam_waves(pairs):
        tasks = [SeamTask(i, j, cells[i], cells[j], footprints[i], footprints[j], cost_for(i, j),
                          cell, max_cells) for i, j in (pairs[k] for k in wave)]
        if executor.kind == "local":  # one after the other: threads cost CPU here, gain little
            results = _one_by_one(tasks, feedback, done, len(pairs))
        else:
            results = map_tiles(route_seam, tasks, executor=executor, feedback=feedback,
                                total=len(wave), start=100.0 * done / len(pairs),
                                end=100.0 * (done + len(wave)) / len(pairs))
        for k, (entry, new) in zip(wave, results, strict=True):
            report[k] = entry
            if new is not None:
                i, j = pairs[k]
                cells[i], cells[j] = new
        done += len(wave)
    return merge_close_vertices(cells, SHORT_SEGMENT_CELLS * cell), report


#: vertices of the cut polygons closer than this fraction of a seam cell are one vertex: the
#: split and unions leave segments of rounding length where a path meets the overlap's edge
#: (2.3e-14 m near the origin, 4.7e-10 m at Siena's coordinates: 114 vertices there, 113 here)
SHORT_SEGMENT_CELLS = 1e-6


def merge_close_vertices(cells: list, tolerance: float) -> list:
    """The polygons ``cells`` with every cluster of vertices closer than ``tolerance`` (over
    all the polygons at once) moved onto one of them (the least: x, then y) and the repeats
    dropped: a boundary two polygons share changes alike in both, so a partition stays exact.
    The polygons as given when a result would be invalid or empty."""
    import shapely
    from scipy.cluster.hierarchy import DisjointSet
    from scipy.spatial import cKDTree

    geoms = np.array(cells, dtype=object)
    live = np.flatnonzero(~shapely.is_missing(geoms))
    if not len(live) or tolerance <= 0:
        return cells
    xy = shapely.get_coordinates(geoms[live])
    points, inverse = np.unique(xy, axis=0, return_inverse=True)  # sorted: x, then y
    pairs = cKDTree(points).query_pairs(tolerance, output_type="ndarray")
    if not len(pairs):
        return cells
    clusters = DisjointSet(range(len(points)))
    for a, b in pairs.tolist():
        clusters.merge(a, b)
    target = np.arange(len(points))
    for members in clusters.subsets():
        if len(members) > 1:
            target[sorted(members)] = min(members)  # the least point (unique's order)
    moved = points[target[inverse.reshape(-1)]]
    try:
        out = shapely.remove_repeated_points(
            shapely.transform(geoms[live], lambda _: moved), 0.0)
    except shapely.errors.GEOSException:  # a ring collapsed below 3 points: GEOS refuses it
        return cells
    if not (shapely.is_valid(out).all() and not shapely.is_empty(out).any()):
        return cells
    result = list(cells)
    for k, geom in zip(live.tolist(), out, strict=True):
        result[k] = geom
    return result


def _one_by_one(tasks: list, feedback: Any, done: int, total: int):
    """The seams of ``tasks`` routed in this thread, lazily, with the progress of each and the
    cancellation checked inside each route (:func:`seam_path`)."""
    for n, task in enumerate(tasks):
        if feedback is not None:
            feedback.check_canceled()
            feedback.set_progress(100.0 * (done + n) / max(1, total))
        yield route_seam(task, feedback)


def seam_waves(pairs: list[tuple[int, int]]) -> list[list[int]]:
    """Indexes of ``pairs`` in waves: a pair goes in the wave after the last one holding an
    earlier pair with one of its two polygons, so no two pairs of a wave share a polygon and
    running the waves in order (a wave's pairs in any order) is running the pairs in order."""
    last: dict[int, int] = {}
    waves: list[list[int]] = []
    for k, (i, j) in enumerate(pairs):
        level = max(last.get(i, -1), last.get(j, -1)) + 1
        last[i] = last[j] = level
        if level == len(waves):
            waves.append([])
        waves[level].append(k)
    return waves


@dataclass(frozen=True)
class SeamTask:
    """One seam to re-route: the two cut polygons and footprints, and the pair's cost."""

    i: int
    j: int
    cell_i: Any
    cell_j: Any
    footprint_i: Any
    footprint_j: Any
    cost: Callable
    cell: float
    max_cells: int


#: gaps between two cut polygons narrower than this fraction of a seam cell are closed in their
#: seam's region (:func:`seam_region`)
GAP_CELLS = 1e-6


def seam_region(cell_i, cell_j, footprint_i, footprint_j, cell: float):
    """The overlap ``(cell_i ∪ cell_j) ∩ F_i ∩ F_j`` a seam is routed in, with the hairline gaps
    between the two cut polygons closed (narrower than :data:`GAP_CELLS` of a cell).

    The cut polygons meet along edges that coincide only to rounding (they are computed one by
    one): their plain union can come out as two polygons that touch at points across a crack
    along the whole Voronoi seam, and the route was then confined to one side of it (the piece
    nearest the seam's ends), switching sides when a nadir point moved by a millimetre (a seam
    moved by 40-60 m in a 6-ortho block)."""
    import shapely

    eps = GAP_CELLS * cell
    union = shapely.union_all([cell_i, cell_j])
    closed = union.buffer(eps, join_style="mitre").buffer(-eps, join_style="mitre")
    return _clean(closed.intersection(footprint_i).intersection(footprint_j))


#: a seam end within this many seam cells of its overlap's outer edge is put on it
#: (:func:`on_edge`)
END_SNAP_CELLS = 3.0


def on_edge(region, point, cell: float) -> tuple[float, float]:
    """The point of ``region``'s outer edge nearest to ``point`` when within
    :data:`END_SNAP_CELLS` cells (plus twice :data:`~toolbox.mosaic.partition.SHARED_TOLERANCE`
    of the coordinates, the tolerance the ends are found to), else ``point`` as it is.

    A path from an end off the outer edge does not split the overlap: an end 4.7 mm inside
    (the shared boundary matched to the tolerance), or on the edge of an island of a third cut
    polygon (a sliver of 1.2 m x 5 cm along the Voronoi line cutting the shared boundary in two:
    the longer part's end 1.2 m inside) left the seam on the Voronoi line or gave one ortho the
    whole overlap, as a nadir point moved by a millimetre."""
    from shapely import Point
    from shapely.ops import nearest_points

    from toolbox.mosaic.partition import SHARED_TOLERANCE

    here = Point(point)
    outer = region.exterior if region.geom_type == "Polygon" else region.boundary
    limit = 2 * SHARED_TOLERANCE * max(1.0, abs(point[0]), abs(point[1])) + END_SNAP_CELLS * cell
    if outer.distance(here) > limit:
        return tuple(point)
    return nearest_points(outer, here)[0].coords[0]


def route_seam(task: SeamTask, feedback: Any = None) -> tuple[dict, tuple | None]:
    """``(report entry, (new cell_i, new cell_j) or None)`` of one seam (a task of
    :func:`least_cost_cells`, run in this thread or on a Dask worker); ``feedback`` (local
    runs) is checked for cancellation between the chunks of the route."""
    from shapely import Point

    i, j, cell = task.i, task.j, task.cell
    entry: dict = {"a": i, "b": j, "method": "voronoi"}
    ends = seam_ends(task.cell_i, task.cell_j, END_GAP_CELLS * cell)
    if ends is None:
        entry["note"] = "no open shared boundary"
        return entry, None
    start, end, n_parts = ends
    region = seam_region(task.cell_i, task.cell_j, task.footprint_i, task.footprint_j, cell)
    if region.is_empty or region.area < cell * cell:
        entry["note"] = "no overlap"
        return entry, None
    if region.geom_type == "MultiPolygon":
        region = min(region.geoms, key=lambda g: g.distance(Point(start)) +
                     g.distance(Point(end)))
    # the shared line's ends are found to SHARED_TOLERANCE (4.8 mm at 4,800,000): on the
    # region's edge exactly, so that the path, prolonged by a few thousandths of a cell, cuts it
    start, end = (on_edge(region, p, cell) for p in (start, end))
    path = seam_path(task.cost, region, start, end, cell, task.max_cells, feedback)
    if path is None:
        entry["note"] = "seam ends not connected inside the overlap"
        return entry, None
    new = split_between({i: task.cell_i, j: task.cell_j}, i, j, path, region, cell * 1e-3)
    if new is None:
        entry["note"] = "the path did not split the overlap"
        return entry, None
    entry.update(method="least_cost", vertices=len(path), pieces=n_parts)
    return entry, new
