"""Snap line ends ("riattacco", thesis S002 §2.2.1 and §2.4: "prossimità tra linee confluenti").

Only line *ends* move; vertices inside a line stay where the operator plotted them. An end that
misses by at most the tolerance goes, in order of preference, to

1. **a node**: other line ends within the tolerance form a cluster, snapped onto the member that
   most ends already share (an existing node), ties broken by the lowest (x, y);
2. **a vertex** of another line (the nearest, ties by lowest (x, y));
3. **a segment** of another line (the nearest point on the nearest line): the classic undershoot
   at a T-junction. The point lies on the segment up to rounding; noding with snap rounding
   (:mod:`toolbox.topology.noding`) makes it a node.

An end that already touches another line (within a thousandth of the coordinate precision) is not
moved.
The two ends of one line are never snapped to each other here: closing a polyline is the closure
tolerance's job (:mod:`toolbox.topology.closure`). The rule is independent of the order of the
input lines.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

NODE, VERTEX, SEGMENT = "node", "vertex", "segment"
MAX_ROUNDS = 10


def touch_distance(precision: float) -> float:
    """Distance under which a line end already touches a line: a thousandth of the grid step.

    Only ends placed on a line by computation (a segment snap) are that close; anything farther,
    however little, is snapped explicitly, because snap rounding would not necessarily node it
    and a second run on the rounded result would then snap it (breaking idempotence).
    """
    return precision * 1e-3


@dataclass
class SnapResult:
    """Lines after snapping and what moved.

    Attributes
    ----------
    lines : (M,) LineStrings, same order as the input minus ``degenerate``.
    kept : (M,) int array, input index of each output line.
    degenerate : (K,) int array, input lines that collapsed to a point (both ends snapped
        together on a two-vertex line) and were dropped.
    move_line, move_end : (J,) int arrays, the line (input index) and end (0 start, 1 end) moved.
    move_from, move_to : (J, 2) float arrays, old and new position.
    move_kind : (J,) str array, ``node``, ``vertex`` or ``segment``.
    """

    lines: np.ndarray
    kept: np.ndarray
    degenerate: np.ndarray
    move_line: np.ndarray
    move_end: np.ndarray
    move_from: np.ndarray
    move_to: np.ndarray
    move_kind: np.ndarray
    counts: dict[str, int] = field(default_factory=dict)


def line_ends(lines: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Coordinates and index of every vertex, and the positions of each line's first/last vertex.

    Returns ``coords (V, 2), owner (V,), first (N,), last (N,)``.
    """
    coords, owner = shapely.get_coordinates(lines, return_index=True)
    counts = np.bincount(owner, minlength=len(lines))
    last = np.cumsum(counts) - 1
    first = last - counts + 1
    return coords, owner, first, last


