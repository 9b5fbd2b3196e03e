"""dem:match - DSM by dense image matching of every suitable stereo pair of a block."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import ExtentParameter, Integer, Number, RasterLayer, String
from toolbox.parameters.outputs import Output, OutputFile, OutputRaster
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.grid import grid_request
from toolbox.ui.photogrammetry import project_parameter


@register
class DenseMatchingDsm(Algorithm):
    """DSM by dense matching of the oriented photos of a PROJECT (S002 par. 3.7).

    1. Pairs: every two photos (of PHOTOS, default all oriented ones) whose footprints at the
       mean of MIN_HEIGHT and MAX_HEIGHT overlap by MIN_OVERLAP of the smaller, whose base/height
       ratio lies in MIN_BASE_RATIO..MAX_BASE_RATIO and whose optical axes are at most
       MAX_ANGLE degrees apart (the others are listed in STATISTICS with the reason).
    2. Each pair is resampled to epipolar images as stereo:epipolar does (distortion removed),
       in a scratch folder, converted to 8 bits.
    3. OpenCV StereoSGBM (semi-global matching, 3-way) over the disparities of heights
       MIN_HEIGHT..MAX_HEIGHT (a pair needing more than MAX_DISPARITIES is skipped with a
       warning, refused when no pair is left; refused too when a first
       match at 1/4 resolution over up to three times those disparities finds less than half
       of the terrain inside the range: the error names the heights found; under 90 %: a
       warning), with left-right consistency (LR_MAX_DIFF pixels), a uniqueness (cost)
       threshold UNIQUENESS % and speckle filtering (SPECKLE_WINDOW pixels, SPECKLE_RANGE
       disparity); pixels outside either photo are invalid.
    4. Disparities (1/16 pixel) are triangulated to points (the normal case; see
       stereo:epipolar); points outside MIN_HEIGHT..MAX_HEIGHT are dropped.
    5. Fusion on the grid (CELL_SIZE / EXTENT / TEMPLATE; default extent: the pairs' shared
       footprints): per pair the median and quartiles of its points in each cell, then across
       pairs the median of their medians (OUTPUT), their number (COUNT, 0 = none) and SPREAD =
       the highest upper quartile minus the lowest lower quartile (one pair: its
       interquartile range; several: also their disagreement). Cells without matched points
       stay nodata: no interpolation, so no cell outside the stereo coverage gets a value.
       SPREAD's nodata is NODATA when negative, else -1 (a spread of 0 is a value).

    The epipolar pixel (PIXEL_SIZE_MM) is by default the left image's, or coarser so that a
    DSM cell spans four pixels on the ground: much finer matching would only add points to
    each cell's median. (Coarsening a large scan this way resamples it bilinearly, without
    averaging.)
    POINTS writes the matched points as LAS/LAZ, coloured from the left photo (RGB, or grey).
    Steps 2-4 run one pair at a time in this process or, with SCHEDULER, on a Dask cluster
    (as many pairs at a time as its workers take): each worker reads its pair's images from
    their paths in PROJECT and sends back the pair's cell statistics (and its points when
    POINTS is given: the client holds those of the pairs in flight); pairs come back in order,
    so the outputs are the local run's.
    Memory: per pair in flight, its epipolar images and disparities (matched in strips of 1024
    rows), its points' cells and heights (16 bytes a point; triangulated 256 rows at a time), the cell
    statistics of the pairs done, and the output grid.
    """

    id = "dem:match"
    display_name = "DSM by dense image matching"
    group = "DEM gridding"
    short_help = ("DSM GeoTIFF (+ pair count and spread) by semi-global matching of every "
                  "suitable stereo pair of an oriented block.")
    parameters = [
        project_parameter("orientation project (YAML) with oriented photos and their images"),
        String("PHOTOS", "photo ids to use, comma-separated (default: every oriented photo)",
               optional=True),
        Number("MIN_HEIGHT", "lowest ground height of the area (sets the disparity search)"),
        Number("MAX_HEIGHT", "highest surface height (roofs, trees) of the area"),
        Number("MIN_OVERLAP", "least footprint overlap of a pair (fraction of the smaller)",
               default=0.3, min_value=0, max_value=1),
        Number("MIN_BASE_RATIO", "least base/height ratio of a pair", default=0.1, min_value=0),
        Number("MAX_BASE_RATIO", "largest base/height ratio of a pair", default=2.0,
               min_value=0, min_exclusive=True),
        Number("MAX_ANGLE", "largest angle between a pair's optical axes, degrees",
               default=30.0, min_value=0, max_value=90),
        Number("PIXEL_SIZE_MM", "pixel of the epipolar images, mm (default: the left image's, "
               "or coarser so that a DSM cell spans four pixels on the ground)", optional=True,
               min_value=0, min_exclusive=True),
        Integer("BLOCK_SIZE", "SGBM matching block, pixels (odd)", default=5, min_value=1,
                max_value=15),
        Integer("UNIQUENESS", "SGBM uniqueness ratio, % (cost threshold)", default=10,
                min_value=0, max_value=100),
        Integer("SPECKLE_WINDOW", "largest speckle removed, pixels (0 = no speckle filter)",
                default=100, min_value=0),
        Number("SPECKLE_RANGE", "disparity variation within a connected region, pixels",
               default=2.0, min_value=0),
        Integer("LR_MAX_DIFF", "left-right consistency tolerance, pixels", default=1,
                min_value=0),
        Integer("MAX_DISPARITIES", "largest disparity search allowed (memory and time)",
                default=512, min_value=16),
        Number("CELL_SIZE", "DSM cell size, CRS units (not with TEMPLATE)", optional=True,
               min_value=0, min_exclusive=True),
        ExtentParameter("EXTENT", "DSM extent 'xmin,ymin,xmax,ymax' (default: the pairs' "
                        "shared footprints)", optional=True),
        RasterLayer("TEMPLATE", "raster whose grid the DSM takes", optional=True),
        Number("NODATA", "value of cells without a height", default=-9999.0),
        Integer("MAX_CELLS", "refuse grids with more cells than this (default: "
                "TOOLBOX_MAX_CELLS or 1e9)", optional=True, min_value=1),
        scheduler_parameter("the stereo pairs"),
        OutputRaster("OUTPUT", "DSM GeoTIFF (Float32): median height of the pairs"),
        OutputRaster("COUNT", "pairs with a height in the cell (UInt16, 0 = none)"),
        OutputRaster("SPREAD", "height spread in the cell: highest upper quartile - lowest "
                     "lower quartile of the pairs (Float32)"),
        OutputFile("POINTS", "matched points as LAS/LAZ (colour from the left photo)",
                   extensions=[".laz", ".las"], optional=True),
    ]
    outputs = [Output("STATISTICS", "pairs, disparity ranges, matched fractions, cells",
                      "dict")]

    def check(self, params: dict[str, Any]) -> None:
        from toolbox.io.raster import check_nodata_fits

        check_nodata_fits(params["NODATA"], "float32")  # before the matching, not after it
        if params["MIN_HEIGHT"] >= params["MAX_HEIGHT"]:
            raise self.fail("MAX_HEIGHT", f"must be above MIN_HEIGHT ({params['MIN_HEIGHT']:g}),"
                            f" got {params['MAX_HEIGHT']:g}")
        if params["BLOCK_SIZE"] % 2 == 0:
            raise self.fail("BLOCK_SIZE", f"must be odd, got {params['BLOCK_SIZE']}")
        if params["MIN_BASE_RATIO"] >= params["MAX_BASE_RATIO"]:
            raise self.fail("MAX_BASE_RATIO", "must be above MIN_BASE_RATIO")
        grid_request(params).check()

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.stereo.dsm import run_match

        stats = run_match(match_request(params), feedback)
        return {"OUTPUT": params["OUTPUT"], "COUNT": params["COUNT"], "SPREAD": params["SPREAD"],
                "POINTS": params["POINTS"], "STATISTICS": stats}


def match_request(params: dict[str, Any]):
    """The typed request (:class:`toolbox.stereo.dsm.MatchRequest`) of validated parameters."""
    from toolbox.stereo.dsm import MatchRequest
    from toolbox.stereo.matching import MatchOptions

    photos = [s.strip() for s in str(params["PHOTOS"]).split(",") if s.strip()] \
        if params.get("PHOTOS") else None
    return MatchRequest(
        project=params["PROJECT"], min_height=params["MIN_HEIGHT"],
        max_height=params["MAX_HEIGHT"], output=params["OUTPUT"], count=params["COUNT"],
        spread=params["SPREAD"], photos=photos, min_overlap=params["MIN_OVERLAP"],
        min_base_ratio=params["MIN_BASE_RATIO"], max_base_ratio=params["MAX_BASE_RATIO"],
        max_angle=params["MAX_ANGLE"], pixel_size_mm=params.get("PIXEL_SIZE_MM"),
        options=MatchOptions(params["BLOCK_SIZE"], params["UNIQUENESS"],
                             params["SPECKLE_WINDOW"], params["SPECKLE_RANGE"],
                             params["LR_MAX_DIFF"], params["MAX_DISPARITIES"]),
        grid=grid_request(params), nodata=params["NODATA"], points=params.get("POINTS"),
        executor=executor_of(params))
