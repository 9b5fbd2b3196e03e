"""topology:check - the checks of area building, reported without changing any geometry."""

from __future__ import annotations

from toolbox.feedback import Feedback
from toolbox.parameters.outputs import Output, OutputVector
from toolbox.registry import register
from toolbox.ui.topology import ERRORS, LineworkAlgorithm, build_linework, linework_parameters


@register
class CheckTopology(LineworkAlgorithm):
    """Check restitution linework before area generation (thesis S002 §2.4): closure of the
    polylines that should form an area, lines crossing without an intersection node, near-misses
    between lines that should meet, duplicates, dangles and overshoots, slivers, self-
    intersections, and, with LABELS, areas without a label, areas with conflicting labels and
    labels outside every area.

    Runs the same steps and tolerances as ``topology:build_areas`` in memory and writes only the
    ``errors_points`` and ``errors_lines`` layers (type, severity, detail and input line numbers); the
    input is not changed and no area is written. Severity ``fixable`` marks what build_areas
    would correct by itself (snap, close, node, dedupe, trim, merge), ``error`` what it would
    leave for the operator (dangles kept, unclosed lines, label problems, invalid features). When
    a check reports no ``error``, build_areas gives a clean result.
    """

    id = "topology:check"
    display_name = "Check linework topology"
    group = "Topology"
    short_help = ("Report near-misses, crossings without node, duplicates, unclosed lines, "
                  "dangles, slivers and label problems as an errors layer; no geometry changed.")
    parameters = [
        *linework_parameters(),
        OutputVector("OUTPUT", "GeoPackage with the errors_points and errors_lines layers", layers=ERRORS),
    ]
    outputs = [Output("STATISTICS", "counts of every check, tolerances and their source",
                      "json")]

    def process(self, params, feedback: Feedback):
        from toolbox.topology.layers import write_topology

        output, data, stats = build_linework(params, feedback, "check", 95)
        with feedback.timed("write"):
            write_topology(params["OUTPUT"], output, data["crs"], layers=("errors",))
        for key in ("areas", "arcs", "nodes"):
            stats["output"].pop(key, None)
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
