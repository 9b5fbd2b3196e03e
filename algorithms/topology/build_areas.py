"""topology:build_areas - coded areas, arcs, nodes and an errors layer from restitution lines."""

from __future__ import annotations

from toolbox.feedback import Feedback
from toolbox.parameters.outputs import Output, OutputVector
from toolbox.registry import register
from toolbox.ui.topology import (
    ARCS,
    AREAS,
    ERRORS,
    NODES,
    LineworkAlgorithm,
    build_linework,
    linework_parameters,
)


@register
class BuildAreas(LineworkAlgorithm):
    """Build closed, coded areas from stereo-plotted linework (thesis S002 §2.2.2 and §2.4).

    Restitution delivers lines with a code; GIS deliverables need closed areas. The lines are
    cleaned in steps, each counted in STATISTICS and in the run's messages:

    1. snap line ends to nearby nodes, vertices or segments within SNAP_TOLERANCE
       ("tolleranza di riattacco"); 2. close polylines whose free ends miss by less than
    CLOSURE_TOLERANCE ("tolleranza di chiusura"); 3. node every crossing and dissolve exact and
    overlapping duplicates (GEOS snap-rounding noding on a PRECISION grid); 4. trim overshoots and
    remove dangles shorter than MIN_DANGLE_LENGTH (reported, not silently); 5. polygonize (GEOS);
    6. merge slivers smaller than MIN_AREA into the neighbour sharing the longest boundary; 7. give
    each area the code and attributes of the LABELS point inside it (a spot height's quota becomes
    the area's height, as the thesis describes).

    Area codes come from the code file CODES (§2.4, the code table declares each code's type): a
    closed line whose code is of type polygon codes the area it bounds (a building plotted closed
    with the building code); a line code codes the area it closes only when its ``area`` column
    names that area code (``FAB01002;muro perimetrale;linea;12;AREA_FAB``); other line codes (a
    kerb closed around a block) code nothing. Label codes declared point codes give attributes
    only. Only area codes can conflict: two labels, or a label and a closed line, giving
    different area codes (a label with the line's own code agrees with it). Without CODES a
    closed line's code only fills an area that no label codes, and never conflicts.

    Tolerances come from the explicit parameters, else from the PARAMETERS file (the plotting
    software's "file dei parametri"), else from the defaults (0.2, 0.5, 1.0, 1.0 m², 0.001).

    OUTPUT is one GeoPackage with five layers:
    ``areas`` (id, code and the other label attributes, labels = label points inside, area in
    CRS units², perimeter in CRS units);
    ``arcs`` (each boundary stored ONCE: id, left_area/right_area ids, 0 = outside, codes = the
    original line codes and lines = the input line numbers it came from, length in CRS units:
    the building/pavement edge of the thesis
    exists once and both areas point to it; kept dangles and unclosed lines are arcs with the same
    area on both sides); ``nodes`` (id, degree, kind); ``errors_points``/``errors_lines`` (id,
    type, severity = error for the operator or fixed for what the cleaning changed, detail,
    lines = input line numbers, area_id and label_id, 0 = none). Heights are dropped from the
    lines (areas are planimetric).
    The same input gives the same ids (numbered by position).
    """

    id = "topology:build_areas"
    display_name = "Build areas from linework"
    group = "Topology"
    short_help = ("Clean coded restitution lines (snap, close, node, dedupe, trim) and build "
                  "labelled areas, shared arcs, nodes and an errors layer.")
    parameters = [
        *linework_parameters(),
        OutputVector("OUTPUT", "GeoPackage with layers areas, arcs, nodes, errors_points, "
                     "errors_lines",
                     layers=[AREAS, ARCS, NODES, *ERRORS]),
    ]
    outputs = [Output("STATISTICS", "counts of every cleaning step, tolerances and their source",
                      "json")]

    def process(self, params, feedback: Feedback):
        from toolbox.topology.layers import write_topology

        output, data, stats = build_linework(params, feedback, "build", 90)
        if data["label_geoms"] is None:
            feedback.push_warning("no LABELS given: only areas bounded by a closed coded "
                                  "outline have a code")
        with feedback.timed("write"):
            write_topology(params["OUTPUT"], output, data["crs"], data["label_dtypes"])
        stats["code_field"] = data["code_field"]
        stats["label_code_field"] = data["label_code_field"]
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
