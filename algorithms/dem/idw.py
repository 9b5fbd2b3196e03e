"""dem:idw - DEM by inverse-distance-weighted mean of the nearest points (thesis eq. [45])."""

from __future__ import annotations

from toolbox.parameters import Integer, Number
from toolbox.registry import register
from toolbox.ui.gridding import (
    GriddingAlgorithm,
    execution_parameters,
    grid_parameters,
    neighbour_parameters,
    source_parameters,
)


@register
class IdwGrid(GriddingAlgorithm):
    """DEM by inverse distance weighting: each cell takes the weighted mean
    ``Q = Σ q_k / d_k^p  /  Σ 1 / d_k^p`` of the heights ``q_k`` of its neighbours at distances
    ``d_k`` from the cell centre (S002 par. 2.5.2 eq. [45], which uses p = 1). A cell centre on
    a data point takes its height, so the surface is exact at the data and never leaves their
    height range.

    Neighbours: the NEIGHBOURS nearest points (default 12), only within RADIUS when given;
    with SECTORS > 1 (needs RADIUS) the ceil(NEIGHBOURS / SECTORS) nearest points of each of
    SECTORS equal angular sectors around the cell (sector 0 starts east), so that points on
    one side only (a contour, a survey line) do not dominate. Cells with fewer than
    MIN_NEIGHBOURS neighbours stay nodata. POWER (default 2, the usual GIS choice; 1 as in the
    thesis) sets how fast the weights fall with distance.

    Data, grid, masks (convex hull, MASK, MAX_DISTANCE), duplicate XY, tiles and the Dask
    executor are as for dem:nearest (see `toolbox help dem:nearest`); QUALITY writes a
    leave-one-out cross-validation report with the same options.
    """

    id = "dem:idw"
    display_name = "DEM by inverse distance weighting"
    short_help = "DEM GeoTIFF by inverse-distance-weighted mean of the nearest points (eq. 45)."
    method = "idw"
    parameters = source_parameters() + grid_parameters() + [
        Number("POWER", "weight exponent p in 1/d^p (thesis eq. 45: 1)", default=2.0,
               min_value=0, min_exclusive=True, max_value=16),
        *neighbour_parameters(12, 1, "search radius, CRS units (default: no limit; required "
                              "with SECTORS)"),
        Integer("SECTORS", "angular sectors for the neighbour search (1 = none; e.g. 4 or 8)",
                default=1, min_value=1, max_value=16),
    ] + execution_parameters()

    def check_method(self, params):
        super().check_method(params)
        sectors = params.get("SECTORS") or 1
        if sectors > 1 and params.get("RADIUS") is None:
            raise self.fail("RADIUS", f"is required with SECTORS > 1 (got SECTORS {sectors}): "
                            "a sector search looks for points up to a radius")
        if sectors > params.get("NEIGHBOURS", 12):
            raise self.fail("SECTORS", f"must be <= NEIGHBOURS ({params.get('NEIGHBOURS')}), "
                            f"got {sectors}")
