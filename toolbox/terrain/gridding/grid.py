"""Step 2 of a gridding run: the output grid (the raster engine's grid rules) and which cells
are computed (convex hull of the data, MASK polygons); plus the neighbour planner that tells
each tile which data points it needs."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.io.grid import GridSpec
from toolbox.terrain.gridding.inputs import GriddingData
from toolbox.terrain.gridding.masks import convex_hull, hull_mask, polygon_mask
from toolbox.terrain.gridding.neighbours import PointBins
from toolbox.terrain.gridding.request import DEFAULT_TILE, GriddingRequest


@dataclass
class GridRun:
    """The grid of one run and its cell selection.

    ``hull`` is the local convex hull ring of the data (None: no hull limit);
    ``mask_geometry`` a shapely (multi)polygon in map coordinates (None: no MASK).
    """

    data: GriddingData
    grid: GridSpec
    tile: int
    hull: np.ndarray | None
    mask_geometry: Any
    nodata: float

    @property
    def origin(self) -> tuple[float, float]:
        return (float(self.data.origin[0]), float(self.data.origin[1]))

    @property
    def single_tile(self) -> bool:
        """True when the whole grid is one tile."""
        from toolbox.raster.tile import tile_count

        return tile_count(self.grid, self.tile) == 1

    def cell_mask(self, tile: Any, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Cells of ``tile`` (local centres ``xs``, ``ys``) to compute: inside the hull and
        the MASK."""
        mask = np.ones((len(ys), len(xs)), dtype=bool)
        if self.hull is not None:  # a centre on the hull is in, up to the map coordinates'
            # rounding (at a northing of 10,000,000 a whole border row fell out)
            from toolbox.io.grid import cell_slack

            cell = max(self.grid.cell_size)
            tol = cell_slack(cell, *self.grid.bounds) * cell
            mask &= hull_mask(self.hull, xs, ys, tol)
        if self.mask_geometry is not None and mask.any():
            mask &= polygon_mask(self.mask_geometry, tile.core_transform, mask.shape)
        return mask


def prepare_grid(request: GriddingRequest, data: GriddingData,
                 limit_to_hull: bool = True) -> GridRun:
    """The output grid and the cell selection of a run (after reading the data)."""
    grid = request.grid.grid(data.bounds, data.crs)
    cells = request.cells
    hull = None
    if limit_to_hull and not cells.extrapolate:
        from toolbox.terrain.points import CollinearError, check_not_collinear

        try:
            check_not_collinear(data.local[:, :2], "data points (after merging duplicate XY)")
        except ValueError as exc:
            hint = " (set EXTRAPOLATE to compute cells beyond their hull)" \
                if isinstance(exc, CollinearError) else ""
            raise InputDataError(f"{exc}{hint}") from None
        hull = convex_hull(data.local[:, :2])
        if hull is None:
            raise InputDataError(f"the {len(data.xyz)} data points are collinear: their convex "
                                 "hull has no area and every cell would be nodata (set "
                                 "EXTRAPOLATE to compute cells beyond the hull)")
    mask_geometry = None
    if cells.mask is not None:
        from shapely import union_all

        from toolbox.io.vector import read_vector

        frame = read_vector(cells.mask, name="MASK")
        mask_geometry = union_all(frame.geometry.values)
    return GridRun(data, grid, int(request.execution.tile_size or DEFAULT_TILE), hull,
                   mask_geometry, float(cells.nodata))


class NeighbourPlanner:
    """Chooses the points a tile needs for k-nearest-neighbour methods.

    For a tile whose computed cells span the box B, every cell's k nearest points lie within
    ``halo`` of B, where ``halo = max d_k(s) + spacing·√2/2`` over sample centres s laid every
    ``spacing`` over B (``d_k`` is 1-Lipschitz); with a search radius, ``halo <= radius``.
    """

    def __init__(self, local_xyz: np.ndarray, k: int, radius: float | None,
                 bins: PointBins | None = None, single_tile: bool = False):
        self.xyz = local_xyz
        self.bins = bins if bins is not None else PointBins.build(local_xyz[:, :2])
        self.k = max(0, int(k))  # 0: every point within the radius
        self.radius = math.inf if radius is None else float(radius)
        #: one tile: it gets every point (no search; on a first run, two kernels less to
        #: compile)
        self.single_tile = single_tile

    def halo(self, x0: float, y0: float, x1: float, y1: float, cell: float) -> float:
        if self.k == 0 or self.k >= len(self.xyz):
            return self.radius
        steps = 8
        sx = np.linspace(x0, x1, steps + 1)
        sy = np.linspace(y0, y1, steps + 1)
        gx, gy = np.meshgrid(sx, sy)
        d2, _ = self.bins.query(gx.ravel(), gy.ravel(), self.k)
        reach = float(np.sqrt(d2[:, -1].max()))
        spacing = math.hypot((x1 - x0) / steps, (y1 - y0) / steps)
        halo = reach + 0.5 * spacing + 1e-6 * max(cell, 1.0)
        return min(halo, self.radius)

    def payload(self, x0: float, y0: float, x1: float, y1: float, cell: float) -> np.ndarray:
        if self.single_tile:
            return self.xyz
        h = self.halo(x0, y0, x1, y1, cell)
        if not math.isfinite(h):
            return self.xyz
        return self.xyz[self.bins.in_rect(x0 - h, y0 - h, x1 + h, y1 + h)]

    def for_cells(self, xs: np.ndarray, ys: np.ndarray, mask: np.ndarray,
                  cell: float) -> np.ndarray:
        """The points the computed cells (``mask``) of a tile need (contiguous (m, 3))."""
        rows = np.flatnonzero(mask.any(axis=1))
        cols = np.flatnonzero(mask.any(axis=0))
        x0, x1 = sorted((xs[cols[0]], xs[cols[-1]]))
        y0, y1 = sorted((ys[rows[0]], ys[rows[-1]]))
        return np.ascontiguousarray(self.payload(x0, y0, x1, y1, cell))
