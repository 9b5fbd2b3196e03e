"""dem:nearest - DEM from the height of the nearest data point (thesis par. 2.5.2, method 1)."""

from __future__ import annotations

from toolbox.registry import register
from toolbox.ui.gridding import GriddingAlgorithm, method_free_parameters


@register
class NearestGrid(GriddingAlgorithm):
    """DEM by nearest neighbour: each cell takes the height of the data point nearest to its
    centre (S002 par. 2.5.2, method 1).

    Data points are the INPUT points and/or the vertices of LINES (e.g. contours) and
    BREAKLINES; points sharing an XY position are merged first (DUPLICATES rule, reported).
    The grid is CELL_SIZE over EXTENT taken as given (origin at its xmin/ymax; the east and
    south edges round up to whole cells), by default over the data bounds snapped outwards to
    multiples of the cell size; or the grid of a TEMPLATE raster (cut to EXTENT on its lattice
    when both are given). Cells whose centre is outside the data's
    convex hull (unless EXTRAPOLATE), outside MASK, or farther than MAX_DISTANCE from every
    point are nodata. Among points at exactly the same distance the one met first in the
    search wins.

    The output (tiled 512, DEFLATE, overviews; COG: a Cloud Optimized GeoTIFF) is written
    tile by tile (TILE_SIZE cells, each with the points within a halo
    found with a neighbour index), on local threads or on a Dask cluster (SCHEDULER or
    DASK_SCHEDULER_ADDRESS); the file is identical either way. QUALITY writes a leave-one-out
    cross-validation report (RMSE, mean and max error).
    """

    id = "dem:nearest"
    display_name = "DEM by nearest neighbour"
    short_help = "DEM GeoTIFF: each cell takes the height of the nearest data point."
    method = "nearest"
    parameters = method_free_parameters()
