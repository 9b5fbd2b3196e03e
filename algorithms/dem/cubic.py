"""dem:cubic - DEM by local 3rd-order surfaces on the k nearest points (thesis eq. [48])."""

from __future__ import annotations

from toolbox.registry import register
from toolbox.ui.gridding import POLYNOMIAL_HELP, GriddingAlgorithm, polynomial_parameters


@register
class CubicGrid(GriddingAlgorithm):
    __doc__ = """DEM by local cubic surfaces: each cell takes, at its centre, the surface
    ``z = a·x³ + b·y³ + c·x²y + d·xy² + e·x² + f·y² + g·xy + h·x + i·y + l`` fitted by least
    squares to its k nearest data points (S002 par. 2.5.2 eq. [48], at least 10 points). Default k = 20.
    """ + POLYNOMIAL_HELP

    id = "dem:cubic"
    display_name = "DEM by local cubic surfaces"
    short_help = "DEM GeoTIFF by least-squares 3rd-order surfaces on the k nearest points (eq. 48)."
    method = "cubic"
    parameters = polynomial_parameters(3, 20)
