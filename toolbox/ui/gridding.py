"""The DEM gridding algorithms' parameters, their base class and the translation of their
parameters to a :class:`~toolbox.terrain.gridding.request.GriddingRequest` (light: no kernel
imports, so that ``toolbox list`` and ``toolbox help`` stay fast)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.io.pointcloud import RETURN_RULES
from toolbox.parameters import (
    Boolean,
    Crs,
    Enum,
    ExtentParameter,
    Field,
    Integer,
    Number,
    RasterLayer,
    String,
    VectorLayer,
)
from toolbox.parameters.outputs import Output, OutputFile, OutputRaster
from toolbox.terrain.gridding.request import (
    DEFAULT_MIN_RCOND,
    DEFAULT_NODATA,
    DEFAULT_TILE,
    TERMS,
    CellOptions,
    Execution,
    GriddingRequest,
    MethodOptions,
    PointSources,
)
from toolbox.terrain.points import DUPLICATE_RULES
from toolbox.ui.execution import scheduler_parameter, workers_parameter
from toolbox.ui.grid import grid_request

STATISTICS = Output("STATISTICS", "inputs, duplicates, grid, cells, fallbacks, timings", "dict")


def point_input_parameters(input_help: str) -> list:
    """INPUT points (PointZ, a height field or a LAS/LAZ/COPC cloud), Z_FIELD, CLASSES,
    RETURNS."""
    return [
        VectorLayer("INPUT", input_help, geometry_types=["point"], optional=True,
                    point_clouds=True),
        Field("Z_FIELD", "height field of INPUT (default: the geometry's Z)", parent="INPUT",
              numeric=True, optional=True),
        *point_cloud_parameters(),
    ]


def source_parameters() -> list:
    """Input data: points, line vertices, breaklines; duplicate rule; CRS."""
    return [
        *point_input_parameters("mass points: PointZ, or points with a height field (Z_FIELD), "
                                "or a LAS/LAZ/COPC point cloud"),
        VectorLayer("LINES", "lines whose vertices are data points, e.g. contours (LineString Z, "
                    "or a height field in LINES_Z_FIELD)", geometry_types=["line"], optional=True),
        Field("LINES_Z_FIELD", "height field of LINES (e.g. the contour's elevation)",
              parent="LINES", numeric=True, optional=True),
        VectorLayer("BREAKLINES", "breaklines: their vertices are data points, and their edges "
                    "are kept as triangle edges by dem:tin_linear", geometry_types=["line"],
                    optional=True),
        Field("BREAKLINES_Z_FIELD", "height field of BREAKLINES (default: geometry Z)",
              parent="BREAKLINES", numeric=True, optional=True),
        Enum("DUPLICATES", "height of points sharing one XY position: mean, first (input "
             "order: INPUT, LINES, BREAKLINES), min, max, or error", options=DUPLICATE_RULES,
             default="mean"),
        Number("DUPLICATE_TOLERANCE", "points closer than this in plan are one position (CRS "
               "units; 0 = identical coordinates)", default=0.0, min_value=0),
        Crs("CRS", "CRS of the data and the output (default: the inputs'); inputs without a CRS "
            "take it, inputs in another CRS are refused", optional=True),
    ]


def point_cloud_parameters() -> list:
    """CLASSES and RETURNS: which points of a LAS/LAZ INPUT are read."""
    return [
        String("CLASSES", "LAS/LAZ INPUT: ASPRS classes to keep, e.g. '2' (ground) or '2,9' "
               "(ground, water); a class absent from the file is an error (default: all)",
               optional=True),
        Enum("RETURNS", "LAS/LAZ INPUT: returns to keep: all, first (return number <= 1) or "
             "last (return number >= number of returns)", options=RETURN_RULES, default="all"),
    ]


def grid_parameters() -> list:
    """The output grid (the engine's grid rules) and which cells get a value."""
    return [
        Number("CELL_SIZE", "cell size, CRS units (not with TEMPLATE)", optional=True,
               min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "output extent 'xmin,ymin,xmax,ymax', taken as given: the "
                        "origin is its xmin/ymax, the east and south edges round up to whole "
                        "cells (default: the data's bounds, snapped outwards to the cell size)",
                        optional=True),
        RasterLayer("TEMPLATE", "raster whose grid the output takes (origin, cell size, and its "
                    "extent unless EXTENT is given)", optional=True),
        Number("NODATA", "value of cells without a height", default=DEFAULT_NODATA),
        Number("MAX_DISTANCE", "cells whose nearest data point is farther than this stay nodata "
               "(CRS units; default: no limit)", optional=True, min_value=0, min_exclusive=True),
        VectorLayer("MASK", "polygons: cells whose centre is outside stay nodata",
                    geometry_types=["polygon"], optional=True),
        Boolean("EXTRAPOLATE", "also compute cells outside the data's convex hull (not for "
                "dem:tin_linear)", default=False),
        Integer("MAX_CELLS", "refuse outputs with more cells than this (default: "
                "TOOLBOX_MAX_CELLS or 1e9)", optional=True, min_value=1),
    ]


def neighbour_parameters(default: int, minimum: int, radius_help: str) -> list:
    """NEIGHBOURS, RADIUS and MIN_NEIGHBOURS of the k-nearest-neighbour methods."""
    return [
        Integer("NEIGHBOURS", f"k nearest data points per cell (at least {minimum})",
                default=default, min_value=minimum, max_value=256),
        Number("RADIUS", radius_help, optional=True, min_value=0, min_exclusive=True),
        Integer("MIN_NEIGHBOURS", "cells with fewer neighbours found (within RADIUS) stay "
                "nodata", default=1, min_value=1),
    ]


def execution_parameters() -> list:
    """Tiling, executor, outputs."""
    return [
        Integer("TILE_SIZE", "tile side in cells (a multiple of 16; also the GeoTIFF block)",
                default=DEFAULT_TILE, min_value=16, max_value=4096),
        scheduler_parameter(),
        workers_parameter(),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        OutputRaster("OUTPUT", "DEM GeoTIFF (Float32, tiled 512, DEFLATE)"),
        OutputFile("QUALITY", "JSON quality report: leave-one-out cross-validation of this "
                   "method on the input points (RMSE, mean and max error)", extensions=[".json"],
                   optional=True),
    ]


def method_free_parameters() -> list:
    """The parameters of a method without options of its own (dem:nearest, dem:tin_linear)."""
    return source_parameters() + grid_parameters() + execution_parameters()


POLYNOMIAL_HELP = """
    Each cell's neighbours are its NEIGHBOURS nearest data points (within RADIUS when given).
    The least squares are solved with coordinates centred on the cell and scaled by the
    farthest neighbour's distance (numerically stable; the height at the centre is the
    constant coefficient), from the normal equations by Cholesky (their factor is the R of the
    QR factorisation of the column-normalised design matrix). Where the neighbourhood is
    ill-conditioned for the order (fewer neighbours than coefficients, or the smallest |R_ii|
    below MIN_RCOND: e.g. all neighbours on one or two contour lines) the fit
    falls back to the next lower order on the same neighbours (cubic -> quadratic -> plane ->
    mean); STATISTICS counts the cells fitted with each order. Cells outside the data's convex
    hull are nodata unless EXTRAPOLATE (then the surface is extrapolated, use with care).

    Data (points, line vertices, breakline vertices), grid, masks, duplicate XY, tiles and the
    Dask executor are as for dem:nearest (see `toolbox help dem:nearest`); QUALITY writes a
    leave-one-out cross-validation report with the same options.
"""


def polynomial_parameters(order: int, default_k: int) -> list:
    """The parameters of dem:plane (order 1), dem:quadratic (2) and dem:cubic (3)."""
    return source_parameters() + grid_parameters() + neighbour_parameters(
        default_k, TERMS[order], "search radius, CRS units (default: no limit)") + [
        Number("MIN_RCOND", "conditioning threshold: smallest |R_ii| of the normalised design "
               "matrix accepted before falling back to a lower order", default=DEFAULT_MIN_RCOND,
               min_value=0, min_exclusive=True, max_value=1),
    ] + execution_parameters()


# -- parameters -> request (the one place) --------------------------------------------------------
def point_sources(params: Mapping[str, Any]) -> PointSources:
    """INPUT, LINES, BREAKLINES (and their Z fields), CLASSES, RETURNS, DUPLICATES, CRS."""
    return PointSources(
        points=params.get("INPUT"), z_field=params.get("Z_FIELD"), lines=params.get("LINES"),
        lines_z_field=params.get("LINES_Z_FIELD"), breaklines=params.get("BREAKLINES"),
        breaklines_z_field=params.get("BREAKLINES_Z_FIELD"), classes=params.get("CLASSES"),
        returns=params.get("RETURNS") or "all", duplicates=params.get("DUPLICATES") or "mean",
        duplicate_tolerance=float(params.get("DUPLICATE_TOLERANCE") or 0.0),
        crs=params.get("CRS"))


def method_options(params: Mapping[str, Any]) -> MethodOptions:
    """NEIGHBOURS, RADIUS, MIN_NEIGHBOURS, POWER, SECTORS, MIN_RCOND, MAX_DISTANCE."""
    rcond = params.get("MIN_RCOND")
    return MethodOptions(
        neighbours=params.get("NEIGHBOURS"), radius=params.get("RADIUS"),
        min_neighbours=int(params.get("MIN_NEIGHBOURS") or 1),
        power=float(params.get("POWER") or 2.0), sectors=int(params.get("SECTORS") or 1),
        min_rcond=DEFAULT_MIN_RCOND if rcond is None else float(rcond),
        max_distance=params.get("MAX_DISTANCE"))


def gridding_request(params: Mapping[str, Any]) -> GriddingRequest:
    """The whole request of a ``dem:<method>`` run."""
    return GriddingRequest(
        sources=point_sources(params), output=params["OUTPUT"], grid=grid_request(params),
        method=method_options(params),
        cells=CellOptions(nodata=float(params.get("NODATA", DEFAULT_NODATA)),
                          mask=params.get("MASK"),
                          extrapolate=bool(params.get("EXTRAPOLATE", False))),
        execution=Execution(tile_size=int(params.get("TILE_SIZE") or DEFAULT_TILE),
                            scheduler=params.get("SCHEDULER"), workers=params.get("WORKERS"),
                            overviews=params.get("OVERVIEWS", True),
                            cog=bool(params.get("COG"))),
        quality=params.get("QUALITY"))


# -- the algorithms' base class -------------------------------------------------------------------
def check_sources(alg: Algorithm, params: Mapping[str, Any]) -> None:
    """Cross-parameter checks shared by every gridding algorithm (raise ParameterError)."""
    if params.get("INPUT") is None and params.get("LINES") is None \
            and params.get("BREAKLINES") is None:
        raise alg.fail("INPUT", "is required: give points (INPUT) and/or lines (LINES, "
                       "BREAKLINES) to grid")
    if params.get("INPUT") is not None:
        from toolbox.io.pointcloud import cloud_filter

        cloud_filter(params["INPUT"], params.get("CLASSES"), params.get("RETURNS"),
                     params.get("CRS"))


class GriddingAlgorithm(Algorithm):
    """Base of ``dem:<method>``: subclasses set ``method`` (a name in
    :data:`toolbox.terrain.gridding.methods.METHODS`) and the method's parameters."""

    length_units = "horizontal"  # x, y in one unit (metres or feet); heights in their own

    group = "DEM gridding"
    method: ClassVar[str] = ""
    outputs = [STATISTICS]

    def check(self, params: dict[str, Any]) -> None:
        check_sources(self, params)
        self.check_method(params)
        grid = grid_request(params)
        grid.check()
        guard_grid_size(params)
        if params.get("TILE_SIZE", DEFAULT_TILE) % 16:
            raise self.fail("TILE_SIZE", f"must be a multiple of 16 (GeoTIFF blocks), got "
                            f"{params['TILE_SIZE']}")

    def check_method(self, params: dict[str, Any]) -> None:
        k, min_k = params.get("NEIGHBOURS"), params.get("MIN_NEIGHBOURS")
        if k is not None and min_k is not None and min_k > k:
            raise self.fail("MIN_NEIGHBOURS", f"must be <= NEIGHBOURS ({k}), got {min_k}")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from functools import partial

        from toolbox.terrain.gridding.methods import METHODS
        from toolbox.terrain.gridding.run import grid_dem
        from toolbox.terrain.gridding.stream import grid_dem_streamed, wants_stream
        from toolbox.terrain.gridding.stream_quality import stream_quality
        from toolbox.terrain.gridding.stream_tin import grid_tin_streamed

        request = gridding_request(params)
        # a point cloud over TOOLBOX_STREAM_POINTS points is read by chunks, never held
        streamed = partial(grid_tin_streamed if self.method == "tin_linear"
                           else grid_dem_streamed, cross_validate=stream_quality)
        grid = streamed if wants_stream(request) else grid_dem
        stats = grid(METHODS[self.method], request, feedback)
        result: dict[str, Any] = {"OUTPUT": request.output}
        if request.quality is not None:
            result["QUALITY"] = request.quality
        return result | {"STATISTICS": stats}


def guard_grid_size(params: Mapping[str, Any]) -> None:
    """The grid's size guard (MAX_CELLS / TOOLBOX_MAX_CELLS) from the inputs' declared bounds,
    before any point is read (also in ``toolbox batch --validate``); the run checks it again on
    the data's exact bounds."""
    import numpy as np

    from toolbox.io.crs import input_crs_and_bounds

    pairs = [pair for name in ("INPUT", "LINES", "BREAKLINES")
             for pair in input_crs_and_bounds(params.get(name))]
    if not pairs or any(b is None for _, b in pairs):
        return
    b = np.array([bounds for _, bounds in pairs], dtype=float)
    bounds = (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())
    grid_request(params).grid(bounds, pairs[0][0])
