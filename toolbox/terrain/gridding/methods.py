"""The gridding methods: their kernels per tile, leave-one-out predictors and options.

One :class:`Method` per thesis method (S002 par. 2.5.2; domain brief section 14). The algorithms
(``dem:idw``...) and ``dem:cross_validate`` take everything method-specific from here, so a
method grids and cross-validates with the same code and the same options.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.terrain.gridding.idw_kernel import idw_grid, idw_loo
from toolbox.terrain.gridding.neighbours import PointBins
from toolbox.terrain.gridding.polynomial import DEFAULT_MIN_RCOND, TERMS, polynomial_grid, polynomial_loo

POLY_ORDER = {"plane": 1, "quadratic": 2, "cubic": 3}


@dataclass(frozen=True)
class Method:
    """A gridding method.

    Attributes
    ----------
    name : str
        ``nearest``, ``idw``, ``plane``, ``quadratic``, ``cubic`` or ``tin_linear``.
    min_points : int
        Distinct data points the method needs at least.
    default_neighbours : int
        k when NEIGHBOURS is not given (0: the method uses no k nearest).
    min_neighbours : int
        Smallest NEIGHBOURS accepted.
    """

    name: str
    min_points: int
    default_neighbours: int
    min_neighbours: int

    def options(self, params: dict[str, Any]) -> dict[str, Any]:
        """Kernel keyword arguments from validated parameters (missing ones take defaults)."""
        max_distance = params.get("MAX_DISTANCE")
        opts: dict[str, Any] = {"max_distance": math.inf if max_distance is None
                                else float(max_distance)}
        if self.name == "tin_linear":
            return opts
        if self.name == "nearest":
            return opts | {"neighbours": 1}
        k = params.get("NEIGHBOURS") or self.default_neighbours
        radius = params.get("RADIUS")
        opts |= {"neighbours": int(k), "radius": math.inf if radius is None else float(radius),
                 "min_neighbours": int(params.get("MIN_NEIGHBOURS") or 1)}
        if self.name == "idw":
            sectors = int(params.get("SECTORS") or 1)
            return opts | {"power": float(params.get("POWER") or 2.0),
                           "sectors": sectors if sectors > 1 else 0}
        rcond = params.get("MIN_RCOND")
        return opts | {"order": POLY_ORDER[self.name],
                       "min_rcond": DEFAULT_MIN_RCOND if rcond is None else float(rcond)}

    def halo_neighbours(self, options: dict[str, Any]) -> tuple[int, float | None]:
        """(k, radius) that bound the points a tile needs (see NeighbourPlanner); k = 0: every
        point within the radius."""
        radius = options.get("radius", math.inf)
        if self.name == "idw" and options.get("sectors", 0) > 1:
            return 0, radius  # a sector search may use any point within the radius
        return int(options.get("neighbours", 1)), (None if not math.isfinite(radius) else radius)

    @property
    def tile_function(self) -> Callable:
        return {"nearest": idw_tile, "idw": idw_tile, "plane": polynomial_tile,
                "quadratic": polynomial_tile, "cubic": polynomial_tile}[self.name]

    def loo(self, bins: PointBins, z: np.ndarray, targets: np.ndarray,
            options: dict[str, Any]) -> tuple[np.ndarray, np.ndarray | None]:
        """Leave-one-out predictions at ``targets`` (input indices); polynomial methods also
        return the order used per target (-1 = none)."""
        if self.name in POLY_ORDER:
            return polynomial_loo(bins, z, targets, **options)
        kwargs = {k: v for k, v in options.items()
                  if k in ("neighbours", "power", "radius", "sectors", "min_neighbours",
                           "max_distance")}
        return idw_loo(bins, z, targets, **kwargs), None


METHODS: dict[str, Method] = {
    "nearest": Method("nearest", 1, 1, 1),
    "idw": Method("idw", 1, 12, 1),
    "plane": Method("plane", TERMS[1], 8, TERMS[1]),
    "quadratic": Method("quadratic", TERMS[2], 12, TERMS[2]),
    "cubic": Method("cubic", TERMS[3], 20, TERMS[3]),
    "tin_linear": Method("tin_linear", 3, 0, 0),
}


def idw_tile(task) -> tuple[np.ndarray, None]:
    """Tile kernel of ``nearest`` and ``idw`` (see :func:`toolbox.terrain.gridding.idw_kernel.idw_grid`)."""
    opts = dict(task.options)
    return idw_grid(task.xyz, task.xs, task.ys, task.mask, **opts), None


def polynomial_tile(task) -> tuple[np.ndarray, np.ndarray]:
    """Tile kernel of ``plane``, ``quadratic`` and ``cubic`` (orders used are counted)."""
    return polynomial_grid(task.xyz, task.xs, task.ys, task.mask, **task.options)
