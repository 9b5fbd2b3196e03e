"""dem:plane - DEM by local least-squares planes on the k nearest points (thesis eq. [46])."""

from __future__ import annotations

from toolbox.registry import register
from toolbox.ui.gridding import POLYNOMIAL_HELP, GriddingAlgorithm, polynomial_parameters


@register
class PlaneGrid(GriddingAlgorithm):
    __doc__ = """DEM by local planes: each cell takes, at its centre, the plane
    ``z = a·x + b·y + c`` fitted by least squares to its k nearest data points (S002 par. 2.5.2
    eq. [46], at least 3 points). Default k = 8.
    """ + POLYNOMIAL_HELP

    id = "dem:plane"
    display_name = "DEM by local planes"
    short_help = "DEM GeoTIFF by least-squares planes on the k nearest points (eq. 46)."
    method = "plane"
    parameters = polynomial_parameters(1, 8)
