"""Close polylines whose ends miss ("chiusura delle polilinee non connesse formanti un'area",
thesis S002 §2.4; "tolleranza di chiusura", §2.2.1).

A polyline is closed when both of its ends are free (they touch no other line), they are at most
the closure tolerance apart, and it has at least three distinct vertices. It is closed by a
closing segment from its end to its start: every vertex the operator plotted stays where it was,
other lines snapped onto it stay on it, and the result does not depend on the direction the line
was plotted in (moving one end onto the other would).

A polyline plotted in several pieces is only seen as one after noding: :func:`chain_closures`
closes an *isolated* chain of lines (free end to free end) whose ends miss by at most the
tolerance the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from toolbox.topology.graph import dangle_chains, edge_graph
from toolbox.topology.noding import NodingResult, grid_keys
from toolbox.topology.snap import line_ends, touch_distance


@dataclass
class ClosureResult:
    """Attributes: ``lines`` (same order as the input), ``closed`` (indices closed), ``gaps``
    (their end-to-end distance before closing), and ``open_free`` / ``open_gaps``: open lines with
    both ends free that were *not* closed (gap above the tolerance), with their gaps."""

    lines: np.ndarray
    closed: np.ndarray
    gaps: np.ndarray
    open_free: np.ndarray
    open_gaps: np.ndarray


def free_ends(lines: np.ndarray, precision: float) -> np.ndarray:
    """(N, 2) bool: start / end of each line touches no *other* line."""
    n = len(lines)
    if n == 0:
        return np.zeros((0, 2), dtype=bool)
    coords, _, first, last = line_ends(lines)
    points = shapely.points(np.column_stack([coords[first], coords[last]]).reshape(-1, 2))
    owner = np.repeat(np.arange(n), 2)
    pi, li = shapely.STRtree(lines).query(points, predicate="dwithin",
                                          distance=touch_distance(precision))
    touched = np.zeros(2 * n, dtype=bool)
    touched[pi[li != owner[pi]]] = True
    return ~touched.reshape(n, 2)


def close_lines(lines: np.ndarray, tolerance: float, precision: float) -> ClosureResult:
    """Close free-ended polylines whose ends miss by at most ``tolerance``.

    Parameters
    ----------
    lines : (N,) array of 2D LineStrings (local coordinates).
    tolerance : float
        Closure tolerance, CRS units; 0 closes nothing (but still reports open lines).
    precision : float
        Coordinate grid (see :func:`toolbox.topology.snap.touch_distance`).
    """
    lines = np.asarray(lines, dtype=object).copy()
    n = len(lines)
    none = np.zeros(0, dtype=np.int64)
    if n == 0:
        return ClosureResult(lines, none, np.zeros(0), none, np.zeros(0))
    coords, owner, first, last = line_ends(lines)
    gap = np.hypot(*(coords[last] - coords[first]).T)
    free = free_ends(lines, precision).all(axis=1)
    open_free = free & (gap > touch_distance(precision))
    closable = open_free & (gap <= tolerance)
    for i in np.flatnonzero(closable):  # few: closing needs three distinct vertices
        closable[i] = len(np.unique(coords[first[i]:last[i] + 1], axis=0)) >= 3
    for i in np.flatnonzero(closable):
        ring = coords[first[i]:last[i] + 1]
        lines[i] = shapely.linestrings(np.concatenate([ring, ring[:1]]))
    rest = open_free & ~closable
    return ClosureResult(lines, np.flatnonzero(closable), gap[closable], np.flatnonzero(rest),
                         gap[rest])


def chain_closures(noding: NodingResult, tolerance: float, precision: float
                   ) -> list[tuple[shapely.Geometry, list[int], float]]:
    """Closing segments for isolated chains of several lines whose free ends miss by at most
    ``tolerance``: ``[(segment from the chain's far end to its first free end, the chain's
    line indices, gap), ...]``. Single lines are left to :func:`close_lines` (before noding).
    """
    edges = noding.edges
    if tolerance <= 0 or len(edges) == 0:
        return []
    graph = edge_graph(edges, precision)
    out = []
    for chain in dangle_chains(graph, shapely.length(edges), np.ones(len(edges), dtype=bool)):
        if not chain.isolated:
            continue
        a, b = graph.xy[chain.stop_node], graph.xy[chain.free_node]
        gap = float(np.hypot(*(a - b)))
        chain_lines = sorted({int(r) for e in chain.edges for r in noding.sources_of(e)})
        if len(chain_lines) < 2 or not touch_distance(precision) < gap <= tolerance:
            continue
        coords = shapely.get_coordinates(edges[chain.edges])
        if len(np.unique(grid_keys(coords, precision), axis=0)) < 3:
            continue
        out.append((shapely.LineString([a, b]), chain_lines, gap))
    return out
