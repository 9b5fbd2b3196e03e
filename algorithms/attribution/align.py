"""attribution:align - nearly collinear vertices made collinear within the alignment tolerance."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import VectorLayer
from toolbox.parameters.outputs import Output
from toolbox.registry import register
from toolbox.ui.attribution import edited_output, parameter_file_parameter
from toolbox.ui.parameter_file import file_backed

# parameter -> (value name, parameter-file key, default; None: the file's DEFAULTS table)
WANTED = {"TOLERANCE": ("tolerance", "alignment_tolerance", None),
          "PRECISION": ("precision", "decimals", None)}


@register
class Align(Algorithm):
    """Align nearly collinear vertices ("allineamento", thesis S002 §2.2.1 parameter file).

    Along each line or ring, the longest runs of vertices whose interior vertices all lie
    within TOLERANCE ("tolleranza planimetrica di allineamento") of the chord between the run's
    two ends are made collinear: the interior vertices are projected onto the chord (kept, not
    removed; Z unchanged). Line ends and vertices shared with another feature (closer than
    PRECISION) never move and end a run, so connections stay connected. No vertex moves more
    than TOLERANCE.

    OUTPUT has the aligned layer (named as the input layer) and ``moved_vertices`` (feature,
    vertex, dx, dy, displacement).
    """

    id = "attribution:align"
    display_name = "Align vertices"
    group = "Attribution"
    short_help = ("Make nearly collinear vertices of lines and outlines collinear within the "
                  "alignment tolerance; moved vertices reported.")
    parameters = [
        VectorLayer("INPUT", "lines or polygons", geometry_types=["line", "polygon"]),
        parameter_file_parameter(),
        file_backed("TOLERANCE", "largest distance of a vertex from the chord it is moved onto, "
                    "CRS units", "alignment_tolerance"),
        file_backed("PRECISION", "vertices closer than this are one shared vertex", "decimals"),
        edited_output("GeoPackage: aligned layer and moved_vertices"),
    ]
    outputs = [Output("STATISTICS", "vertices moved, largest move", "dict")]

    def process(self, params, feedback: Feedback):
        import numpy as np

        from toolbox.attribution.edit_io import read_parts, write_edited
        from toolbox.attribution.editing import align_vertices
        from toolbox.ui.attribution import file_values

        parts = read_parts(params["INPUT"])
        v, sources = file_values(params, WANTED, self.id, feedback, parts.frame.crs)
        keys = [np.round(c[:, :2] / v["precision"]).astype(np.int64) for c in parts.coords]
        counts: dict[tuple[int, int], int] = {}
        for k in keys:
            for key in {tuple(row) for row in k.tolist()}:
                counts[key] = counts.get(key, 0) + 1
        out, rows = [], []
        for r, (c, k) in enumerate(zip(parts.coords, keys, strict=True)):
            feedback.check_canceled()
            fixed = np.array([counts[tuple(row)] > 1 for row in k.tolist()], dtype=bool)
            if not parts.closed[r]:
                fixed[[0, -1]] = True
            new = align_vertices(c, v["tolerance"], fixed, closed=bool(parts.closed[r]))
            out.append(new)
            d = new[:, :2] - c[:, :2]
            n_check = len(c) - 1 if parts.closed[r] else len(c)
            for i in np.flatnonzero(np.hypot(*d[:n_check].T) > 0):
                rows.append({"feature": str(int(parts.feature[r]) + 1), "vertex": int(i) + 1,
                             "change": "moved", "dx": float(d[i, 0]), "dy": float(d[i, 1]),
                             "displacement": float(np.hypot(*d[i])), "x": new[i, 0],
                             "y": new[i, 1]})
        layer = write_edited(params["OUTPUT"], params["INPUT"], parts, out, rows)
        stats = {"features": len(parts.frame), "moved_vertices": len(rows),
                 "largest_move": max((r["displacement"] for r in rows), default=0.0),
                 "tolerances": v, "tolerance_sources": sources, "layer": layer}
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
