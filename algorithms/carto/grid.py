"""carto:grid - the map grid ("parametratura") of an extent or of map sheets, with labels."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, Enum, Number
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.cartography import sheet_parameters, sheet_source


@register
class Grid(Algorithm):
    """The map grid: a square mesh of ``MAP_STEP`` millimetres on paper (10 cm in the thesis,
    S002 §2.2.3), so ``SCALE · MAP_STEP / 1000`` metres on the ground: 500 m at 1:5000, 50 m at
    1:500. Grid values are multiples of the step (tied to the CRS origin, as on Italian map
    sheets), generated from the extent's corners.

    ``STYLE`` ``lines`` draws full grid lines; ``crosses`` draws a cross of ``CROSS_SIZE`` mm at
    each node. Labels (layer ``grid_labels``: ``text``, ``axis`` x/y, ``value``, ``edge``) sit
    where the grid meets the frame. For a sheet grid (``SHEETS``), every sheet gets its own grid
    clipped to the sheet, with the sheet id in ``sheet``; a grid line cut by a hole of the sheet
    is one MultiLineString (the layer holds MultiLineStrings only). A sheet that crosses itself
    is repaired (GEOS make_valid, with a warning); a null or empty sheet, or one without area,
    is refused.
    """

    id = "carto:grid"
    display_name = "Map grid (parametratura)"
    group = "Cartography"
    short_help = "Map grid every 10 cm on paper (500 m at 1:5000) as lines or crosses, labelled."
    parameters = [
        *sheet_parameters("area: 'xmin,ymin,xmax,ymax EPSG:3003' (CRS optional)",
                               "map sheets (polygons) instead of EXTENT"),
        Number("MAP_STEP", "grid step on paper, mm", default=100.0, min_value=0,
               min_exclusive=True),
        Enum("STYLE", "grid drawing", options=["crosses", "lines"], default="crosses"),
        Number("CROSS_SIZE", "cross size on paper, mm (STYLE crosses)", default=10.0,
               min_value=0, min_exclusive=True),
        Crs("CRS", "CRS of EXTENT or SHEETS when they name none (one naming another CRS "
            "is refused)", optional=True),
        OutputVector("OUTPUT", "grid GeoPackage (layers grid, grid_labels)", layers=[
            Layer("grid", "MultiLineString", [("sheet", "string"), ("kind", "string"),
                                              ("value", "real", "the coordinate drawn")],
                  "grid lines or crosses"),
            Layer("grid_labels", "Point", [("sheet", "string"), ("text", "string"),
                                           ("axis", "string"), ("value", "real"),
                                           ("edge", "string")], "coordinate labels")]),
    ]
    outputs = [Output("STATISTICS", "ground step, counts", "dict")]

    def check(self, params):
        sheet_source(params)

    def process(self, params, feedback: Feedback):
        from toolbox.cartography.grid_io import MapGridRequest, grid_frames
        from toolbox.io.vector_write import write_layers

        sheets = sheet_source(params)
        grid, labels, step, crs = grid_frames(MapGridRequest(
            sheets, params["SCALE"], params["MAP_STEP"], params["STYLE"], params["CROSS_SIZE"]),
            feedback.push_warning)
        write_layers(params["OUTPUT"], {"grid": grid, "grid_labels": labels}, crs=crs,
                     geometry_types={"grid": "MultiLineString", "grid_labels": "Point"})
        return {"OUTPUT": params["OUTPUT"],
                "STATISTICS": {"ground_step": step, "features": len(grid),
                               "labels": len(labels)}}
