"""topology:overlay - intersection, union, difference, symmetric difference of two area layers."""

from __future__ import annotations

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.io.crs import common_crs, crs_label
from toolbox.io.vector import read_vector
from toolbox.io.vector_write import write_layers
from toolbox.parameters import Enum, Number, String, VectorLayer
from toolbox.parameters.outputs import Output, OutputVector
from toolbox.registry import register
from toolbox.terrain.points import local_origin
from toolbox.topology.setops import OPERATIONS, clean_polygons, overlay_polygons
from toolbox.ui.topology import ERRORS, OVERLAY_RESULT

RESULT_COLUMNS = ("id", "part", "area", "perimeter")


def _side_columns(frame, index: np.ndarray, prefix: str) -> dict:
    """Attribute columns of ``frame`` for each output piece (null where ``index`` is -1)."""
    import pandas as pd

    out = {}
    present = index >= 0
    rows = np.where(present, index, 0)
    for column in frame.columns:
        if column == frame.geometry.name:
            continue
        values = frame[column]
        if pd.api.types.is_integer_dtype(values.dtype):
            values = values.astype("Int64")
        elif pd.api.types.is_bool_dtype(values.dtype):
            values = values.astype("boolean")
        if len(frame) == 0:
            picked = pd.Series([None] * len(index), dtype=object)
        else:
            picked = values.iloc[rows].reset_index(drop=True)
            picked = picked.where(pd.Series(present))
        out[f"{prefix}{column}"] = picked
    return out


