"""Node every crossing and store every piece of line once (thesis S002 §2.4: "incrocio fra linee
senza nodo di intersezione"; the shared edge of §2.2.2 exists once).

GEOS does the computational geometry: ``unary_union`` with a ``grid_size`` nodes the lines by snap
rounding to the coordinate grid (robust, and the same answer on every run), splits them at every
crossing and at every line end, and dissolves exact and overlapping duplicates. Each resulting
*edge* is then traced back to the input lines it came from with an STRtree, which gives the
duplicate counts and, later, the original codes of each arc.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from toolbox.topology.snap import line_ends


@dataclass
class NodingResult:
    """Noded, dissolved edges and their provenance.

    Attributes
    ----------
    edges : (E,) LineStrings, coordinates on the precision grid, meeting only at their ends.
    indptr, sources : CSR arrays: the input lines covering edge ``e`` are
        ``sources[indptr[e]:indptr[e + 1]]`` (sorted).
    crossings : (C, 2) float array, nodes where no input line had a vertex (lines crossed or
        touched without a node).
    self_intersecting : (S,) int array, input lines that cross or touch themselves.
    duplicate_edges : (D,) int array, edges plotted by more than one line.
    exact_duplicates : (X,) int array, input lines identical (as point sets) to a line with a
        lower index.
    counts : dict
    """

    edges: np.ndarray
    indptr: np.ndarray
    sources: np.ndarray
    crossings: np.ndarray
    self_intersecting: np.ndarray
    duplicate_edges: np.ndarray
    exact_duplicates: np.ndarray
    counts: dict[str, float] = field(default_factory=dict)

    def sources_of(self, edge: int) -> np.ndarray:
        return self.sources[self.indptr[edge]:self.indptr[edge + 1]]


def grid_keys(xy: np.ndarray, precision: float) -> np.ndarray:
    """Integer grid coordinates (N, 2) int64 of points already on (or near) the grid."""
    return np.rint(np.asarray(xy) / precision).astype(np.int64)


def points_along(lines: np.ndarray, fraction: float) -> np.ndarray:
    """(N, 2) points at ``fraction`` (0-1) of each line's length (numpy, no per-line calls)."""
    coords, owner = shapely.get_coordinates(lines, return_index=True)
    n = len(lines)
    seg = np.hypot(*np.diff(coords, axis=0).T)
    seg[owner[1:] != owner[:-1]] = 0.0  # no segment between two lines
    cum = np.concatenate([[0.0], np.cumsum(seg)])  # distance from the first line's start
    counts = np.bincount(owner, minlength=n)
    last = np.cumsum(counts) - 1
    first = last - counts + 1
    target = cum[first] + fraction * (cum[last] - cum[first])
    # segment k (coords k -> k+1) holding the target, inside the line
    k = np.clip(np.searchsorted(cum, target, side="right") - 1, first, np.maximum(last - 1, first))
    span = cum[k + 1] - cum[k]
    t = np.divide(target - cum[k], span, out=np.zeros(n), where=span > 0)
    return coords[k] + t[:, None] * (coords[k + 1] - coords[k])


def trace_sources(edges: np.ndarray, lines: np.ndarray, precision: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """CSR (indptr, sources) of the input lines lying along each edge.

    A line lies along an edge when it passes within one grid step of the edge's midpoint (snap
    rounding moves lines by at most ~0.71 grid step); when several lines do, each is confirmed at
    1/4 and 3/4 of the edge too, which drops a line merely crossing the edge there. An edge that
    no line matches (should not happen) takes the nearest line.
    """
    ne = len(edges)
    if ne == 0:
        return np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    tree = shapely.STRtree(lines)
    mids = shapely.points(points_along(edges, 0.5))
    edge_of, line_of = tree.query(mids, predicate="dwithin", distance=precision)
    # an edge with one candidate has found its line (some line always passes its midpoint);
    # several candidates are confirmed at 1/4 and 3/4 of the edge (lines crossing it there)
    several = np.bincount(edge_of, minlength=ne)[edge_of] > 1
    if several.any():
        check_e, check_l = edge_of[several], line_of[several]
        for fraction in (0.25, 0.75):
            pts = shapely.points(points_along(edges[check_e], fraction))
            ok = shapely.dwithin(pts, lines[check_l], precision)
            check_e, check_l = check_e[ok], check_l[ok]
        edge_of = np.concatenate([edge_of[~several], check_e])
        line_of = np.concatenate([line_of[~several], check_l])
    order = np.lexsort((line_of, edge_of))
    edge_of, line_of = edge_of[order].astype(np.int64), line_of[order].astype(np.int64)
    found = np.zeros(ne, dtype=bool)
    found[edge_of] = True
    missing = np.flatnonzero(~found)
    if len(missing):
        mids = shapely.line_interpolate_point(edges[missing], 0.5, normalized=True)
        qi, qj = tree.query_nearest(mids, all_matches=False)
        edge_of = np.concatenate([edge_of, missing[qi]])
        line_of = np.concatenate([line_of, qj])
        order = np.lexsort((line_of, edge_of))
        edge_of, line_of = edge_of[order], line_of[order]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(edge_of, minlength=ne))])
    return indptr.astype(np.int64), line_of.astype(np.int64)


