"""What every gridding method provides, and the shared part of the k-nearest-neighbour ones."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np

from toolbox.terrain.gridding.request import MethodOptions


@dataclass
class TilePlan:
    """How a run's tiles are computed: ``plan(tile) -> arrays | None`` (in this process: the
    arrays the tile needs, None for a tile without cells to compute) and ``kernel(tile, arrays)
    -> values | (values, counts)`` (on a thread or a Dask worker: a partial of a module-level
    function); ``info`` goes into STATISTICS' method section."""

    plan: Callable
    kernel: Callable
    info: dict = field(default_factory=dict)


class Method:
    """A gridding method.

    Attributes: ``name``; ``min_points`` (distinct data points needed); ``default_neighbours``
    (k when NEIGHBOURS is not given; 0: no k nearest); ``min_neighbours`` (smallest NEIGHBOURS);
    ``limits_to_hull`` (cells outside the data's convex hull stay nodata unless EXTRAPOLATE).
    """

    name: str = ""
    min_points: int = 1
    default_neighbours: int = 0
    min_neighbours: int = 0
    limits_to_hull: bool = True

    def options(self, request: MethodOptions) -> dict[str, Any]:
        """Kernel keyword arguments of this method from the run's options."""
        max_distance = request.max_distance
        return {"max_distance": math.inf if max_distance is None else float(max_distance)}

    def plan_tiles(self, run: Any, options: dict[str, Any], feedback: Any) -> TilePlan:
        raise NotImplementedError

    def loo(self, local_xyz: np.ndarray, options: dict[str, Any], segments: np.ndarray | None,
            feedback: Any, workers: int | None) -> tuple[np.ndarray, np.ndarray | None]:
        """Leave-one-out predictions at every point (NaN: not predicted) and, for the
        polynomial methods, the order used per point (-1 = none)."""
        raise NotImplementedError

    def summarise(self, counts: np.ndarray | None) -> dict[str, Any]:
        """STATISTICS of the summed per-tile counters."""
        return {}


class NeighbourMethod(Method):
    """A method on the k nearest data points of each cell (within a radius)."""

    def options(self, request: MethodOptions) -> dict[str, Any]:
        k = request.neighbours or self.default_neighbours
        radius = request.radius
        return super().options(request) | {
            "neighbours": int(k), "radius": math.inf if radius is None else float(radius),
            "min_neighbours": int(request.min_neighbours or 1)}

    def halo_neighbours(self, options: dict[str, Any]) -> tuple[int, float | None]:
        """(k, radius) that bound the points a tile needs (see NeighbourPlanner); k = 0: every
        point within the radius."""
        radius = options.get("radius", math.inf)
        return int(options.get("neighbours", 1)), (None if not math.isfinite(radius) else radius)

    #: module-level ``kernel(origin, options, tile, arrays)``, set by each method
    tile_kernel: Callable

    def plan_tiles(self, run: Any, options: dict[str, Any], feedback: Any) -> TilePlan:
        from toolbox.terrain.gridding.grid import NeighbourPlanner

        k, radius = self.halo_neighbours(options)
        planner = NeighbourPlanner(run.data.local, k, radius, run.data.bins,
                                   run.single_tile)
        cell = max(run.grid.cell_size)
        origin = run.origin

        def plan(tile) -> dict | None:
            xs, ys = tile.cell_centres(origin, halo=False)
            mask = run.cell_mask(tile, xs, ys)
            if not mask.any():
                return None
            return {"xyz": planner.for_cells(xs, ys, mask, cell), "mask": mask}

        return TilePlan(plan, partial(type(self).tile_kernel, origin, dict(options)))

    def loo_chunk(self, bins: Any, z: np.ndarray, targets: np.ndarray,
                  options: dict[str, Any]) -> tuple[np.ndarray, np.ndarray | None]:
        raise NotImplementedError

    def loo(self, local_xyz, options, segments, feedback, workers):
        from toolbox.terrain.gridding.neighbours import PointBins

        n = len(local_xyz)
        bins = PointBins.build(local_xyz[:, :2])
        return self.loo_targets(bins, local_xyz[:, 2], np.arange(n), options, feedback, workers)

    def loo_targets(self, bins: Any, z: np.ndarray, targets: np.ndarray,
                    options: dict[str, Any], feedback: Any, workers: int | None
                    ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`loo` at the points ``targets`` (indices into the points of ``bins``, heights
        ``z``) only, every point of ``bins`` a neighbour (the streamed QUALITY: a tile's own
        points in its bucket). Returns (predicted (t,), orders used (t,) or None)."""
        from toolbox.executor import Executor, default_workers, map_tiles

        n = len(targets)
        chunk = max(1000, math.ceil(n / 64))
        starts = list(range(0, n, chunk))

        def run(start: int):
            return self.loo_chunk(bins, z, targets[start:start + chunk], options)

        predicted = np.full(n, np.nan)
        used = None
        executor = Executor("local", workers or default_workers())
        results = map_tiles(run, starts, executor=executor, feedback=feedback, total=len(starts))
        for start, (pred, order) in zip(starts, results, strict=True):
            predicted[start:start + len(pred)] = pred
            if order is not None:
                if used is None:
                    used = np.full(n, -1, dtype=np.int64)
                used[start:start + len(order)] = order
        return predicted, used
