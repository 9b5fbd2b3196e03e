"""attribution:sample - curve sampling by distance and angle ("per vettori"), and densification."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, Number, VectorLayer
from toolbox.parameters.outputs import Output
from toolbox.registry import register
from toolbox.ui.attribution import edited_output, parameter_file_parameter
from toolbox.ui.parameter_file import file_backed

# parameter -> (value name, parameter-file key, default; None: the file's DEFAULTS table)
WANTED = {"DISTANCE": ("distance", "spline_step", None),
          "ANGLE": ("angle", "-", 10.0),
          "TOLERANCE": ("tolerance", "-", None),
          "PRECISION": ("precision", "decimals", None)}


@register
class Sample(Algorithm):
    """Resample curves (thesis S002 §2.2.2).

    METHOD=vectors is the thesis' "campionamento per vettori": along the plotted vertices a
    vertex is kept when its distance from the last kept one reaches DISTANCE, or when the
    direction from the last kept vertex turns by more than ANGLE degrees from the line through
    the last two kept ones (the ends are always kept). METHOD=distance puts a vertex every
    DISTANCE along the line (Z interpolated; poor where curvature is high, as the thesis notes).
    METHOD=densify adds vertices so that no segment is longer than DISTANCE.

    DISTANCE defaults to the parameter file's "passo di spline". With TOLERANCE, a feature
    whose original vertices would end farther than TOLERANCE from the new line is left
    unchanged and reported. OUTPUT has the sampled layer and ``moved_vertices`` (removed
    vertices at their place with their distance from the new line, added vertices with 0).
    """

    id = "attribution:sample"
    display_name = "Sample curves"
    group = "Attribution"
    short_help = ("Curve sampling by distance and angle deviation ('per vettori'), constant-step "
                  "resampling, densification; changed vertices reported.")
    parameters = [
        VectorLayer("INPUT", "lines (or polygons, by their rings)",
                    geometry_types=["line", "polygon"]),
        parameter_file_parameter(),
        Enum("METHOD", "vectors (distance + angle), distance (constant step) or densify",
             options=["vectors", "distance", "densify"], default="vectors"),
        file_backed("DISTANCE", "largest distance between kept vertices / the step, CRS units",
                    "spline_step", min_exclusive=True),
        Number("ANGLE", "direction change that records a vertex, degrees (METHOD=vectors) "
               "[default 10]", min_value=0, max_value=180, optional=True),
        Number("TOLERANCE", "largest distance of an original vertex from the new line; features "
               "beyond it are left unchanged [default: no limit]", min_value=0, optional=True),
        edited_output("GeoPackage: sampled layer and moved_vertices"),
    ]
    outputs = [Output("STATISTICS", "vertices before/after, largest deviation", "dict")]

    def process(self, params, feedback: Feedback):
        import numpy as np

        from toolbox.attribution.edit_io import MovedVertices, read_parts, write_edited
        from toolbox.attribution.editing import densify, deviation, sample_by_distance, sample_by_vectors
        from toolbox.errors import InputDataError
        from toolbox.ui.attribution import file_values

        parts = read_parts(params["INPUT"])
        v, sources = file_values(params, WANTED, self.id, feedback, parts.frame.crs)
        method, step = params["METHOD"], v["distance"]
        if method != "vectors":  # a vertex every DISTANCE: refused before any is made
            from toolbox.limits import check_size

            length = float(sum(np.hypot(*np.diff(c[:, :2], axis=0).T).sum()
                               for c in parts.coords))
            check_size("vertices", length / step + len(parts.coords), "DISTANCE",
                       f"{step:g} along {length:,.0f} units of lines", "use a larger DISTANCE")
            if method == "densify":  # each added vertex is also a moved_vertices feature
                check_size("features", length / step, "DISTANCE",
                           f"{step:g} along {length:,.0f} units of lines", "use a larger DISTANCE",
                           "added vertices (a moved_vertices point each)")
        out, rows, left, collapsed = [], MovedVertices(), set(), set()
        largest = 0.0
        for r, c in enumerate(parts.coords):
            feedback.check_canceled()
            feature = str(int(parts.feature[r]) + 1)
            if len(c) < 2:
                out.append(c)
                continue
            if not np.hypot(*np.diff(c[:, :2], axis=0).T).sum() > 0:
                raise InputDataError(f"INPUT feature {feature} has zero length (every vertex "
                                     f"at one point, {len(c)} vertices): nothing to sample; "
                                     "remove or fix it")
            if method == "densify":
                new, added = densify(c, step)
                where = np.flatnonzero(added)
                rows.add(feature, where + 1, "added", new[where, 0], new[where, 1])
                out.append(new)
                continue
            if method == "vectors":
                keep = sample_by_vectors(c, step, v["angle"])
                new = c[keep]
                removed = np.setdiff1d(np.arange(len(c)), keep)
            else:
                new = sample_by_distance(c, step)
                removed = np.arange(1, len(c) - 1)
            dist = deviation(c, new)
            if v["tolerance"] is not None and dist.max() > v["tolerance"]:
                left.add(feature)
                out.append(c)
                continue
            if parts.closed[r] and parts.kinds[int(parts.feature[r])] == "polygon" \
                    and len(new) < 4:  # a ring needs 3 distinct vertices + the closing one
                collapsed.add(feature)
                out.append(c)
                continue
            largest = max(largest, float(dist.max()))
            rows.add(feature, removed + 1, "removed", c[removed, 0], c[removed, 1],
                     displacement=dist[removed])
            out.append(new)
        layer = write_edited(params["OUTPUT"], params["INPUT"], parts, out, rows)
        stats = {"features": len(parts.frame), "method": method,
                 "vertices_before": int(sum(len(c) for c in parts.coords)),
                 "vertices_after": int(sum(len(c) for c in out)),
                 "largest_deviation": largest,
                 "left_unchanged": sorted(left | collapsed, key=int),
                 "parameters": v, "sources": sources, "layer": layer}
        if left:
            feedback.push_warning(f"{len(left)} features left unchanged: sampling would move "
                                  f"them more than TOLERANCE ({v['tolerance']:g})")
        if collapsed:
            feedback.push_warning(f"{len(collapsed)} polygons left unchanged: sampling with "
                                  f"DISTANCE {step:g} would leave fewer than 3 vertices in a "
                                  f"ring (features {', '.join(sorted(collapsed, key=int))})")
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}