def node_lines(lines: np.ndarray, precision: float) -> NodingResult:
    """Node and dissolve lines; trace each edge to its input lines.

    Parameters
    ----------
    lines : (N,) 2D LineStrings (local coordinates: snap rounding works on a grid anchored at 0,
        so keep coordinates small).
    precision : float
        Grid step of snap rounding, CRS units (e.g. 0.001 m).

    Returns
    -------
    NodingResult
    """
    lines = np.asarray(lines, dtype=object)
    n = len(lines)
    zero = np.zeros(0, dtype=np.int64)
    if n == 0:
        return NodingResult(np.zeros(0, dtype=object), np.zeros(1, np.int64), zero,
                            np.zeros((0, 2)), zero, zero, zero,
                            {"edges": 0, "crossings_noded": 0, "self_intersections": 0,
                             "exact_duplicates": 0, "duplicate_pieces": 0,
                             "duplicate_length": 0.0})
    merged = shapely.union_all(lines, grid_size=precision)
    edges = shapely.get_parts(merged)
    edges = edges[(shapely.get_type_id(edges) == 1) & (shapely.length(edges) > 0)]
    indptr, sources = trace_sources(edges, lines, precision)
    # crossings: nodes of the noded network that were no vertex of any input line
    coords, _, first, last = line_ends(edges)
    node_xy = np.concatenate([coords[first], coords[last]])
    node_packed, at = np.unique(pack_keys(grid_keys(node_xy, precision)), return_index=True)
    vertex_packed = pack_keys(grid_keys(shapely.get_coordinates(lines), precision))
    new = ~np.isin(node_packed, vertex_packed)
    crossings = grid_keys(node_xy[at[new]], precision) * precision
    # duplicates
    multiplicity = np.diff(indptr)
    duplicate_edges = np.flatnonzero(multiplicity > 1)
    exact = _exact_duplicates(indptr, sources, n)
    lengths = shapely.length(edges)
    counts = {
        "edges": len(edges),
        "crossings_noded": int(new.sum()),
        "self_intersections": 0,
        "exact_duplicates": len(exact),
        "duplicate_pieces": len(duplicate_edges),
        "duplicate_length": float(np.sum((multiplicity - 1) * lengths)),
    }
    simple = shapely.is_simple(lines)
    self_intersecting = np.flatnonzero(~simple)
    counts["self_intersections"] = len(self_intersecting)
    return NodingResult(edges, indptr, sources, crossings, self_intersecting, duplicate_edges,
                        exact, counts)


def pack_keys(keys: np.ndarray) -> np.ndarray:
    """One int64 per (N, 2) grid key, for sorting and set operations (|key| < 2**31)."""
    keys = np.asarray(keys, dtype=np.int64)
    if len(keys) and np.abs(keys).max() >= 2**31:
        raise ValueError("coordinates too large for the precision grid: shift them to a local "
                         "origin or use a coarser precision")
    return (keys[:, 0] << 32) + (keys[:, 1] + 2**31)


def _exact_duplicates(indptr: np.ndarray, sources: np.ndarray, n: int) -> np.ndarray:
    """Lines whose set of edges equals that of a lower-index line."""
    edge_of = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    order = np.lexsort((edge_of, sources))
    by_line = sources[order]
    edges_sorted = edge_of[order]
    bounds = np.searchsorted(by_line, np.arange(n + 1))
    seen: dict[tuple[int, ...], int] = {}
    duplicates = []
    for line in range(n):
        key = tuple(edges_sorted[bounds[line]:bounds[line + 1]].tolist())
        if not key:
            continue
        if key in seen:
            duplicates.append(line)
        else:
            seen[key] = line
    return np.asarray(duplicates, dtype=np.int64)


def self_intersection_points(line: shapely.Geometry, precision: float) -> list:
    """Points where a line crosses or touches itself (the line itself when none is found)."""
    parts = shapely.get_parts(shapely.node(line))
    coords, idx = shapely.get_coordinates(parts, return_index=True)
    counts = np.bincount(idx, minlength=len(parts))
    last = np.cumsum(counts) - 1
    first = last - counts + 1
    ends = np.concatenate([coords[first], coords[last]])
    keys, mult = np.unique(grid_keys(ends, precision), axis=0, return_counts=True)
    points = [shapely.Point(k * precision) for k in keys[mult >= 3]]
    return points or [line]
