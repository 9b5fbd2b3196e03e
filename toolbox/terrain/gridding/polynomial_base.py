"""Shared declaration of dem:plane, dem:quadratic and dem:cubic (local least-squares surfaces)."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.parameters import Number
from toolbox.terrain.gridding.base import GriddingAlgorithm, neighbour_parameters
from toolbox.terrain.gridding.gridding import execution_parameters, grid_parameters
from toolbox.terrain.gridding.inputs import source_parameters
from toolbox.terrain.gridding.polynomial import DEFAULT_MIN_RCOND, ORDER_NAMES, TERMS

COMMON_HELP = """
    Each cell's neighbours are its NEIGHBOURS nearest data points (within RADIUS when given).
    The least squares are solved with coordinates centred on the cell and scaled by the
    farthest neighbour's distance (numerically stable; the height at the centre is the
    constant coefficient), by a Cholesky factorisation of the normal equations of the
    column-normalised design matrix (AᵀA = RᵀR, R the triangular factor of its QR). Where the
    neighbourhood is ill-conditioned for the order (fewer neighbours than coefficients, or the
    smallest |R_ii| below MIN_RCOND: e.g. all neighbours on one or two contour lines) the fit
    falls back to the next lower order on the same neighbours (cubic -> quadratic -> plane ->
    mean); STATISTICS counts the cells fitted with each order. Cells outside the data's convex
    hull are nodata unless EXTRAPOLATE (then the surface is extrapolated, use with care).

    Data (points, line vertices, breakline vertices), grid, masks, duplicate XY, tiles and the
    Dask executor are as for dem:nearest (see `toolbox help dem:nearest`); QUALITY writes a
    leave-one-out cross-validation report with the same options.
"""


def polynomial_parameters(order: int, default_k: int) -> list:
    return source_parameters() + grid_parameters() + neighbour_parameters(
        default_k, TERMS[order], "search radius, CRS units (default: no limit)") + [
        Number("MIN_RCOND", "conditioning threshold: smallest |R_ii| of the normalised design "
               "matrix accepted before falling back to a lower order", default=DEFAULT_MIN_RCOND,
               min_value=0, min_exclusive=True, max_value=1),
    ] + execution_parameters()


class PolynomialGrid(GriddingAlgorithm):
    """Base of the local polynomial algorithms."""

    def summarise_counts(self, counts: np.ndarray | None) -> dict[str, Any]:
        if counts is None:
            counts = np.zeros(4, dtype=np.int64)
        order = {"plane": 1, "quadratic": 2, "cubic": 3}[self.method]
        used = {ORDER_NAMES[o]: int(counts[o]) for o in range(order + 1)}
        total = int(counts.sum())
        fell_back = total - int(counts[order])
        return {"orders_used": used, "cells_fitted": total, "fallbacks": fell_back,
                "fallback_share": fell_back / total if total else 0.0}
