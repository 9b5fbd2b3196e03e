"""The topology algorithms' shared parameters, their declared output layers (the specs of
topology:build_areas, check, overlay) and the translation of their parameters to requests."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.parameters import Field, File, VectorLayer
from toolbox.parameters.outputs import Layer
from toolbox.topology.inputs import LineworkSources
from toolbox.topology.tolerances import TOLERANCE_PARAMETERS
from toolbox.ui.parameter_file import file_backed

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
    ("severity", "string", "error, fixed or fixable"), ("detail", "string", "what was found"),
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


def linework_parameters() -> list:
    """INPUT, CODE_FIELD, LABELS, LABEL_CODE_FIELD, CODES, PARAMETERS and the tolerances."""
    return [
        VectorLayer("INPUT", "restitution lines with a code field (polygons are used by their "
                    "rings)", geometry_types=["line", "polygon"]),
        Field("CODE_FIELD", "field with the line code (default: a field named code or codice)",
              parent="INPUT", optional=True),
        VectorLayer("LABELS", "label points: a code and attributes (e.g. quota) for the area "
                    "they fall in", geometry_types=["point"], optional=True),
        Field("LABEL_CODE_FIELD", "field with the area code of the label points (default: a "
              "field named code or codice)", parent="LABELS", optional=True),
        File("CODES", "code file ('file dei codici'): which codes are area codes (type polygon) "
             "and which area code a closed line of a line code gives (its area column); only "
             "area codes can conflict. Without it a closed line's code only fills an area no "
             "label codes", optional=True),
        File("PARAMETERS", "parameter file ('file dei parametri': tolleranza di riattacco, "
             "tolleranza di chiusura, ...); explicit tolerances override it", optional=True),
        file_backed("SNAP_TOLERANCE", "snap (riattacco) distance for line ends, CRS units",
                    "snap_tolerance"),
        file_backed("CLOSURE_TOLERANCE", "largest gap closed between the two ends of a "
                    "polyline", "closure_tolerance"),
        file_backed("MIN_DANGLE_LENGTH", "shorter dangles and overshoots are removed, longer "
                    "ones reported", "min_dangle_length"),
        file_backed("MIN_AREA", "smaller areas are slivers, merged into a neighbour, square CRS "
                    "units", "min_area"),
        file_backed("PRECISION", "coordinate grid of the result, CRS units", "decimals"),
    ]


def linework_sources(params: Mapping[str, Any]) -> LineworkSources:
    """INPUT, CODE_FIELD, LABELS, LABEL_CODE_FIELD, CODES, PARAMETERS."""
    return LineworkSources(lines=params["INPUT"], code_field=params.get("CODE_FIELD"),
                           labels=params.get("LABELS"),
                           label_code_field=params.get("LABEL_CODE_FIELD"),
                           codes=params.get("CODES"), parameters=params.get("PARAMETERS"))


def explicit_tolerances(params: Mapping[str, Any]) -> dict[str, float | None]:
    """The tolerances given as parameters (None: not given)."""
    return {name: params.get(name) for name in TOLERANCE_PARAMETERS}


def check_linework(params: Mapping[str, Any]) -> None:
    """Before any work: a bad parameter file, PRECISION or CODES file fails."""
    from toolbox.topology.layers import tolerances_from

    tolerances_from(explicit_tolerances(params), params.get("PARAMETERS"))
    if params.get("CODES") is not None:
        from toolbox.io.code_file import read_code_file

        read_code_file(params["CODES"], "CODES")


def check_precision(precision: float, geoms: Any) -> None:
    """Refuse a coordinate grid finer than the coordinates can hold: below 1e-12 of their
    largest magnitude (float64 keeps about 1e-16), snap rounding degenerates."""
    import shapely

    from toolbox.errors import ParameterError

    coords = shapely.get_coordinates(geoms)
    magnitude = float(abs(coords).max()) if len(coords) else 0.0
    if precision > 0 and precision < 1e-12 * max(magnitude, 1.0):
        raise ParameterError("PRECISION", f"{precision:g} is finer than coordinates of "
                             f"{magnitude:,.0f} can hold; expected >= "
                             f"{1e-12 * max(magnitude, 1.0):.1g} (CRS units), e.g. 0.001")


def build_linework(params: Mapping[str, Any], feedback: Any, mode: str, end: float
                   ) -> tuple[Any, dict[str, Any], dict[str, Any]]:
    """Read the linework and run area building in ``mode`` ("build" or "check") up to
    ``end`` % of the progress: (TopologyOutput, the inputs read, STATISTICS: the output's
    counts, the tolerances' sources, the area codes' source, the CRS)."""
    from toolbox.topology.build import build_topology
    from toolbox.topology.inputs import read_linework
    from toolbox.topology.layers import tolerances_from

    data = read_linework(linework_sources(params), feedback)
    tol, sources, _ = tolerances_from(explicit_tolerances(params), params.get("PARAMETERS"),
                                      feedback, data["crs"])
    check_precision(tol.precision, data["line_geoms"])
    output = build_topology(data["line_geoms"], data["line_codes"], data["label_geoms"],
                            data["label_codes"], data["label_attributes"], tol,
                            feedback.step(0, end), mode=mode, area_codes=data["area_codes"])
    stats = dict(output.statistics)
    stats["tolerance_sources"] = sources
    stats["area_codes"] = "CODES" if data["area_codes"] is not None else \
        "none (no CODES: closed lines only fill uncoded areas)"
    stats["crs"] = data["crs_label"]
    return output, data, stats


class LineworkAlgorithm(Algorithm):
    """Base of the algorithms on restitution linework (topology:check, topology:build_areas):
    their parameter file, PRECISION and CODES are checked before any work."""

    def check(self, params):
        check_linework(params)
