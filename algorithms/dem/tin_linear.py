"""dem:tin_linear - DEM from the planes of the Delaunay TIN, breaklines kept (thesis eq. [43]-[44])."""

from __future__ import annotations

from toolbox.registry import register
from toolbox.ui.gridding import GriddingAlgorithm, method_free_parameters


@register
class TinLinearGrid(GriddingAlgorithm):
    """DEM from a TIN: the data points (INPUT points, vertices of LINES and BREAKLINES) are
    triangulated by Delaunay (as tin:delaunay: CDT, or Triangle when TOOLBOX_TRIANGULATOR
    chooses it), constrained so that every BREAKLINES edge is a triangle edge; each cell centre
    takes the height of the plane through the three nodes of its triangle (S002 par. 2.5.1
    eq. [43]-[44], linear interpolation of par. 2.5.2). Planes are reproduced exactly; the
    surface is continuous, with slope breaks along triangle edges and breaklines.

    Cells outside the TIN (the convex hull of the data) are nodata (EXTRAPOLATE does not
    apply); MASK and MAX_DISTANCE (distance to the nearest data point) also make nodata.
    Breaklines crossing without a shared vertex are split at the crossing, whose height is
    interpolated along the crossing segments (their mean, with a warning, if they disagree).

    The triangulation is built once; each output tile then rasterises only the triangles
    touching it, on local threads or a Dask cluster (SCHEDULER), in bounded memory. Duplicate
    XY, grid and template are as for dem:nearest (see `toolbox help dem:nearest`). QUALITY
    writes a leave-one-out report (each point predicted from the TIN of the others).
    """

    id = "dem:tin_linear"
    display_name = "DEM by TIN linear interpolation"
    short_help = "DEM GeoTIFF from the planes of the Delaunay TIN, breaklines kept (eq. 43-44)."
    method = "tin_linear"
    parameters = method_free_parameters()

    def process(self, params, feedback):
        if params.get("EXTRAPOLATE"):
            feedback.push_warning("EXTRAPOLATE does not apply to dem:tin_linear: cells outside "
                                  "the TIN stay nodata")
        return super().process(params, feedback)
