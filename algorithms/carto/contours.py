"""carto:contours - contour lines of a DEM or a TIN, index contours flagged, styled for QGIS."""

from __future__ import annotations

from pathlib import Path

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import (
    Integer,
    Layer,
    Number,
    Output,
    OutputFile,
    OutputVector,
    RasterLayer,
    VectorLayer,
)
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter


@register
class Contours(Algorithm):
    """Contour lines ("curve di livello") at ``BASE + k·INTERVAL`` from a DEM or a TIN.

    DEM: cell values sit at cell centres and the surface between four centres is bilinear (as
    ``gdal_contour``); lines are traced by contourpy, or for all levels in one pass by a
    compiled kernel (the same lines) when the levels are many enough to repay its start-up (the
    statistics' ``tracer``; ``kernel_build``: compiled ahead of time by ``toolbox warmup``, with
    no numba start-up, or numba's JIT), in ``TILE_SIZE`` blocks sharing one row and column, and stitched
    across block edges, so big DEMs work in bounded memory and a line
    crossing many blocks comes out whole, with no break and no duplicate. TIN: every triangle's
    plane is cut at each level and the segments are chained through shared edges.

    Every ``INDEX_EVERY``-th level from ``BASE`` is an index contour (``index`` = 1; 5 m
    contours with 25 m index contours at 1:5000). ``SMOOTHING`` rounds of Chaikin corner cutting
    (DEM only) are kept only while a line stays inside its cell band (the grid squares it
    crosses); any two smoothed lines that would touch fall back to their traced shape, so
    contours never cross. Lines are oriented with higher ground on their right. A DEM cell
    exactly at a level with its neighbours all below (a peak) or all above (a pit) makes no
    line there: the isoline is a point (lines shorter than 1e-6 of a cell are left out, counted
    as ``points_dropped``; gdal_contour writes a ring about 1e-5 of a cell long).

    Output: layer ``contours`` (LineString Z at the level's height) with ``elev``, ``index``,
    ``closed``, ``length``, styled in the GeoPackage's ``layer_styles`` (index contours heavier,
    labels along them), as QML and SLD; ``STYLE`` also writes the QML.
    """

    length_units = "horizontal"  # x, y in one unit (metres or feet); heights in their own

    id = "carto:contours"
    display_name = "Contour lines"
    group = "Cartography"
    short_help = "Contours of a DEM (tiled, stitched) or a TIN, index contours, styled GeoPackage."
    parameters = [
        RasterLayer("INPUT", "DEM raster", optional=True, role="heights"),
        VectorLayer("TIN", "TIN: the triangles layer of a tin:delaunay GeoPackage, or "
                    "triangle polygons with Z (instead of INPUT)", geometry_types=["polygon"],
                    optional=True),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        Number("INTERVAL", "contour interval, height units", default=5.0, min_value=0,
               min_exclusive=True),
        Number("BASE", "height of one contour; the others are BASE + k·INTERVAL", default=0.0),
        Integer("INDEX_EVERY", "every N-th contour is an index contour (0 = none)", default=5,
                min_value=0),
        Integer("SMOOTHING", "rounds of band-constrained smoothing (DEM only; 0 = none)",
                default=0, min_value=0, max_value=5),
        Integer("TILE_SIZE", "DEM block side in cells (a block traces only the levels it spans)",
                default=512, min_value=8),
        scheduler_parameter("the blocks"),
        OutputVector("OUTPUT", "contours GeoPackage", layers=[
            Layer("contours", "LineString Z", [("elev", "real", "height of the line"),
                                               ("index", "integer", "1 on index contours"),
                                               ("closed", "boolean", "the line is a ring"),
                                               ("length", "real")],
                  "contour lines, higher ground on their right; styled", style="contours")]),
        OutputFile("STYLE", "QGIS style of the contours (.qml)", extensions=[".qml"],
                   optional=True),
    ]
    outputs = [Output("STATISTICS", "levels, lines, index lines, tiles", "dict")]

    def check(self, params):
        if (params.get("INPUT") is None) == (params.get("TIN") is None):
            raise self.fail("INPUT", "or TIN: give exactly one of them (a DEM or a TIN)")
        if params.get("INPUT") is None and params["SMOOTHING"]:
            raise self.fail("SMOOTHING", f"applies to DEM contours only, got "
                            f"{params['SMOOTHING']} with a TIN")
        if params.get("INPUT") is not None:  # south-up or east to west: traced as they lie
            from toolbox.io.raster import require_north_up

            info = params["INPUT"]
            require_north_up(info.transform, "INPUT", info.path, flips_ok=True)
            if min(info.width, info.height) < 2:  # no square of four centres to trace in
                raise self.fail("INPUT", f"{info} has {info.width} column(s) x {info.height} "
                                "row(s): contours run between cell centres, at least 2 x 2 are "
                                "needed")
            from toolbox.io.raster import has_valid_pixel

            if not has_valid_pixel(info.path):
                raise self.fail("INPUT", f"{info} has no valid cell (every cell is nodata)")

    def planned_files(self, params):
        """A one-layer format (Shapefile, FlatGeobuf, GeoJSON, GeoParquet) has no style table:
        the style goes beside it as ``<stem>.qml``/``.sld``, which QGIS loads with the file."""
        from toolbox.io.vector import is_multi_layer

        out = params.get("OUTPUT")
        if out is None or is_multi_layer(out):
            return {}
        stem = Path(out).stem
        return {"OUTPUT": [f"{stem}.qml", f"{stem}.sld"]}

    # duplicate-ok: process() imports its libraries lazily (toolbox list/help stay light); the
    # lists of lazy imports after a check() look alike across algorithms
    def process(self, params, feedback: Feedback):
        from toolbox.cartography.contour_io import (
            raster_contours,
            tin_layer_contours,
            write_contours,
        )
        from toolbox.cartography.qml import contour_qml, write_contour_style
        from toolbox.io.vector import vector_driver

        interval, base = params["INTERVAL"], params["BASE"]
        if params.get("INPUT") is not None:
            info = params["INPUT"]
            result = raster_contours(info.path, params["BAND"], interval, base,
                                     params["TILE_SIZE"], params["SMOOTHING"], feedback,
                                     executor_of(params))
            crs = info.crs
        else:
            from toolbox.terrain.tin.store import read_tin

            xyz, triangles, crs = read_tin(params["TIN"])
            result = tin_layer_contours(xyz, triangles, interval, base)
        feedback.set_progress(90)
        fields = write_contours(params["OUTPUT"], result.contours, interval, base,
                                params["INDEX_EVERY"], crs, result.min_length)
        # a GeoPackage embeds the style; beside a one-layer file, <stem>.qml/.sld (QGIS's
        # default style of that file)
        if vector_driver(params["OUTPUT"]) == "GPKG":
            qml = write_contour_style(params["OUTPUT"], "contours")
        else:
            from toolbox.cartography.qml import contour_sld
            from toolbox.styles.files import write_style_files

            qml = contour_qml()
            write_style_files(Path(params["OUTPUT"]).with_suffix(""), qml,
                              contour_sld(name="contours"))
        if params.get("STYLE"):
            params["STYLE"].write_text(qml, encoding="utf-8")
        lines = len(fields["elev"])
        if not lines:
            feedback.push_warning(f"no contour at interval {interval} from base {base} crosses the "
                             "surface")
        stats = {"levels": int(len(result.levels)), "lines": lines,
                 "index_lines": int(fields["index"].sum()),
                 "points_dropped": len(result.contours) - lines,  # DEGENERATE_CELL_FRACTION
                 "vertices": int(sum(len(c.xy) for c in result.contours))} | result.stats
        return {"OUTPUT": params["OUTPUT"], "STYLE": params.get("STYLE"), "STATISTICS": stats}
