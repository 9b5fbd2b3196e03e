"""Local polynomial surfaces (plane, quadratic, cubic: thesis eq. [46]-[48]) fitted by least
squares to the k nearest points, with fallback to lower orders."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.terrain.gridding.methods.base import NeighbourMethod
from toolbox.terrain.gridding.request import (
    DEFAULT_MIN_RCOND,
    ORDER_NAMES,
    TERMS,
    MethodOptions,
)


def polynomial_tile(origin, options, tile, arrays):
    """Kernel of one tile: (heights, cells fitted per order)."""
    from toolbox.terrain.gridding.polynomial import polynomial_grid

    xs, ys = tile.cell_centres(origin, halo=False)
    return polynomial_grid(arrays["xyz"], xs, ys, arrays["mask"], **options)


class PolynomialMethod(NeighbourMethod):
    """``order`` 1 (plane), 2 (quadratic) or 3 (cubic)."""

    tile_kernel = staticmethod(polynomial_tile)

    def __init__(self, name: str, order: int, default_neighbours: int):
        self.name = name
        self.order = order
        self.min_points = self.min_neighbours = TERMS[order]
        self.default_neighbours = default_neighbours

    def options(self, request: MethodOptions) -> dict[str, Any]:
        rcond = request.min_rcond
        return super().options(request) | {
            "order": self.order,
            "min_rcond": DEFAULT_MIN_RCOND if rcond is None else float(rcond)}

    def loo_chunk(self, bins, z, targets, options):
        from toolbox.terrain.gridding.polynomial import polynomial_loo

        return polynomial_loo(bins, z, targets, **options)

    def summarise(self, counts: np.ndarray | None) -> dict[str, Any]:
        if counts is None:
            counts = np.zeros(4, dtype=np.int64)
        used = {ORDER_NAMES[o]: int(counts[o]) for o in range(self.order + 1)}
        total = int(counts.sum())
        fell_back = total - int(counts[self.order])
        return {"orders_used": used, "cells_fitted": total, "fallbacks": fell_back,
                "fallback_share": fell_back / total if total else 0.0}
