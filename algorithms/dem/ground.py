"""dem:ground - DTM from a DSM or a point cloud: SMRF ground filter, then gridding."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, Enum, Number, RasterLayer
from toolbox.parameters.outputs import OutputFile, OutputRaster
from toolbox.registry import register
from toolbox.ui.grid import grid_request
from toolbox.ui.gridding import (
    STATISTICS,
    execution_parameters,
    grid_parameters,
    gridding_request,
    point_input_parameters,
)

GRID_METHODS = ("tin_linear", "idw", "nearest")


@register
class GroundFilterDtm(Algorithm):
    """DTM (bare earth) from a DSM raster or a point cloud (LAS/LAZ or point layer).

    Ground filter: SMRF, the simple morphological filter (Pingel et al. 2013), a refinement of
    the progressive morphological filter of Zhang et al. (2003), on a grid of FILTER_CELL:

    1. the lowest point of each cell (a DSM: its own cells, FILTER_CELL not used); empty cells
       take the nearest value;
    2. grey openings (scipy.ndimage, square window of 2r+1 cells) for r = 1 ... MAX_WINDOW /
       FILTER_CELL; a cell that drops by more than SLOPE x r x FILTER_CELL at a step is an
       object (building, tree). Objects wider than 2 x MAX_WINDOW stay ground: set MAX_WINDOW
       to half the widest building; SLOPE to the steepest terrain (rise/run);
    3. a provisional DTM: the ground cells, holes filled by linear interpolation;
    4. a point (a DSM cell) is ground when its height is within ELEVATION_THRESHOLD +
       ELEVATION_SCALAR x (local slope of the provisional DTM) of it.

    The ground points are then gridded by METHOD (tin_linear, idw or nearest: the dem:* methods,
    the same grid rules: CELL_SIZE / EXTENT / TEMPLATE; default: the DSM's grid, or
    FILTER_CELL over the points' bounds). NONGROUND: UInt8 on the output grid, 1 where a cell
    holds a non-ground point or DSM cell, 0 where only ground ones, 255 where none.
    HEIGHTS (optional): on the same grid, the highest point (or DSM cell) of each cell minus
    the DTM there (a normalised DSM: buildings and trees stand up, open ground is about 0;
    no data where no point fell), the HEIGHTS mosaic:seamlines routes seams around.
    GROUND_POINTS writes the input points classified (2 ground, 1 other) as LAS/LAZ.
    The filter grid is held in memory (its cells count against MAX_CELLS).
    """

    length_units = "one"  # x, y and heights in one unit (metres or feet): slopes mix them

    id = "dem:ground"
    display_name = "DTM by ground filtering (SMRF)"
    group = "DEM gridding"
    short_help = ("DTM GeoTIFF and non-ground mask from a DSM or a LAS/LAZ point cloud by a "
                  "morphological ground filter (SMRF), gridded by a dem:* method.")
    parameters = [
        *point_input_parameters("points: a LAS/LAZ/COPC point cloud, or PointZ / points with "
                                "a height field"),
        RasterLayer("DSM", "DSM raster (band 1) instead of INPUT", optional=True,
                    role="heights"),
        Crs("CRS", "CRS of inputs without one (a point cloud without a CRS needs it)",
            optional=True),
        Number("FILTER_CELL", "cell of the filter grid, CRS units (points only; default 1)",
               optional=True, min_value=0, min_exclusive=True),
        Number("SLOPE", "terrain slope tolerated by the opening (rise/run, e.g. 0.15 = 15 %)",
               default=0.15, min_value=0),
        Number("MAX_WINDOW", "largest opening radius, CRS units (half the widest object)",
               default=18.0, min_value=0, min_exclusive=True),
        Number("ELEVATION_THRESHOLD", "height above the provisional DTM still ground, CRS units",
               default=0.5, min_value=0),
        Number("ELEVATION_SCALAR", "extra threshold per unit of local slope (rise/run)",
               default=1.25, min_value=0),
        Enum("METHOD", "gridding of the ground points (as dem:tin_linear / dem:idw / "
             "dem:nearest, default options)", options=GRID_METHODS, default="tin_linear"),
        *grid_parameters(),
        *execution_parameters(),
        OutputRaster("NONGROUND", "non-ground mask GeoTIFF (UInt8: 1 non-ground, 0 ground, "
                     "255 no data), on the DTM's grid"),
        OutputRaster("HEIGHTS", "height above the DTM of the highest point (or DSM cell) of "
                     "each cell, Float32 (for mosaic:seamlines HEIGHTS)", optional=True),
        OutputFile("GROUND_POINTS", "the input points classified (2 ground, 1 other) as "
                   "LAS/LAZ", extensions=[".laz", ".las"], optional=True),
    ]
    outputs = [STATISTICS]

    def check(self, params: dict[str, Any]) -> None:
        from toolbox.io.pointcloud import cloud_filter

        if (params.get("INPUT") is None) == (params.get("DSM") is None):
            raise self.fail("INPUT", "give exactly one of INPUT (points) or DSM (raster)")
        if params.get("INPUT") is not None:
            cloud_filter(params["INPUT"], params.get("CLASSES"), params.get("RETURNS"),
                         params.get("CRS"))
        elif params.get("FILTER_CELL") is not None:
            raise self.fail("FILTER_CELL", "is not used with DSM (the filter runs on the DSM's "
                            "cells)")
        else:  # its cells are the output grid's template
            from toolbox.io.raster import require_north_up

            require_north_up(params["DSM"].transform, "DSM", params["DSM"].path)
        grid_request(params).check(cell_required=False)

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.terrain.ground import GroundFilter
        from toolbox.terrain.ground_run import GroundRequest, run_ground

        request = GroundRequest(
            gridding=gridding_request(params),
            filter=GroundFilter(float(params.get("FILTER_CELL") or 1.0), float(params["SLOPE"]),
                                float(params["MAX_WINDOW"]), float(params["ELEVATION_THRESHOLD"]),
                                float(params["ELEVATION_SCALAR"])),
            nonground=params["NONGROUND"], method=params["METHOD"], dsm=params.get("DSM"),
            ground_points=params.get("GROUND_POINTS"), heights=params.get("HEIGHTS"))
        stats = run_ground(request, feedback)
        names = ("OUTPUT", "NONGROUND", "HEIGHTS", "GROUND_POINTS", "QUALITY")
        out = {name: params[name] for name in names if params.get(name) is not None}
        return out | {"STATISTICS": stats}
