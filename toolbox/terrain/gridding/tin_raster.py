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


class TinTiles:
    """Triangles of a TIN grouped by the tiles of ``grid`` they overlap.

    ``nodes`` are (N, 3) in coordinates relative to ``origin`` (a local origin keeps large
    projected coordinates precise); ``triangles`` (T, 3) node indices.
    """

    def __init__(self, nodes: np.ndarray, triangles: np.ndarray, grid: Any, tile_size: int,
                 origin: tuple[float, float] = (0.0, 0.0)):
        from toolbox.terrain.tin.kernels import triangles_by_tile

        t = grid.transform
        self.nodes = np.asarray(nodes, dtype="float64")
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.origin = origin
        self.order, self.start, _ = triangles_by_tile(
            self.nodes[:, :2], self.triangles, t.c - origin[0], t.f - origin[1], t.a, -t.e,
            grid.width, grid.height, tile_size)

    def plan(self, tile: Any) -> dict[str, np.ndarray] | None:
        """The tile's ``nodes`` and ``triangles`` (renumbered), None when no triangle touches
        it."""
        ids = self.order[self.start[tile.index]:self.start[tile.index + 1]]
        if not len(ids):
            return None
        used, inverse = np.unique(self.triangles[ids].ravel(), return_inverse=True)
        return {"nodes": np.ascontiguousarray(self.nodes[used]),
                "triangles": inverse.reshape(-1, 3).astype(np.int64)}


def tin_tile(origin: tuple[float, float], tile: Any, arrays: dict) -> np.ndarray:
    """Kernel: (h, w) float64 heights of the tile (no halo), NaN outside the triangles."""
    from toolbox.terrain.tin.kernels import rasterize_tin

    t = tile.core_transform
    h, w = tile.shape
    return rasterize_tin(arrays["nodes"], arrays["triangles"], t.c - origin[0], t.f - origin[1],
                         t.a, -t.e, w, h)
