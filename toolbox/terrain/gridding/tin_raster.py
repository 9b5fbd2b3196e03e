"""A TIN drawn tile by tile onto a raster grid: the plane of the containing triangle at every
cell centre (thesis eq. [43]-[44]), exactly.

Shared by ``tin:to_raster`` and ``dem:tin_linear``: :class:`TinTiles` groups the triangles by
the output tiles they touch (once), its :meth:`~TinTiles.plan` gives each tile only its own
nodes and triangles (arrays, so a tile can run on a thread or a Dask worker), and
:func:`tin_tile` rasterises them (NaN outside the TIN).

Two equal paths (same grouping, same renumbering, same cell values): the compiled kernels of
:mod:`toolbox.terrain.tin.planes` (``compiled=True``), and numpy ones for small runs
(``compiled=False``: :func:`~toolbox.terrain.tin.kernels.triangles_by_tile`, ``np.unique`` and
:mod:`toolbox.terrain.tin.planes_numpy`), which never import numba.
"""

from __future__ import annotations

from typing import Any

import numpy as np


class TinTiles:
    """Triangles of a TIN grouped by the tiles of ``grid`` they overlap.

    ``nodes`` are (N, 3) in coordinates relative to ``origin`` (a local origin keeps large
    projected coordinates precise); ``triangles`` (T, 3) node indices (held as int32, the
    triangulators' type: one compiled version of each kernel, half the memory of int64).
    ``compiled``: numba kernels (True) or numpy (False, no numba import; see the module notes).
    """

    def __init__(self, nodes: np.ndarray, triangles: np.ndarray, grid: Any, tile_size: int,
                 origin: tuple[float, float] = (0.0, 0.0), compiled: bool = True):
        t = grid.transform
        self.nodes = np.ascontiguousarray(nodes, dtype="float64")
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int32)
        self.origin = origin
        self.compiled = compiled
        self._slot: np.ndarray | None = None
        box = (t.c - origin[0], t.f - origin[1], t.a, -t.e, grid.width, grid.height, tile_size)
        if compiled:
            self.order, self.start = group_by_tile(self.nodes, self.triangles, *box)
        else:
            from toolbox.terrain.tin.kernels import triangles_by_tile

            self.order, self.start, _ = triangles_by_tile(self.nodes, self.triangles, *box)

    def plan(self, tile: Any) -> dict[str, np.ndarray] | None:
        """The tile's ``nodes`` and ``triangles`` (renumbered), None when no triangle touches
        it."""
        ids = self.order[self.start[tile.index]:self.start[tile.index + 1]]
        if not len(ids):
            return None
        if not self.compiled:
            triangles = self.triangles[ids]
            used, local = np.unique(triangles, return_inverse=True)  # ascending, as below
            return {"nodes": self.nodes[used], "triangles": local.reshape(triangles.shape)}
        from toolbox.terrain.tin.planes import _mark_nodes, _renumber

        if self._slot is None:  # node -> its index in the tile being planned, -1: not in it
            self._slot = np.full(len(self.nodes), -1, dtype=np.int64)
        used = np.sort(_mark_nodes(self.triangles, ids, self._slot))  # ascending: the edge
        # tests evaluate each edge from its lower node index, as in the whole TIN
        nodes, triangles = _renumber(self.nodes, self.triangles, ids, used, self._slot)
        return {"nodes": nodes, "triangles": triangles}


def tin_tile(origin: tuple[float, float], tile: Any, arrays: dict,
             compiled: bool = True) -> np.ndarray:
    """Kernel: (h, w) float64 heights of the tile (no halo), NaN outside the triangles
    (``compiled``: numba, else numpy)."""
    from toolbox.terrain.tin.kernels import rasterize_tin

    t = tile.core_transform
    h, w = tile.shape
    return rasterize_tin(arrays["nodes"], arrays["triangles"], t.c - origin[0], t.f - origin[1],
                         t.a, -t.e, w, h, compiled=compiled,
                         magnitude=max(abs(t.c), abs(t.f)))


def group_by_tile(nodes: np.ndarray, triangles: np.ndarray, x0: float, y0: float,
                  cell_x: float, cell_y: float, width: int, height: int,
                  tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangles grouped by the ``tile`` x ``tile`` tiles (row by row from the top-left) their
    bounding boxes overlap, by counting sort in two passes (no temporary per triangle-tile
    pair): tile ``k``'s triangles are ``order[start[k]:start[k + 1]]`` (int32), in increasing
    index. ``nodes`` (N, 3) float64 and ``triangles`` (T, 3) int32, C-contiguous;
    ``(x0, y0)`` is the grid's top-left corner in the nodes' coordinates. The same grouping as
    :func:`toolbox.terrain.tin.kernels.triangles_by_tile`."""
    from toolbox.terrain.tin.planes import _group

    ntx = max(1, -(-int(width) // tile))
    nty = max(1, -(-int(height) // tile))
    return _group(nodes, triangles, float(x0), float(y0), float(cell_x), float(cell_y),
                  int(width), int(height), int(tile), ntx, nty)
