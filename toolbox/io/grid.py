"""Output grid definition: extent + cell size (snapped) or a template raster, with a size guard.

Cells are square, north-up: ``transform = (cell, 0, xmin, 0, -cell, ymax)``. A cell's value belongs
to its centre (thesis par. 2.5.2): column ``j`` has centre ``xmin + (j + 0.5) * cell``.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import ParameterError

DEFAULT_MAX_CELLS = 1_000_000_000  # overridable with the TOOLBOX_MAX_CELLS environment variable


def max_cells_default() -> int:
    """The grid-size limit: ``TOOLBOX_MAX_CELLS`` from the environment, else 1e9 (the "cells"
    limit of :mod:`toolbox.limits`, shared by every size guard)."""
    from toolbox.limits import size_limit

    return size_limit("cells")


def coordinate_rounding(*coordinates: float) -> float:
    """The rounding a computation on ``coordinates`` carries (their units): 64 ulps of the
    largest (a northing of 5,000,000 has 1e-9 m bits)."""
    return 64 * max((abs(float(c)) for c in coordinates), default=0.0) * sys.float_info.epsilon


def cell_slack(cell_size: float, *coordinates: float) -> float:
    """How far (in cells) a count of cells computed from ``coordinates`` may be from a whole
    number by rounding alone: 1e-9 cell, more for coordinates so large that their last bit is
    more (:func:`coordinate_rounding`: 2e-7 of a 5 mm cell at a northing of 5,000,000)."""
    return max(1e-9, coordinate_rounding(*coordinates) / cell_size)


def snap_outwards(bounds: tuple[float, float, float, float],
                  cell_size: float) -> tuple[float, float, float, float]:
    """``bounds`` moved outwards to multiples of ``cell_size``; an edge within rounding of a
    multiple stays on it (:func:`cell_slack`): a corner computed 1 ulp beyond a multiple,
    1688120.0000000002, must not add a whole cell."""
    xmin, ymin, xmax, ymax = map(float, bounds)
    slack = cell_slack(cell_size, xmin, ymin, xmax, ymax)  # cells
    return (math.floor(xmin / cell_size + slack) * cell_size,
            math.floor(ymin / cell_size + slack) * cell_size,
            math.ceil(xmax / cell_size - slack) * cell_size,
            math.ceil(ymax / cell_size - slack) * cell_size)


@dataclass(frozen=True)
class GridSpec:
    """A north-up raster grid: affine ``transform``, ``width`` x ``height`` cells, ``crs``."""

    transform: Any
    width: int
    height: int
    crs: Any = None

    @classmethod
    def from_bounds(cls, bounds: tuple[float, float, float, float], cell_size: float,
                    crs: Any = None, snap: bool = True, max_cells: int | None = None,
                    name: str = "CELL_SIZE") -> GridSpec:
        """Grid covering ``bounds`` (xmin, ymin, xmax, ymax); with ``snap`` the edges are moved
        outwards to multiples of ``cell_size`` (so grids from different runs align)."""
        from affine import Affine

        if not cell_size > 0:
            raise ParameterError(name, f"must be > 0, got {cell_size}")
        xmin, ymin, xmax, ymax = map(float, bounds)
        limit = max_cells_default() if max_cells is None else max_cells
        across, down = (xmax - xmin) / cell_size, (ymax - ymin) / cell_size
        far = max(abs(xmin), abs(xmax), abs(ymin), abs(ymax)) / cell_size
        if not (math.isfinite(across) and math.isfinite(down) and math.isfinite(far)):
            raise ParameterError(name, f"{cell_size:g} is too small for the extent (the grid "
                                 f"would have more than {limit:,} cells); use a larger cell size")
        if snap:
            xmin, ymin, xmax, ymax = snap_outwards((xmin, ymin, xmax, ymax), cell_size)
        width = max(1, int(round((xmax - xmin) / cell_size)))
        height = max(1, int(round((ymax - ymin) / cell_size)))
        if width * height > limit:
            raise ParameterError(name, f"{cell_size:g} gives a {width} x {height} grid "
                                 f"({width * height:,} cells), over the limit of {limit:,} cells; "
                                 "use a larger cell size or a smaller extent (or raise "
                                 "TOOLBOX_MAX_CELLS)")
        return cls(Affine(cell_size, 0.0, xmin, 0.0, -cell_size, ymin + height * cell_size),
                   width, height, crs)

    @classmethod
    def from_raster(cls, info: Any) -> GridSpec:
        """Grid of an existing raster (a :class:`~toolbox.io.raster.RasterInfo`)."""
        return cls(info.transform, info.width, info.height, info.crs)

    @property
    def cell_size(self) -> tuple[float, float]:
        return (abs(self.transform.a), abs(self.transform.e))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        t = self.transform
        return (t.c, t.f + t.e * self.height, t.c + t.a * self.width, t.f)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    def cell_centers(self, window: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """1-D x of column centres and y of row centres, for the whole grid or a window."""
        col0, row0, w, h = (0, 0, self.width, self.height) if window is None else (
            int(window.col_off), int(window.row_off), int(window.width), int(window.height))
        t = self.transform
        x = t.c + (np.arange(col0, col0 + w) + 0.5) * t.a
        y = t.f + (np.arange(row0, row0 + h) + 0.5) * t.e
        return x, y

    def window_transform(self, window: Any):
        """The affine transform of a window of the grid (rasterio's ``windows.transform``,
        written out: the same arithmetic, without its per-call deprecation warnings)."""
        from affine import Affine

        t, col, row = self.transform, window.col_off, window.row_off
        return Affine(t.a, t.b, t.a * col + t.b * row + t.c, t.d, t.e, t.d * col + t.e * row + t.f)
