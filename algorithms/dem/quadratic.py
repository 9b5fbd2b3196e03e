"""dem:quadratic - DEM by local 2nd-order surfaces on the k nearest points (thesis eq. [47])."""

from __future__ import annotations

from toolbox.registry import register
from toolbox.ui.gridding import POLYNOMIAL_HELP, GriddingAlgorithm, polynomial_parameters


@register
class QuadraticGrid(GriddingAlgorithm):
    __doc__ = """DEM by local quadratic surfaces: each cell takes, at its centre, the surface
    ``z = a·x² + b·y² + c·xy + d·x + e·y + f`` fitted by least squares to its k nearest data
    points (S002 par. 2.5.2 eq. [47], at least 6 points).
    Default k = 12.
    """ + POLYNOMIAL_HELP

    id = "dem:quadratic"
    display_name = "DEM by local quadratic surfaces"
    short_help = "DEM GeoTIFF by least-squares 2nd-order surfaces on the k nearest points (eq. 47)."
    method = "quadratic"
    parameters = polynomial_parameters(2, 12)
