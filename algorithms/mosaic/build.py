"""mosaic:build - one mosaic GeoTIFF from orthos and cut polygons."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Enum, Integer, Number, String, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputRaster, OutputVector
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.mosaic import SEAM_FIELDS, orthos_parameter

BLEND_METHODS = ("none", "feather", "multiband")
RESAMPLING = ("nearest", "bilinear", "cubic", "lanczos")


@register
class MosaicBuild(Algorithm):
    """Join orthos into one mosaic GeoTIFF along cut polygons.

    Each mosaic cell takes the ortho whose cut polygon (CUTLINES, e.g. from mosaic:seamlines;
    default: the Voronoi cells of the orthos' nadir points, else footprint centres) holds it;
    where that ortho has no data, the first ortho by file name that has data fills it, so the
    mosaic has no gap where any input has data. Ties go by file name too, never by the order
    of INPUT (the same orthos in any order give the same mosaic): a cell centre exactly on the
    edge two polygons share (a Voronoi bisector) or inside two overlapping CUTLINES polygons
    takes the ortho whose file name sorts first, and so does the overlap of two orthos with
    one centre.

    BLEND: none (hard cut); feather (each ortho's weight ramps linearly across its polygon's
    edge over FEATHER_WIDTH ground units, weights normalised to sum to 1); multiband (Laplacian
    pyramid blending over LEVELS levels: low frequencies blend over about 2^LEVELS cells, fine
    detail over a few). Farther from the seams than the blend width, cells equal their source.

    BALANCE: one gain and offset per ortho and band from the overlap means and standard
    deviations of every overlapping pair, solved together by least squares with the mean gain
    held at 1 and the mean offset at 0 (no ortho is the reference).

    The grid has the finest input's cell (or CELL_SIZE) over the cut polygons' area; inputs on
    other grids are resampled (RESAMPLING) with a warning. The mosaic is written tile by tile
    (a Cloud Optimized GeoTIFF by default, COG=false: a tiled DEFLATE GeoTIFF with overviews;
    SOURCE_INDEX likewise), with an alpha band if any input has one, else the inputs' nodata
    when they share one (inputs without, or with different ones: NaN nodata for floats, else
    an alpha band). SOURCE_INDEX gets the 1-based input number of each cell (0 = no data),
    and SEAMLINES the seams: exactly the cell
    edges between different sources in the source index (steps of one cell where a seam runs
    diagonally; edges next to no data are not seams), in the layer seamlines (a_id, b_id = the
    1-based input numbers of the two orthos, the lower first; a, b = their file names; method;
    length in CRS units). Their ``method`` is the one
    mosaic:seamlines recorded for the pair when CUTLINES is its GeoPackage, else "cut
    polygons" (other CUTLINES) or "voronoi" (no CUTLINES).
    """

    id = "mosaic:build"
    display_name = "Build mosaic"
    group = "Mosaic"
    short_help = "Orthos + cut polygons -> mosaic GeoTIFF (blending, balancing, source index)."
    parameters = [
        orthos_parameter(),
        VectorLayer("CUTLINES", "cut polygons (mosaic:seamlines' cut_polygons layer; default: "
                    "Voronoi cells)", geometry_types=["polygon"], optional=True,
                    known_layer="cut_polygons"),
        String("SOURCE_FIELD", "field of CUTLINES holding the ortho file names (or 1-based "
               "input numbers)", default="source"),
        Enum("BLEND", "blending across seams", options=BLEND_METHODS, default="feather"),
        Number("FEATHER_WIDTH", "feathering width, ground units (default: 8 cells)",
               optional=True, min_value=0),
        Integer("LEVELS", "pyramid levels for BLEND=multiband", default=4, min_value=1,
                max_value=10),
        Boolean("BALANCE", "balance gains and offsets over the block", default=False),
        Number("CELL_SIZE", "mosaic cell size (default: the finest input's)", optional=True,
               min_value=0, min_exclusive=True),
        Enum("RESAMPLING", "resampling of inputs off the mosaic grid", options=RESAMPLING,
             default="bilinear"),
        Boolean("COG", "write the mosaic and SOURCE_INDEX as Cloud Optimized GeoTIFFs (false: "
                "tiled GeoTIFFs with internal overviews)", default=True),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        scheduler_parameter(),
        OutputRaster("OUTPUT", "mosaic GeoTIFF"),
        OutputRaster("SOURCE_INDEX", "source index raster (1-based input number, 0 = none)",
                     optional=True),
        OutputVector("SEAMLINES", "seamlines GeoPackage", optional=True, layers=[
            Layer("seamlines", "MultiLineString", SEAM_FIELDS,
                  "the boundaries between different sources in the source index")]),
    ]
    outputs = [Output("STATISTICS", "grid, cells per source, gains and offsets", "dict")]

    def check(self, params):
        if params["FEATHER_WIDTH"] is not None and params["BLEND"] != "feather":
            raise self.fail("FEATHER_WIDTH", f"applies to BLEND=feather, got BLEND="
                            f"{params['BLEND']}")

    # duplicate-ok: process() imports its libraries lazily (toolbox list/help stay light); the
    # lists of lazy imports after a check() look alike across algorithms
    def process(self, params, feedback: Feedback):
        import shapely

        from toolbox.io.crs import crs_label
        from toolbox.io.vector_write import write_layers
        from toolbox.mosaic.balance import block_statistics, solve_gain_offset
        from toolbox.mosaic.block import (
            cells_from_layer,
            centres_of,
            close_block,
            mosaic_grid,
            name_order,
            open_block,
            seam_methods,
            seams_frame,
            union_area,
        )
        from toolbox.mosaic.build import TILE_SIZE, MosaicPlan, write_mosaic
        from toolbox.mosaic.index_seams import index_raster_seams
        from toolbox.mosaic.partition import voronoi_cells

        inputs, crs = open_block([i.path for i in params["INPUT"]], "INPUT", feedback)
        try:
            # the block is mosaicked in file-name order (ties, fallback source, grid, band
            # names), so the mosaic does not depend on the order of INPUT
            order = name_order(inputs)
            sources = [inputs[k] for k in order]
            if params["CUTLINES"] is not None:
                cells = cells_from_layer(params["CUTLINES"], params["SOURCE_FIELD"], inputs,
                                         crs=crs, feedback=feedback)
                cells = [cells[k] for k in order]
            else:
                cells = voronoi_cells([s.footprint for s in sources],
                                      centres_of(sources, "nadir", None, feedback))
            area = shapely.union_all([c for c in cells if not c.is_empty] or [union_area(sources)])
            grid = mosaic_grid(sources, crs, params["CELL_SIZE"], area.union(union_area(sources)),
                               feedback)
            dtype, n_bands = sources[0].dtype, len(sources[0].data_bands)  # one kind: open_block
            gains = offsets = None
            if params["BALANCE"] and len(sources) > 1:
                with feedback.timed("balance"):
                    stats = block_statistics(sources, [s.footprint for s in sources], crs)
                    gains, offsets = solve_gain_offset(stats, len(sources), n_bands)
            feather = params["FEATHER_WIDTH"]
            feather_cells = 8.0 if feather is None else feather / grid.cell_size[0]
            plan = MosaicPlan(sources, cells, grid, n_bands, dtype, params["BLEND"], feather_cells,
                              params["LEVELS"], gains, offsets, params["RESAMPLING"])
            if plan.blend in ("feather", "multiband"):  # refused before any tile is read
                from toolbox.limits import check_size

                if plan.blend == "feather":
                    cell = grid.cell_size[0]
                    name = "FEATHER_WIDTH"
                    value = f"{feather_cells * cell:g} ({feather_cells:,.0f} cells of {cell:g})"
                else:
                    name, value = "LEVELS", f"{params['LEVELS']}"
                check_size("window cells", plan.window_cells(TILE_SIZE), name,
                           f"{value}: a halo of {plan.halo():,} cells around each "
                           f"{TILE_SIZE}-cell tile", f"use a smaller {name}", "cells per tile")
            alpha = any(s.alpha_band is not None for s in sources)
            # the orthos' nodata when they share one; an ortho without (or with another) may
            # hold that value as valid data (its black pixels were turned into no data)
            kinds = {"nan" if s.nodata is not None and s.nodata != s.nodata else s.nodata
                     for s in sources}
            nodata = sources[0].nodata if len(kinds) == 1 else None
            if not alpha and nodata is None:  # every value valid (or a mask band), or not one
                from toolbox.raster.writer import empty_marker

                nodata, alpha = empty_marker(dtype)
            index = params["SOURCE_INDEX"]
            scratch = None
            if index is None and params["SEAMLINES"] is not None:  # the seams come from the index
                import tempfile
                from pathlib import Path

                # in the output's staging folder (the run's storage, not the client's /tmp;
                # removed with the folder if the run is killed), read here only: no overviews
                scratch = tempfile.TemporaryDirectory(prefix=".toolbox-index-", dir=Path(
                    params["OUTPUT"]).expanduser().absolute().parent)
                index = Path(scratch.name) / "source_index.tif"
            try:
                with feedback.timed("mosaic"):
                    stats = write_mosaic(plan, params["OUTPUT"], index, alpha=alpha,
                                         nodata=None if alpha else nodata, cog=params["COG"],
                                         overviews=params["OVERVIEWS"],
                                         index_finished=scratch is None,
                                         executor=executor_of(params),
                                         feedback=feedback.step(5, 95))
                if params["SEAMLINES"] is not None:
                    with feedback.timed("seams"):
                        seams, _ = index_raster_seams(index)
                    if params["CUTLINES"] is not None:
                        methods = seam_methods(params["CUTLINES"], sources)
                        default = "cut polygons"
                    else:
                        methods, default = {}, "voronoi"
                    write_layers(params["SEAMLINES"], {"seamlines": seams_frame(
                        inputs, seams, crs, methods, default)},  # input numbers (the index's)
                        geometry_types={"seamlines": "MultiLineString"})
            finally:
                if scratch is not None:
                    scratch.cleanup()
            back = sorted(range(len(order)), key=order.__getitem__)  # input k at back[k]
            return {"OUTPUT": params["OUTPUT"], "SOURCE_INDEX": params["SOURCE_INDEX"],
                    "SEAMLINES": params["SEAMLINES"], "STATISTICS": {
                        "crs": crs_label(crs), "width": grid.width, "height": grid.height,
                        "cell_size": grid.cell_size[0], "bounds": list(grid.bounds),
                        "blend": params["BLEND"], "alpha": alpha, **stats,
                        "gains": None if gains is None else gains[back].round(5).tolist(),
                        "offsets": None if offsets is None else
                        offsets[back].round(4).tolist()}}  # in input order
        finally:
            close_block(inputs)
