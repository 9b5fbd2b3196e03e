"""Arcs and nodes: each boundary stored once, pointed to by the areas on its two sides.

The thesis' rule (S002 §2.2.2): the edge 2-5 shared by building B and pavement C exists once and
is referenced by both areas. An *arc* here is a maximal chain of edges through nodes where exactly
two edges meet and the original line codes do not change; it keeps the set of input lines (and so
codes) it came from. Nodes are the arcs' end points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from toolbox.topology.graph import EdgeGraph
from toolbox.topology.labels import blank_mask
from toolbox.topology.noding import grid_keys, pack_keys


@dataclass
class Arcs:
    """Arcs built from edges.

    Attributes
    ----------
    geoms : (A,) LineStrings, each starting at its lower (x, y) end; a closed arc runs
        counter-clockwise from its lowest (x, y) vertex (or from the node attaching it).
    members : (E,) int array, arc index of each edge.
    src_ptr, src_rows : CSR arrays, the sorted input lines of arc ``a`` are
        ``src_rows[src_ptr[a]:src_ptr[a + 1]]``.
    code_key : (A,) object array, the ``;``-joined sorted set of input codes.
    """

    geoms: np.ndarray
    members: np.ndarray
    src_ptr: np.ndarray
    src_rows: np.ndarray
    code_key: np.ndarray

    def sources(self, arc: int) -> np.ndarray:
        return self.src_rows[self.src_ptr[arc]:self.src_ptr[arc + 1]]


def code_keys(indptr: np.ndarray, sources: np.ndarray, line_codes: np.ndarray) -> np.ndarray:
    """``;``-joined sorted distinct codes of the input lines along each edge ('' if none)."""
    line_codes = np.asarray(line_codes, dtype=object)
    text = np.where(blank_mask(line_codes), "", line_codes.astype(str)).astype(object)
    counts = np.diff(indptr)
    out = np.full(len(counts), "", dtype=object)
    single = counts == 1
    out[single] = text[sources[indptr[:-1][single]]]
    for e in np.flatnonzero(counts > 1):
        out[e] = ";".join(sorted({text[s] for s in sources[indptr[e]:indptr[e + 1]]} - {""}))
    return out


def _ring_starts(lines: np.ndarray, precision: float, free_ring: np.ndarray) -> np.ndarray:
    """Closed lines counter-clockwise, each from its lowest (x, y) vertex when it touches nothing
    else (``free_ring``), else from the node where it is attached (all rings at once)."""
    coords, owner = shapely.get_coordinates(lines, return_index=True)
    counts = np.bincount(owner, minlength=len(lines))
    keep = np.ones(len(coords), dtype=bool)
    keep[np.cumsum(counts) - 1] = False  # the closing vertex
    coords, owner = coords[keep], owner[keep]
    n = counts - 1
    start = np.cumsum(n) - n
    local = np.arange(len(coords)) - start[owner]
    # lowest (x, y) on the grid, the first of equals (lexsort is stable), for free rings
    k = grid_keys(coords, precision)
    lowest = np.lexsort((k[:, 1], k[:, 0], owner))[start] - start
    lowest[~np.asarray(free_ring, dtype=bool)] = 0
    ring = np.empty_like(coords)
    ring[start[owner] + (local - lowest[owner]) % n[owner]] = coords
    # clockwise rings: the same start, the other vertices in reverse
    cw = ~shapely.is_ccw(shapely.linearrings(ring, indices=owner))
    flip = cw[owner] & (local > 0)
    at = np.where(flip, n[owner] - local, local)
    out = np.empty_like(ring)
    out[start[owner] + at] = ring
    # close again with the start vertex
    closed = np.insert(out, np.cumsum(n), out[start], axis=0)
    return shapely.linestrings(closed, indices=np.repeat(np.arange(len(lines)), n + 1))


def build_arcs(edges: np.ndarray, graph: EdgeGraph, indptr: np.ndarray, sources: np.ndarray,
               line_codes: np.ndarray, precision: float) -> Arcs:
    """Merge edges into arcs through degree-2 nodes where the code set does not change.

    Parameters
    ----------
    edges : (E,) LineStrings (the cleaned network); graph : their :class:`EdgeGraph`.
    indptr, sources : CSR provenance (input line indices) of each edge.
    line_codes : (N,) code of each input line.
    precision : float, coordinate grid.
    """
    m = len(edges)
    if m == 0:
        zero = np.zeros(0, np.int64)
        return Arcs(np.zeros(0, dtype=object), zero, np.zeros(1, np.int64), zero,
                    np.zeros(0, object))
    keys = code_keys(indptr, sources, line_codes)
    degree = graph.degree()
    # pairs of edges meeting at a degree-2 node with the same code key
    inc_counts = np.diff(graph.inc_ptr)
    two = np.flatnonzero((degree == 2) & (inc_counts == 2))
    a = graph.inc_edge[graph.inc_ptr[two]]
    b = graph.inc_edge[graph.inc_ptr[two] + 1]
    link = (a != b) & (keys[a] == keys[b])
    a, b = a[link], b[link]
    adjacency = coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m))
    n_arcs, members = connected_components(adjacency, directed=False)
    # number arcs by their first edge (GEOS order) for a stable result
    first_edge = np.full(n_arcs, m, dtype=np.int64)
    np.minimum.at(first_edge, members, np.arange(m))
    order = np.argsort(first_edge)
    rank = np.empty(n_arcs, dtype=np.int64)
    rank[order] = np.arange(n_arcs)
    members = rank[members]
    by_arc = np.argsort(members, kind="stable")
    geoms = shapely.line_merge(shapely.multilinestrings(edges[by_arc], indices=members[by_arc]))
    for i in np.flatnonzero(shapely.get_type_id(geoms) != 1):
        raise RuntimeError(f"arc {i} did not merge into one line: {geoms[i].wkt[:200]}")
    # canonical direction: open arcs from the lower (x, y) end
    coords, owner = shapely.get_coordinates(geoms, return_index=True)
    counts = np.bincount(owner, minlength=n_arcs)
    last = np.cumsum(counts) - 1
    first = last - counts + 1
    k0, k1 = grid_keys(coords[first], precision), grid_keys(coords[last], precision)
    closed = (k0 == k1).all(axis=1)
    backwards = ~closed & ((k1[:, 0] < k0[:, 0]) | ((k1[:, 0] == k0[:, 0]) & (k1[:, 1] < k0[:, 1])))
    geoms[backwards] = shapely.reverse(geoms[backwards])
    if closed.any():
        node_keys = pack_keys(grid_keys(graph.xy, precision))
        sorter = np.argsort(node_keys)
        at = sorter[np.searchsorted(node_keys, pack_keys(k0[closed]), sorter=sorter)]
        geoms[closed] = _ring_starts(geoms[closed], precision, degree[at] == 2)
    # input lines of each arc
    entry_arc = members[np.repeat(np.arange(m), np.diff(indptr))]
    n_lines = int(sources.max()) + 1 if len(sources) else 1
    pairs = np.unique(entry_arc.astype(np.int64) * n_lines + sources)
    src_rows = pairs % n_lines
    src_ptr = np.searchsorted(pairs // n_lines, np.arange(n_arcs + 1)).astype(np.int64)
    code_key = np.empty(n_arcs, dtype=object)
    code_key[members] = keys
    return Arcs(geoms, members, src_ptr, src_rows, code_key)


@dataclass
class Nodes:
    """Arc end points: ``xy`` (K, 2), ``degree`` (arc ends there; a closed arc counts 2) and
    ``kind``: ``junction`` (>= 3), ``end`` (1: a free end), ``pseudo`` (2 arcs: the code changes),
    ``ring`` (start of a closed arc touching nothing)."""

    xy: np.ndarray
    degree: np.ndarray
    kind: np.ndarray


def build_nodes(arcs: np.ndarray, precision: float) -> Nodes:
    """Nodes of the arcs, sorted by (x, y)."""
    if len(arcs) == 0:
        return Nodes(np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, dtype=object))
    coords, owner = shapely.get_coordinates(arcs, return_index=True)
    counts = np.bincount(owner, minlength=len(arcs))
    last = np.cumsum(counts) - 1
    first = last - counts + 1
    ends = np.concatenate([coords[first], coords[last]])
    packed = pack_keys(grid_keys(ends, precision))
    uniq, first_at, inverse, degree = np.unique(packed, return_index=True, return_inverse=True,
                                                return_counts=True)
    xy = ends[first_at]
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    xy, degree = xy[order], degree[order]
    closed_start = np.zeros(len(uniq), dtype=bool)
    closed = packed[: len(arcs)] == packed[len(arcs):]
    ring_nodes = inverse[: len(arcs)][closed]
    only_ring = np.zeros(len(uniq), dtype=bool)
    only_ring[ring_nodes] = True
    closed_start = only_ring[order] & (degree == 2)
    kind = np.where(degree >= 3, "junction", np.where(degree == 1, "end", "pseudo")).astype(object)
    kind[closed_start] = "ring"
    return Nodes(xy, degree, kind)