def _cluster_ends(ends: np.ndarray, end_owner: np.ndarray, tolerance: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Node snapping: new position of each end and a mask of the ends moved."""
    pos, inverse, mult = np.unique(ends, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    npos = len(pos)
    lo = np.full(npos, np.iinfo(np.int64).max)
    hi = np.full(npos, -1)
    np.minimum.at(lo, inverse, end_owner)
    np.maximum.at(hi, inverse, end_owner)
    single = np.where(lo == hi, lo, -1)  # owning line when a position holds one line's ends only
    pairs = cKDTree(pos).query_pairs(tolerance, output_type="ndarray")
    if len(pairs):
        same_line = (single[pairs[:, 0]] == single[pairs[:, 1]]) & (single[pairs[:, 0]] >= 0)
        pairs = pairs[~same_line]
    new_pos = pos.copy()
    if len(pairs):
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(npos, npos))
        _, comp = connected_components(graph, directed=False)
        # representative: most ends already there, then lowest x, lowest y
        order = np.lexsort((pos[:, 1], pos[:, 0], -mult))
        rank = np.empty(npos, dtype=np.int64)
        rank[order] = np.arange(npos)
        best = np.full(comp.max() + 1, npos, dtype=np.int64)
        np.minimum.at(best, comp, rank)
        rep = order[best[comp]]
        near = np.hypot(*(pos - pos[rep]).T) <= tolerance
        move = near & (rep != np.arange(npos))
        new_pos[move] = pos[rep[move]]
    new_ends = new_pos[inverse]
    moved = (new_ends != ends).any(axis=1)
    return new_ends, moved


def _touching(points: np.ndarray, point_owner: np.ndarray, lines: np.ndarray, tree, radius: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (point, other line) within ``radius``: point index, line index, distance."""
    geoms = shapely.points(points)
    pi, li = tree.query(geoms, predicate="dwithin", distance=radius)
    other = li != point_owner[pi]
    pi, li = pi[other], li[other]
    dist = shapely.distance(geoms[pi], lines[li]) if len(pi) else np.zeros(0)
    return pi, li, dist


def _free_end_targets(coords: np.ndarray, owner: np.ndarray, ends: np.ndarray,
                      end_owner: np.ndarray, n: int, tolerance: float, precision: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Vertex or segment target of every free end within reach (NaN where none).

    An end is free when no other line's end is at its position and no other line passes within
    :func:`touch_distance`; its target is the nearest vertex of another line within the tolerance,
    else the nearest point of the nearest other line.
    """
    work = shapely.linestrings(coords, indices=owner)
    tree = shapely.STRtree(work)
    pos, inverse = np.unique(ends, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    lo = np.full(len(pos), n)
    hi = np.full(len(pos), -1)
    np.minimum.at(lo, inverse, end_owner)
    np.maximum.at(hi, inverse, end_owner)
    cand_idx = np.flatnonzero(lo == hi)  # ends of a single line only
    pos_owner = lo
    pi, li, dist = _touching(pos[cand_idx], pos_owner[cand_idx], work, tree, tolerance)
    touching = np.zeros(len(cand_idx), dtype=bool)
    touching[pi[dist <= touch_distance(precision)]] = True
    reach = np.zeros(len(cand_idx), dtype=bool)
    reach[pi] = True
    free = reach & ~touching
    target = np.full((len(pos), 2), np.nan)
    target_kind = np.full(len(pos), "", dtype="<U7")
    if free.any():
        vtree = cKDTree(coords)
        order = np.argsort(pi, kind="stable")
        pi, li, dist = pi[order], li[order], dist[order]
        bounds = np.searchsorted(pi, np.arange(len(cand_idx) + 1))
        for k in np.flatnonzero(free):
            p = cand_idx[k]
            near = [v for v in vtree.query_ball_point(pos[p], tolerance) if owner[v] != pos_owner[p]]
            if near:
                near = np.asarray(near)
                d = np.hypot(*(coords[near] - pos[p]).T)
                best = np.lexsort((coords[near, 1], coords[near, 0], d))[0]
                target[p], target_kind[p] = coords[near[best]], VERTEX
                continue
            my_lines, my_dist = li[bounds[k]:bounds[k + 1]], dist[bounds[k]:bounds[k + 1]]
            line = work[my_lines[np.lexsort((my_lines, my_dist))[0]]]
            point = shapely.line_interpolate_point(line, shapely.line_locate_point(
                line, shapely.Point(pos[p])))
            target[p], target_kind[p] = shapely.get_coordinates(point)[0], SEGMENT
    return target[inverse], target_kind[inverse]


def snap_endpoints(lines: np.ndarray, tolerance: float, precision: float) -> SnapResult:
    """Move line ends onto nearby nodes, vertices or segments of other lines.

    Parameters
    ----------
    lines : (N,) array of 2D LineStrings (local coordinates, metres).
    tolerance : float
        Snap ("riattacco") distance; 0 returns the lines unchanged.
    precision : float
        Coordinate grid; an end closer than :func:`touch_distance` to another line already
        touches it.

    Returns
    -------
    SnapResult
    """
    lines = np.asarray(lines, dtype=object)
    n = len(lines)
    empty_f = np.zeros((0, 2))
    nothing = SnapResult(lines.copy(), np.arange(n), np.zeros(0, np.int64), np.zeros(0, np.int64),
                         np.zeros(0, np.int64), empty_f, empty_f, np.zeros(0, dtype="<U7"),
                         {NODE: 0, VERTEX: 0, SEGMENT: 0, "degenerate": 0})
    if n == 0 or tolerance <= 0:
        return nothing
    coords, owner, first, last = line_ends(lines)
    slots = np.column_stack([first, last]).ravel()  # vertex index of end 2i (start), 2i+1 (end)
    end_owner = np.repeat(np.arange(n), 2)
    ends = coords[slots]
    kinds = np.full(2 * n, "", dtype="<U7")
    # 1. ends onto nodes
    new_ends, moved = _cluster_ends(ends, end_owner, tolerance)
    kinds[moved] = NODE
    coords[slots] = new_ends
    # 2./3. ends still free: onto vertices, else segments, of other lines. Repeated until no end
    # moves, because an end snapped onto a segment whose own line end moves in the same round
    # is left off it (and would be snapped on a second run: the result must be a fixed point).
    final_ends = new_ends.copy()
    for _ in range(MAX_ROUNDS):
        coords[slots] = final_ends  # a closed line's two slots hold one position: they move together
        target, target_kind = _free_end_targets(coords, owner, final_ends, end_owner, n,
                                                tolerance, precision)
        has = ~np.isnan(target[:, 0])
        if not has.any():
            break
        final_ends[has] = target[has]
        kinds[has] = target_kind[has]
    coords[slots] = final_ends
    out = shapely.remove_repeated_points(shapely.linestrings(coords, indices=owner), 0.0)
    degenerate = shapely.length(out) == 0
    closed = (ends[0::2] == ends[1::2]).all(axis=1)
    kinds[1::2][closed] = ""  # a closed line's start and end are one node: report it once
    moved_any = kinds != ""
    result = SnapResult(
        lines=out[~degenerate], kept=np.flatnonzero(~degenerate),
        degenerate=np.flatnonzero(degenerate),
        move_line=end_owner[moved_any], move_end=np.tile([0, 1], n)[moved_any],
        move_from=ends[moved_any], move_to=final_ends[moved_any], move_kind=kinds[moved_any],
        counts={NODE: int(np.sum(kinds == NODE)), VERTEX: int(np.sum(kinds == VERTEX)),
                SEGMENT: int(np.sum(kinds == SEGMENT)), "degenerate": int(degenerate.sum())})
    return result
