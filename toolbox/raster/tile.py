"""Tiles of an output grid: the unit of work of the raster engine and the warp (picklable)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.io.grid import GridSpec


@dataclass(frozen=True)
class Tile:
    """One tile of an output grid (picklable).

    ``window`` is the part of the output this tile writes (no halo); the kernel's input arrays
    cover :attr:`haloed_window`, ``halo`` cells more on every side (also beyond the grid's
    edges: see the boundary rules of :func:`read_window`). ``grid_transform`` is the output
    grid's transform.
    """

    index: int
    window: Any  # rasterio.windows.Window
    halo: int
    grid_transform: Any  # affine.Affine

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the tile without halo."""
        return (int(self.window.height), int(self.window.width))

    @property
    def haloed_shape(self) -> tuple[int, int]:
        h, w = self.shape
        return (h + 2 * self.halo, w + 2 * self.halo)

    @property
    def haloed_window(self) -> Any:
        from rasterio.windows import Window

        h = self.halo
        return Window(int(self.window.col_off) - h, int(self.window.row_off) - h,
                      int(self.window.width) + 2 * h, int(self.window.height) + 2 * h)

    @property
    def transform(self) -> Any:
        """Transform of the haloed window (its top-left cell corner -> map)."""
        return _window_transform(self.grid_transform, self.haloed_window)

    @property
    def core_transform(self) -> Any:
        """Transform of the tile without halo."""
        return _window_transform(self.grid_transform, self.window)

    @property
    def crop(self) -> tuple[slice, slice]:
        """Slices cutting the tile out of a haloed array: ``array[..., *tile.crop]``."""
        h, (rows, cols) = self.halo, self.shape
        return (slice(h, h + rows), slice(h, h + cols))

    def cell_centres(self, origin: tuple[float, float] = (0.0, 0.0),
                     halo: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """1-D float64 x of the column centres and y of the row centres (haloed window by
        default), minus ``origin`` (a local origin keeps large map coordinates precise)."""
        w = self.haloed_window if halo else self.window
        t = self.grid_transform
        j = np.arange(int(w.col_off), int(w.col_off) + int(w.width)) + 0.5
        i = np.arange(int(w.row_off), int(w.row_off) + int(w.height)) + 0.5
        return (t.c - origin[0]) + j * t.a, (t.f - origin[1]) + i * t.e

    def sub_tile(self, window: Any) -> Tile:
        """The tile of a part ``window`` of this one (same halo)."""
        return Tile(self.index, window, self.halo, self.grid_transform)


def _window_transform(transform: Any, window: Any) -> Any:
    """Transform of ``window`` (its top-left cell corner -> map); the window may lie partly
    outside the grid (negative offsets)."""
    t, col, row = transform, int(window.col_off), int(window.row_off)
    return t.__class__(t.a, t.b, t.c + col * t.a + row * t.b, t.d, t.e, t.f + col * t.d + row * t.e)


def iter_tiles(grid: GridSpec, tile_size: int = 512, halo: int = 0) -> Iterator[Tile]:
    """The tiles of ``grid``, row by row: ``tile_size`` x ``tile_size`` cells (smaller at the
    east and south edges), each with ``halo`` cells of margin. Use the writer's block size (or
    a multiple) so that writes align with the GeoTIFF blocks."""
    from rasterio.windows import Window

    if tile_size <= 0 or halo < 0:
        raise ValueError(f"tile_size must be > 0 and halo >= 0, got {tile_size}, {halo}")
    index = 0
    for row0 in range(0, grid.height, tile_size):
        for col0 in range(0, grid.width, tile_size):
            window = Window(col0, row0, min(tile_size, grid.width - col0),
                            min(tile_size, grid.height - row0))
            yield Tile(index, window, int(halo), grid.transform)
            index += 1


def tile_count(grid: GridSpec, tile_size: int = 512) -> int:
    return math.ceil(grid.width / tile_size) * math.ceil(grid.height / tile_size)
