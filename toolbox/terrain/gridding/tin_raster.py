"""A TIN drawn tile by tile onto a raster grid: the plane of the containing triangle at every
cell centre (thesis eq. [43]-[44]), exactly.

Shared by ``tin:to_raster`` and ``dem:tin_linear``: :class:`TinTiles` groups the triangles by
the output tiles they touch (once), its :meth:`~TinTiles.plan` gives each tile only its own
nodes and triangles (arrays, so a tile can run on a thread or a Dask worker), and
:func:`tin_tile` rasterises them (NaN outside the TIN).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit


class TinTiles:
    """Triangles of a TIN grouped by the tiles of ``grid`` they overlap.

    ``nodes`` are (N, 3) in coordinates relative to ``origin`` (a local origin keeps large
    projected coordinates precise); ``triangles`` (T, 3) node indices (held as int32, the
    triangulators' type: one compiled version of each kernel, half the memory of int64).
    """

    def __init__(self, nodes: np.ndarray, triangles: np.ndarray, grid: Any, tile_size: int,
                 origin: tuple[float, float] = (0.0, 0.0)):
        t = grid.transform
        self.nodes = np.ascontiguousarray(nodes, dtype="float64")
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int32)
        self.origin = origin
        self._slot: np.ndarray | None = None
        self.order, self.start = group_by_tile(
            self.nodes, self.triangles, t.c - origin[0], t.f - origin[1], t.a, -t.e,
            grid.width, grid.height, tile_size)

    def plan(self, tile: Any) -> dict[str, np.ndarray] | None:
        """The tile's ``nodes`` and ``triangles`` (renumbered), None when no triangle touches
        it."""
        ids = self.order[self.start[tile.index]:self.start[tile.index + 1]]
        if not len(ids):
            return None
        if self._slot is None:  # node -> its index in the tile being planned, -1: not in it
            self._slot = np.full(len(self.nodes), -1, dtype=np.int64)
        used = np.sort(_mark_nodes(self.triangles, ids, self._slot))  # ascending: the edge
        # tests evaluate each edge from its lower node index, as in the whole TIN
        nodes, triangles = _renumber(self.nodes, self.triangles, ids, used, self._slot)
        return {"nodes": nodes, "triangles": triangles}


@njit(cache=True, nogil=True)
def _mark_nodes(triangles, ids, slot):
    """The nodes of triangles ``ids`` (each once), marked in ``slot`` (scratch, one per node,
    all -1 before)."""
    used = np.empty(3 * len(ids), dtype=np.int64)
    m = 0
    for k in range(len(ids)):
        for j in range(3):
            v = triangles[ids[k], j]
            if slot[v] < 0:
                slot[v] = 0
                used[m] = v
                m += 1
    return used[:m]


@njit(cache=True, nogil=True)
def _renumber(nodes, triangles, ids, used, slot):
    """``nodes[used]`` and triangles ``ids`` renumbered to them; ``slot`` is left all -1."""
    m = len(used)
    out = np.empty((m, 3), dtype=np.float64)
    for i in range(m):
        v = used[i]
        slot[v] = i
        out[i, 0] = nodes[v, 0]
        out[i, 1] = nodes[v, 1]
        out[i, 2] = nodes[v, 2]
    local = np.empty((len(ids), 3), dtype=np.int64)
    for k in range(len(ids)):
        for j in range(3):
            local[k, j] = slot[triangles[ids[k], j]]
    for i in range(m):
        slot[used[i]] = -1
    return out, local


def tin_tile(origin: tuple[float, float], tile: Any, arrays: dict) -> np.ndarray:
    """Kernel: (h, w) float64 heights of the tile (no halo), NaN outside the triangles."""
    from toolbox.terrain.tin.kernels import rasterize_tin

    t = tile.core_transform
    h, w = tile.shape
    return rasterize_tin(arrays["nodes"], arrays["triangles"], t.c - origin[0], t.f - origin[1],
                         t.a, -t.e, w, h)


@njit(cache=True, nogil=True)
def _tile_range(xy, tri, k, x0, y0, cell_x, cell_y, width, height, tile):
    """Tile columns and rows (inclusive) whose cells triangle ``k``'s box may cover (one cell of
    margin: cell centres are what count); tx1 < tx0 when it covers none."""
    a, b, c = tri[k, 0], tri[k, 1], tri[k, 2]
    xmin = min(xy[a, 0], xy[b, 0], xy[c, 0])
    xmax = max(xy[a, 0], xy[b, 0], xy[c, 0])
    ymin = min(xy[a, 1], xy[b, 1], xy[c, 1])
    ymax = max(xy[a, 1], xy[b, 1], xy[c, 1])
    c_lo = np.floor((xmin - x0) / cell_x - 0.5)
    c_hi = np.ceil((xmax - x0) / cell_x - 0.5)
    r_lo = np.floor((y0 - ymax) / cell_y - 0.5)
    r_hi = np.ceil((y0 - ymin) / cell_y - 0.5)
    if c_hi < 0 or c_lo > width - 1 or r_hi < 0 or r_lo > height - 1:
        return 0, -1, 0, -1
    tx0 = int(max(c_lo, 0.0)) // tile
    tx1 = int(min(c_hi, width - 1.0)) // tile
    ty0 = int(max(r_lo, 0.0)) // tile
    ty1 = int(min(r_hi, height - 1.0)) // tile
    return tx0, tx1, ty0, ty1


@njit(cache=True, nogil=True)
def _group(xy, tri, x0, y0, cell_x, cell_y, width, height, tile, ntx, nty):
    start = np.zeros(ntx * nty + 1, dtype=np.int64)
    for k in range(tri.shape[0]):  # pass 1: triangles per tile
        tx0, tx1, ty0, ty1 = _tile_range(xy, tri, k, x0, y0, cell_x, cell_y, width, height,
                                         tile)
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                start[ty * ntx + tx + 1] += 1
    for i in range(ntx * nty):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    order = np.empty(start[-1], dtype=np.int32)
    for k in range(tri.shape[0]):  # pass 2: in triangle order within each tile
        tx0, tx1, ty0, ty1 = _tile_range(xy, tri, k, x0, y0, cell_x, cell_y, width, height,
                                         tile)
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                key = ty * ntx + tx
                order[fill[key]] = k
                fill[key] += 1
    return order, start


def group_by_tile(nodes: np.ndarray, triangles: np.ndarray, x0: float, y0: float,
                  cell_x: float, cell_y: float, width: int, height: int,
                  tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangles grouped by the ``tile`` x ``tile`` tiles (row by row from the top-left) their
    bounding boxes overlap, by counting sort in two passes (no temporary per triangle-tile
    pair): tile ``k``'s triangles are ``order[start[k]:start[k + 1]]`` (int32), in increasing
    index. ``nodes`` (N, 3) float64 and ``triangles`` (T, 3) int32, C-contiguous;
    ``(x0, y0)`` is the grid's top-left corner in the nodes' coordinates. The same grouping as
    :func:`toolbox.terrain.tin.kernels.triangles_by_tile`."""
    ntx = max(1, -(-int(width) // tile))
    nty = max(1, -(-int(height) // tile))
    return _group(nodes, triangles, float(x0), float(y0), float(cell_x), float(cell_y),
                  int(width), int(height), int(tile), ntx, nty)
