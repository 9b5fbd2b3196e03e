"""The edge graph of noded linework: nodes, degrees, dangle chains, dangle and overshoot removal.

A *free end* is a node with one edge. A *dangle* is the chain of edges from a free end, through
nodes of degree 2, to a junction (degree >= 3); an *isolated chain* runs from a free end to another
free end (a line that bounds nothing: an unclosed polyline). A dangle that ends where the same input
line continues past the junction is an *overshoot* (the line was plotted beyond the line it meets).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely

from toolbox.topology.noding import grid_keys, pack_keys
from toolbox.topology.snap import line_ends


@dataclass
class EdgeGraph:
    """Nodes of a set of edges. ``start``/``end``: node index of each edge's first/last vertex;
    ``xy``: (nodes, 2) coordinates; ``incident``: CSR (``inc_ptr``, ``inc_edge``) of the edges at
    each node (a closed edge appears twice at its node)."""

    start: np.ndarray
    end: np.ndarray
    xy: np.ndarray
    inc_ptr: np.ndarray
    inc_edge: np.ndarray

    @property
    def n_nodes(self) -> int:
        return len(self.xy)

    def degree(self, alive: np.ndarray | None = None) -> np.ndarray:
        mask = np.ones(len(self.start), dtype=bool) if alive is None else alive
        return (np.bincount(self.start[mask], minlength=self.n_nodes)
                + np.bincount(self.end[mask], minlength=self.n_nodes))

    def edges_at(self, node: int) -> np.ndarray:
        return self.inc_edge[self.inc_ptr[node]:self.inc_ptr[node + 1]]


def edge_graph(edges: np.ndarray, precision: float) -> EdgeGraph:
    """Build the node table of ``edges`` (coordinates on the ``precision`` grid)."""
    coords, _, first, last = line_ends(edges)
    keys = grid_keys(np.concatenate([coords[first], coords[last]]), precision)
    packed = pack_keys(keys)
    uniq, first_at, inverse = np.unique(packed, return_index=True, return_inverse=True)
    m = len(edges)
    start, end = inverse[:m], inverse[m:]
    xy = np.concatenate([coords[first], coords[last]])[first_at]
    ends = np.concatenate([start, end])
    owner = np.concatenate([np.arange(m), np.arange(m)])
    order = np.lexsort((owner, ends))
    inc_ptr = np.concatenate([[0], np.cumsum(np.bincount(ends, minlength=len(uniq)))])
    return EdgeGraph(start, end, xy, inc_ptr, owner[order])


@dataclass
class Chain:
    """A dangle or isolated chain: its edges in order from the free end, the free node, the node
    where it stops (a junction, or the other free end when ``isolated``) and its length."""

    edges: list[int]
    free_node: int
    stop_node: int
    length: float
    isolated: bool


def dangle_chains(graph: EdgeGraph, lengths: np.ndarray, alive: np.ndarray) -> list[Chain]:
    """Every chain starting at a free end of the ``alive`` edges (an isolated chain once), in
    order of the free node's coordinates."""
    degree = graph.degree(alive)
    free = np.flatnonzero(degree == 1)
    free = free[np.lexsort((graph.xy[free, 1], graph.xy[free, 0]))]
    used = np.zeros(len(alive), dtype=bool)
    chains = []
    for f in free:
        here = [e for e in graph.edges_at(f) if alive[e]]
        edge = here[0]
        if used[edge]:
            continue  # the far end of an isolated chain already walked
        members = [edge]
        used[edge] = True
        node = graph.end[edge] if graph.start[edge] == f else graph.start[edge]
        while degree[node] == 2 and node != f:
            nxt = [e for e in graph.edges_at(node) if alive[e] and e != edge]
            if not nxt or used[nxt[0]]:
                break
            edge = nxt[0]
            members.append(edge)
            used[edge] = True
            node = graph.end[edge] if graph.start[edge] == node else graph.start[edge]
        chains.append(Chain(members, int(f), int(node), float(lengths[members].sum()),
                            bool(degree[node] == 1)))
    return chains


@dataclass
class DangleRemoval:
    """What :func:`remove_short_dangles` removed: chains (with ``kind`` ``overshoot``,
    ``dangle`` or ``isolated``) and the final ``alive`` mask of edges."""

    alive: np.ndarray
    removed: list[tuple[Chain, str]]


def _continues(chain: Chain, graph: EdgeGraph, indptr: np.ndarray, sources: np.ndarray,
               alive: np.ndarray) -> bool:
    """The input line of the chain's last edge goes on past the junction (an overshoot)."""
    last = chain.edges[-1]
    mine = set(sources[indptr[last]:indptr[last + 1]].tolist())
    for e in graph.edges_at(chain.stop_node):
        if e in chain.edges or not alive[e]:
            continue
        if mine & set(sources[indptr[e]:indptr[e + 1]].tolist()):
            return True
    return False


def remove_short_dangles(edges: np.ndarray, graph: EdgeGraph, indptr: np.ndarray,
                         sources: np.ndarray, min_length: float, alive: np.ndarray | None = None,
                         check_canceled: Callable[[], None] | None = None) -> DangleRemoval:
    """Remove dangle chains and isolated chains shorter than ``min_length``, repeatedly (removing
    one can turn its junction into a degree-2 node and expose a longer chain, which is judged on
    its full length in the next round).

    Parameters
    ----------
    edges : (E,) LineStrings; graph : their :class:`EdgeGraph`.
    indptr, sources : CSR provenance of the edges (see :mod:`toolbox.topology.noding`).
    min_length : float
        CRS units; 0 removes nothing.
    alive : (E,) bool, optional
        Edges still in the network (default all).
    """
    alive = np.ones(len(edges), dtype=bool) if alive is None else alive.copy()
    removed: list[tuple[Chain, str]] = []
    if min_length <= 0 or len(edges) == 0:
        return DangleRemoval(alive, removed)
    lengths = shapely.length(edges)
    while True:
        if check_canceled is not None:
            check_canceled()
        short = [c for c in dangle_chains(graph, lengths, alive) if c.length < min_length]
        if not short:
            break
        kinds = []
        for chain in short:
            if chain.isolated:
                kinds.append("isolated")
            else:
                kinds.append("overshoot" if _continues(chain, graph, indptr, sources, alive)
                             else "dangle")
        for chain, kind in zip(short, kinds, strict=True):
            alive[chain.edges] = False
            removed.append((chain, kind))
    return DangleRemoval(alive, removed)


def chain_geometry(edges: np.ndarray, chain: Chain) -> shapely.Geometry:
    """The chain's edges merged into one line (a MultiLineString if they do not merge)."""
    return shapely.line_merge(shapely.multilinestrings(edges[chain.edges]))
