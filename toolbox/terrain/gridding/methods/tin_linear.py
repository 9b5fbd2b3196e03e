"""TIN linear: the plane of the containing triangle of the (constrained) Delaunay TIN of the
data at each cell centre (thesis eq. [43]-[44]).

Two paths with the same cell values (the same arithmetic; tested equal): numba kernels, and for
small runs (:func:`use_compiled`) numpy ones that never import numba, whose import and kernel
cache load (about 1 s per process) would cost a small run more than its work. (QUALITY's
leave-one-out always uses the numba kernels.)
"""

from __future__ import annotations

import math
from functools import partial
from typing import Any

import numpy as np

from toolbox.terrain.gridding.methods.base import Method, TilePlan
from toolbox.terrain.gridding.neighbours import NUMPY_MAX_POINTS

#: the numpy path up to this many cells (and NUMPY_MAX_POINTS points). Measured crossover, whole
#: process on 2 cores (bench/dem_bench.py --crossover, bench/results/dem_crossover.md): numpy is
#: faster up to 400,000 points and 2000 x 2000 cells (100,000 points -> 632 x 632: 1.3 s
#: against 2.3 s), numba from 700,000 points, and from about 2828 x 2828 cells
NUMPY_MAX_CELLS = 4_000_000


def use_compiled(points: int, cells: int) -> bool:
    """True: the numba kernels; False (up to NUMPY_MAX_POINTS data points and NUMPY_MAX_CELLS
    cells): numpy, no numba import."""
    return points > NUMPY_MAX_POINTS or cells > NUMPY_MAX_CELLS


def tin_linear_tile(origin, max_distance, tile, arrays, compiled=True):
    """Kernel of one tile: plane of the containing triangle at each computed cell centre, NaN
    outside the TIN, the cell mask, or MAX_DISTANCE from the nearest data point."""
    from toolbox.terrain.gridding.tin_raster import tin_tile

    values = tin_tile(origin, tile, arrays, compiled)
    values[~arrays["mask"]] = np.nan
    near = arrays.get("near")
    if near is not None:
        xs, ys = tile.cell_centres(origin, halo=False)
        if compiled:
            from toolbox.terrain.gridding.idw_kernel import nearest_grid

            far = np.isnan(nearest_grid(near, xs, ys, ~np.isnan(values), max_distance))
        else:
            from toolbox.terrain.gridding.neighbours import beyond

            far = beyond(near, xs, ys, ~np.isnan(values), max_distance)
        values[far] = np.nan
    return values


class TinLinearMethod(Method):
    name = "tin_linear"
    min_points = 3
    limits_to_hull = False  # the TIN is the convex hull

    def plan_tiles(self, run: Any, options: dict[str, Any], feedback: Any) -> TilePlan:
        from toolbox.errors import InputDataError
        from toolbox.terrain.gridding.grid import NeighbourPlanner
        from toolbox.terrain.gridding.tin_constrained import constrained_tin
        from toolbox.terrain.gridding.tin_raster import TinTiles

        # the points in bin order (rows of small square bins): neighbours in the plane are
        # near in memory, which makes triangulating and every pass over the triangles faster
        bins = run.data.bins
        segments = bins.positions()[run.data.segments] if len(run.data.segments) else None
        with feedback.timed("triangulate"):
            try:
                nodes, triangles, info = constrained_tin(run.data.local[bins.order], segments)
            except ValueError as exc:
                raise InputDataError(f"cannot triangulate the data points: {exc}") from None
        if info.get("crossing_z_disagreement", 0) > 0:
            feedback.push_warning(f"{info['crossings']} breakline crossings without a shared "
                                  "vertex; the crossing breaklines disagree in Z by up to "
                                  f"{info['crossing_z_disagreement']:.6g} (mean used)")
        origin = run.origin
        compiled = use_compiled(len(run.data.local), run.grid.width * run.grid.height)
        with feedback.timed("tiles_index"):
            tin_tiles = TinTiles(nodes, triangles, run.grid, run.tile, origin, compiled)
        max_distance = options["max_distance"]
        # the points a tile's MAX_DISTANCE test needs: k = 0 (all within the distance of the
        # tile) on the numpy path, whose bins have no nearest-neighbour search
        near = NeighbourPlanner(run.data.local, 1 if compiled else 0, max_distance,
                                run.data.bins, run.single_tile) \
            if math.isfinite(max_distance) else None
        cell = max(run.grid.cell_size)

        def plan(tile) -> dict | None:
            arrays = tin_tiles.plan(tile)
            if arrays is None:
                return None
            xs, ys = tile.cell_centres(origin, halo=False)
            arrays["mask"] = run.cell_mask(tile, xs, ys)
            if not arrays["mask"].any():
                return None
            if near is not None:
                arrays["near"] = near.payload(xs.min(), ys.min(), xs.max(), ys.max(), cell)
            return arrays

        return TilePlan(plan, partial(tin_linear_tile, origin, max_distance, compiled=compiled),
                        {"triangles": len(triangles), **info,
                         "kernels": "numba" if compiled else "numpy"})

    def loo(self, local_xyz, options, segments, feedback, workers):
        from toolbox.terrain.gridding.neighbours import PointBins
        from toolbox.terrain.gridding.tin_constrained import tin_loo

        n = len(local_xyz)
        predicted = tin_loo(local_xyz, segments, feedback)
        max_distance = options.get("max_distance", math.inf)
        if math.isfinite(max_distance) and n > 1:  # as in the grid: nearest other point
            bins = PointBins.build(local_xyz[:, :2])
            d2, _ = bins.query(local_xyz[:, 0], local_xyz[:, 1], 1, skip=np.arange(n))
            predicted[d2[:, 0] > max_distance ** 2] = np.nan
        return predicted, None
