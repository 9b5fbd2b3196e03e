"""Declared layers of the topology outputs (the specs of topology:build_areas, check, overlay)."""

from __future__ import annotations

from toolbox.parameters import Layer

AREAS = Layer("areas", "Polygon", [
    ("id", "integer", "area id"), ("labels", "integer", "label points inside"),
    ("area", "real", "area, CRS units²"), ("perimeter", "real", "perimeter, CRS units")],
    "coded areas; the label point's code and attributes are copied too", style="areas")
ARCS = Layer("arcs", "LineString", [
    ("id", "integer", "arc id"), ("left_area", "integer", "area id on the left (0: outside)"),
    ("right_area", "integer", "area id on the right (0: outside)"),
    ("codes", "string", "codes of the input lines"), ("lines", "string", "input line numbers"),
    ("length", "real", "length, CRS units")], "shared boundaries between areas")
NODES = Layer("nodes", "Point", [
    ("id", "integer", "node id"), ("degree", "integer", "arcs meeting there"),
    ("kind", "string", "node kind")], "arc end points")
ERROR_FIELDS = (
    ("id", "integer", "error id"), ("type", "string", "check that failed"),
    ("severity", "string", "error or warning"), ("detail", "string", "what was found"),
    ("lines", "string", "input line numbers (1-based, ';'-separated)"),
    ("area_id", "integer", "area concerned (0: none)"),
    ("label_id", "integer", "label point concerned (0: none)"))
#: the error layers (a list: the algorithms declare ``*ERRORS``)
ERRORS = [Layer("errors_points", "Point", ERROR_FIELDS,
                "points where a check failed (empty when none did)", style="errors"),
          Layer("errors_lines", "LineString", ERROR_FIELDS,
                "lines where a check failed (empty when none did)", style="errors")]
OVERLAY_RESULT = Layer("{OPERATION}", "Polygon", [
    ("id", "integer", "piece id"), ("part", "string", "origin: both, a or b"),
    ("area", "real", "area, CRS units²"), ("perimeter", "real", "perimeter, CRS units")],
    "single polygons, named after the operation; the attributes of A and B follow with the "
    "prefixes a_ and b_")
