"""attribution:square - building squaring within the squaring tolerances."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Number, VectorLayer
from toolbox.parameters.outputs import Output
from toolbox.registry import register
from toolbox.ui.attribution import edited_output, parameter_file_parameter
from toolbox.ui.parameter_file import file_backed

# parameter -> (value name, parameter-file key, default; None: the file's DEFAULTS table)
WANTED = {"TOLERANCE": ("tolerance", "squaring_tolerance", None),
          "ANGLE_TOLERANCE": ("angle_tolerance", "squaring_angle_tolerance", None),
          "AREA_TOLERANCE": ("area_tolerance", "-", 1.0),
          "PRECISION": ("precision", "decimals", None)}


@register
class Square(Algorithm):
    """Square buildings ("squadratura", thesis S002 §2.2.1 parameter file): walls within
    ANGLE_TOLERANCE degrees of the building's dominant direction (or its perpendicular) are made
    exactly parallel or perpendicular to it, by the smallest (least-squares) move of the
    vertices.

    Vertices closer than PRECISION are one node, so buildings sharing a wall are squared
    together (one dominant direction: the wall direction most wall length lies within
    ANGLE_TOLERANCE of, refined by theta = atan2(sum L sin 4phi, sum L cos 4phi) / 4 over those
    walls; oblique walls stay oblique) and their shared vertices stay shared. A building whose
    vertices would move more than TOLERANCE ("tolleranza planimetrica di squadratura"), or
    whose area would change by more than AREA_TOLERANCE percent, is left as it was (with its
    neighbours on the offending vertices) and reported: no vertex ever moves beyond TOLERANCE.
    A feature without geometry (null or empty) is kept as it is and reported the same way.

    OUTPUT has the squared layer (named as the input layer, attributes kept, plus ``squared``,
    ``squaring_note`` and ``orientation`` in degrees) and ``moved_vertices`` (each moved
    vertex, its dx, dy and displacement). Tolerances: explicit parameters, else PARAMETERS
    ("tolleranza planimetrica/angolare di squadratura", "numero di cifre decimali"), else 0.2 m,
    3 degrees, 0.001 m.
    """

    id = "attribution:square"
    display_name = "Square buildings"
    group = "Attribution"
    short_help = ("Make building walls exactly perpendicular within the planimetric and angular "
                  "squaring tolerances; shared vertices kept shared; moved vertices reported.")
    parameters = [
        VectorLayer("INPUT", "buildings (polygons)", geometry_types=["polygon"]),
        parameter_file_parameter(),
        file_backed("TOLERANCE", "largest vertex move, CRS units", "squaring_tolerance"),
        file_backed("ANGLE_TOLERANCE", "walls within this many degrees of the dominant "
                    "direction are squared", "squaring_angle_tolerance", max_value=44.9),
        Number("AREA_TOLERANCE", "largest area change, percent [default 1]", min_value=0,
               optional=True),
        file_backed("PRECISION", "vertices closer than this are one shared vertex", "decimals"),
        edited_output("GeoPackage: squared buildings and moved_vertices"),
    ]
    outputs = [Output("STATISTICS", "buildings squared / left, largest move, largest deviation "
                      "from 90 degrees of a corner between squared walls", "dict")]

    def process(self, params, feedback: Feedback):
        import numpy as np

        from toolbox.attribution.edit_io import read_parts, write_edited
        from toolbox.attribution.editing import square_rings
        from toolbox.ui.attribution import file_values

        parts = read_parts(params["INPUT"])
        v, sources = file_values(params, WANTED, self.id, feedback, parts.frame.crs)
        rings = parts.coords
        result = square_rings(rings, parts.feature, v["tolerance"], v["angle_tolerance"],
                              v["area_tolerance"] / 100.0, v["precision"], parts.exterior,
                              len(parts.frame))
        n = len(parts.frame)
        squared = np.zeros(n, dtype=bool)
        note = np.full(n, "", dtype=object)
        orientation = np.full(n, np.nan)
        squared[: len(result.squared)] = result.squared
        for p, reason in result.reasons.items():
            note[p] = reason
        orientation[: len(result.orientation)] = np.round(result.orientation, 6)
        owners: dict[int, list[int]] = {}
        for r, nodes in enumerate(result.node_of_vertex):
            for node in nodes:
                owners.setdefault(int(node), []).append(int(parts.feature[r]) + 1)
        rows = []
        for node, a, b in zip(result.moved, result.before, result.after, strict=True):
            d = b - a
            rows.append({"feature": ";".join(map(str, sorted(set(owners[int(node)])))),
                         "vertex": int(node) + 1, "change": "moved", "dx": float(d[0]),
                         "dy": float(d[1]), "displacement": float(np.hypot(*d)),
                         "x": b[0], "y": b[1]})
        layer = write_edited(params["OUTPUT"], params["INPUT"], parts, result.rings, rows,
                             {"squared": squared, "squaring_note": note,
                              "orientation": orientation})
        stats = {"buildings": n, "squared": int(squared.sum()), "left": int(n - squared.sum()),
                 "moved_vertices": len(rows),
                 "largest_move": max((r["displacement"] for r in rows), default=0.0),
                 "largest_corner_error_deg": result.corner_error,
                 "tolerances": v, "tolerance_sources": sources, "layer": layer,
                 "not_squared": {int(p) + 1: r for p, r in result.reasons.items()}}
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