@register
class Overlay(Algorithm):
    """Set operations between two area layers, keeping both sides' attributes (thematic maps,
    thesis S002 §2.4, Fig. 26-28: intersection, union, subtraction).

    OPERATION: ``intersection`` (pieces in both), ``union`` (the intersection pieces plus the
    parts of each layer outside the other), ``difference`` (INPUT minus OVERLAY), or
    ``symmetric_difference`` (the parts in exactly one layer). GEOS does the geometry (OverlayNG
    with snap rounding to PRECISION, robust, no float-noise slivers). Invalid areas are repaired
    with GEOS make_valid and reported; features that cannot be repaired are skipped and reported.

    OUTPUT: a GeoPackage with a layer named after the operation (single polygons: id, part =
    ``a``/``b``/``ab`` for pieces from INPUT only, OVERLAY only or both, area, perimeter, then
    INPUT's fields with INPUT_PREFIX and OVERLAY's with OVERLAY_PREFIX, empty where the piece is
    outside that layer) and ``errors_points``/``errors_lines`` (repairs and skipped features).
    """

    id = "topology:overlay"
    display_name = "Overlay areas"
    group = "Topology"
    short_help = ("Intersection, union, difference or symmetric difference of two area layers, "
                  "keeping both sides' attributes.")
    parameters = [
        VectorLayer("INPUT", "area layer A (e.g. the areas of topology:build_areas)",
                    geometry_types=["polygon"]),
        VectorLayer("OVERLAY", "area layer B (e.g. thematic zones)", geometry_types=["polygon"]),
        Enum("OPERATION", "set operation", options=OPERATIONS, default="intersection"),
        String("INPUT_PREFIX", "prefix of INPUT's fields in the output", default="a_"),
        String("OVERLAY_PREFIX", "prefix of OVERLAY's fields in the output", default="b_"),
        Number("PRECISION", "coordinate grid of the result, CRS units", default=0.001,
               min_value=0, min_exclusive=True),
        OutputVector("OUTPUT", "GeoPackage with the result layer (named after OPERATION), "
                     "errors_points and errors_lines", layers=[OVERLAY_RESULT, *ERRORS]),
    ]
    outputs = [Output("STATISTICS", "pieces by origin, repaired and skipped features", "json")]

    def check(self, params):
        a_fields = [f"{params['INPUT_PREFIX']}{f}" for f in params["INPUT"].fields]
        b_fields = [f"{params['OVERLAY_PREFIX']}{f}" for f in params["OVERLAY"].fields]
        for name, fields in (("INPUT_PREFIX", a_fields), ("OVERLAY_PREFIX", b_fields)):
            clash = [f for f in fields if f.lower() in RESULT_COLUMNS]
            if clash:
                raise self.fail(name, f"{params[name]!r} makes field {clash[0]!r}, which the "
                                "output uses itself; choose another prefix")
        common = {f.lower() for f in a_fields} & {f.lower() for f in b_fields}
        if common:
            raise self.fail("OVERLAY_PREFIX", f"{params['OVERLAY_PREFIX']!r} gives field "
                            f"{sorted(common)[0]!r} to both layers; use different prefixes")

    def process(self, params, feedback: Feedback):
        import shapely

        from toolbox.topology.layers import error_frames, to_frame
        from toolbox.topology.output import ERROR_LAYERS, Layer, issues_layer, order_key

        operation, grid = params["OPERATION"], params["PRECISION"]
        with feedback.timed("read"):
            fa = read_vector(params["INPUT"], name="INPUT")
            fb = read_vector(params["OVERLAY"], name="OVERLAY")
        crs = common_crs({"INPUT": fa.crs, "OVERLAY": fb.crs})
        ga = np.asarray(fa.geometry.values, dtype=object)
        gb = np.asarray(fb.geometry.values, dtype=object)
        valid = [g for g in np.concatenate([ga, gb]) if g is not None and not shapely.is_empty(g)]
        if not valid:
            raise InputDataError("INPUT and OVERLAY have no geometry to overlay")
        bounds = shapely.total_bounds(np.asarray(valid, dtype=object))
        origin = local_origin(np.array([[bounds[0], bounds[1]], [bounds[2], bounds[3]]]))
        origin = np.round(origin / grid) * grid

        def shift(geoms, offset):
            out = geoms.copy()
            has = np.array([g is not None for g in geoms], dtype=bool)
            if has.any():
                out[has] = shapely.transform(geoms[has], lambda c: c + offset)
            return out

        feedback.set_progress(10, "repairing inputs")
        with feedback.timed("clean"):
            ca, issues_a, counts_a = clean_polygons(shift(ga, -origin), "INPUT")
            cb, issues_b, counts_b = clean_polygons(shift(gb, -origin), "OVERLAY")
        feedback.check_canceled()
        feedback.set_progress(30, f"{operation}")
        with feedback.timed("overlay"):
            result = overlay_polygons(ca, cb, operation, grid)
        feedback.check_canceled()
        big = np.iinfo(np.int64).max
        geo_order = order_key(result.geoms, grid)
        rank = np.empty(len(geo_order), dtype=np.int64)
        rank[geo_order] = np.arange(len(geo_order))
        order = np.lexsort((rank, np.where(result.b_index < 0, big, result.b_index),
                            np.where(result.a_index < 0, big, result.a_index)))
        geoms = result.geoms[order]
        ai, bi = result.a_index[order], result.b_index[order]
        part = np.where((ai >= 0) & (bi >= 0), "ab", np.where(ai >= 0, "a", "b")).astype(object)
        columns = {"id": np.arange(1, len(geoms) + 1), "part": part,
                   "area": np.round(shapely.area(geoms), 6),
                   "perimeter": np.round(shapely.length(geoms), 6)}
        columns |= _side_columns(fa, ai, params["INPUT_PREFIX"])
        if operation != "difference":
            columns |= _side_columns(fb, bi, params["OVERLAY_PREFIX"])
        pieces = Layer(shift(geoms, origin), columns)
        errors = issues_layer(issues_a + issues_b, origin, lambda f: 0)
        feedback.set_progress(90, "writing")
        with feedback.timed("write"):
            write_layers(params["OUTPUT"], {operation: to_frame(pieces, crs),
                                            **error_frames(errors, crs)},
                         crs=crs, geometry_types={operation: "Polygon", **ERROR_LAYERS})
        stats = {"operation": operation, "crs": crs_label(crs), "input": counts_a,
                 "overlay": counts_b, **result.counts}
        for issue in issues_a + issues_b:
            if issue.severity == "error":
                feedback.push_warning(f"{issue.detail} (feature {issue.lines[0] + 1})")
        if len(geoms) == 0:
            feedback.push_warning(f"the {operation} is empty")
        return {"OUTPUT": params["OUTPUT"], "STATISTICS": stats}

