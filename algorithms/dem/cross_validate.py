"""dem:cross_validate - leave-one-out errors of the gridding methods, side by side."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Integer, Number, String
from toolbox.parameters.outputs import Layer, Output, OutputFile, OutputVector
from toolbox.registry import register
from toolbox.terrain.gridding.methods import METHODS
from toolbox.ui.gridding import (
    DEFAULT_MIN_RCOND,
    check_sources,
    method_options,
    point_sources,
    source_parameters,
)

ALL_METHODS = ("nearest", "idw", "plane", "quadratic", "cubic", "tin_linear")


def parse_methods(text: str) -> list[str]:
    """``"idw, quadratic"`` -> ``["idw", "quadratic"]``; ``"all"`` -> every method."""
    names = [t.strip().lower() for t in str(text).replace(";", ",").split(",") if t.strip()]
    if names == ["all"]:
        return list(ALL_METHODS)
    return list(dict.fromkeys(names))


@register
class CrossValidate(Algorithm):
    """Leave-one-out cross-validation of the DEM gridding methods on the data points.

    Each data point in turn is left out and its height predicted from the others by each of
    METHODS, with the same options as the gridding algorithms (dem:nearest, dem:idw,
    dem:plane, dem:quadratic, dem:cubic, dem:tin_linear; the thesis' five methods of S002 par.
    2.5.2 plus the TIN). The report gives, per method, the RMSE, the mean error (bias), the
    mean and maximum absolute error of ``predicted - observed`` and the points not predicted,
    and ranks the methods by RMSE: evidence for choosing the method of a DEM.

    Rules as in gridding: data points are INPUT points and LINES / BREAKLINES vertices, with
    duplicate XY merged first (DUPLICATES); with EXTRAPOLATE off, convex-hull vertices are not
    predicted (they lie outside the hull of the others); MAX_DISTANCE and MIN_NEIGHBOURS apply.
    NEIGHBOURS, when given, is used by every k-nearest method (else each method's default:
    idw 12, plane 8, quadratic 12, cubic 20). For tin_linear each point is predicted from the
    TIN of the other points (breakline vertices stay and are not predicted). A method needs one
    point more than for gridding (cubic 11, quadratic 7, plane and tin_linear 4): with
    METHODS all, those the points are too few for are left out (a warning names them).

    RESIDUALS writes the points with, per method, the predicted height (``<method>_z``) and
    the error (``<method>_err``), to map where a method fails.
    """

    length_units = "horizontal"  # x, y in one unit (metres or feet); heights in their own

    id = "dem:cross_validate"
    display_name = "DEM cross-validation"
    group = "DEM gridding"
    short_help = "Leave-one-out RMSE, mean and max error of each gridding method on the points."
    parameters = [
        *source_parameters(),
        String("METHODS", "comma-separated methods: nearest, idw, plane, quadratic, cubic, "
               "tin_linear, or all", default="all"),
        Integer("NEIGHBOURS", "k nearest points for every k-nearest method (default: each "
                "method's)", optional=True, min_value=1, max_value=256),
        Number("POWER", "IDW weight exponent", default=2.0, min_value=0, min_exclusive=True,
               max_value=16),
        Number("RADIUS", "search radius, CRS units (default: no limit)", optional=True,
               min_value=0, min_exclusive=True),
        Integer("SECTORS", "IDW angular sectors (1 = none; needs RADIUS)", default=1,
                min_value=1, max_value=16),
        Integer("MIN_NEIGHBOURS", "fewer neighbours found: not predicted", default=1,
                min_value=1),
        Number("MIN_RCOND", "polynomial conditioning threshold (see dem:quadratic)",
               default=DEFAULT_MIN_RCOND, min_value=0, min_exclusive=True, max_value=1),
        Number("MAX_DISTANCE", "points farther than this from every other point are not "
               "predicted (CRS units)", optional=True, min_value=0, min_exclusive=True),
        Boolean("EXTRAPOLATE", "also predict the convex-hull vertices (not for tin_linear)",
                default=False),
        Integer("WORKERS", "local threads (default: the CPUs available)", optional=True,
                min_value=1),
        OutputFile("OUTPUT", "JSON report", extensions=[".json"]),
        OutputVector("RESIDUALS", "points with predicted heights and errors per method "
                     "(GeoPackage, layer 'residuals')", optional=True, layers=[
                         Layer("residuals", "Point Z", [("z", "real", "measured height")],
                               "each data point, with <method>_z (leave-one-out prediction) "
                               "and <method>_err (prediction - z) per method")]),
    ]
    outputs = [Output("STATISTICS", "per method: RMSE, mean, max error; ranking", "json")]

    def check(self, params: dict[str, Any]) -> None:
        check_sources(self, params)
        names = parse_methods(params["METHODS"])
        unknown = [n for n in names if n not in METHODS]
        if not names or unknown:
            raise self.fail("METHODS", f"must list methods among {', '.join(ALL_METHODS)} (or "
                            f"'all'), got {params['METHODS']!r}")
        k = params.get("NEIGHBOURS")
        if k is not None:
            for name in names:
                if METHODS[name].min_neighbours > k:
                    raise self.fail("NEIGHBOURS", f"must be >= {METHODS[name].min_neighbours} "
                                    f"for {name}, got {k}")
        if (params.get("SECTORS") or 1) > 1 and params.get("RADIUS") is None:
            raise self.fail("RADIUS", "is required with SECTORS > 1 (a sector search looks for "
                            f"points up to a radius), got SECTORS {params['SECTORS']}")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.io.crs import crs_label
        from toolbox.terrain.gridding.inputs import read_sources, require_points
        from toolbox.terrain.gridding.run import jsonable_options, write_quality
        from toolbox.terrain.gridding.validation import add_worst_point, error_summary, loo_predict

        names = parse_methods(params["METHODS"])
        data = read_sources(point_sources(params), feedback)
        requested = method_options(params)
        n = len(data.xyz)
        short = [m for m in names if n < METHODS[m].min_points + 1]
        if short and len(short) < len(names) and \
                str(params["METHODS"]).strip().lower() == "all":  # the default: those that can
            feedback.push_warning(
                f"METHODS all: {', '.join(short)} left out, too few points for their "
                f"cross-validation ({', '.join(str(METHODS[m].min_points + 1) for m in short)} "
                f"needed, got {n})")
            names = [m for m in names if m not in short]
        for name in names:
            try:
                require_points(data, METHODS[name].min_points + 1, f"cross-validation of {name}")
            except InputDataError as exc:
                raise InputDataError(f"{exc}: leave {name} out of METHODS") from None
        local = data.local
        results: dict[str, Any] = {}
        predictions: dict[str, np.ndarray] = {}
        step = 90.0 / len(names)
        for i, name in enumerate(names):
            method = METHODS[name]
            options = method.options(requested)
            with feedback.timed(f"loo_{name}"):
                predicted, details = loo_predict(
                    method, local, options, bool(params.get("EXTRAPOLATE")), data.segments,
                    feedback.step(i * step, (i + 1) * step), params.get("WORKERS"))
            summary = error_summary(predicted, local[:, 2]) | details
            add_worst_point(summary, data.xyz, predicted)
            summary["options"] = jsonable_options(options)
            results[name] = summary
            predictions[name] = predicted
        ranking = sorted((n for n in names if results[n]["rmse"] is not None),
                         key=lambda n: results[n]["rmse"])
        report = {"what": "leave-one-out cross-validation: error = predicted - observed height",
                  "crs": crs_label(data.crs), "points": len(local), "inputs": data.counts,
                  "duplicates": data.duplicates.as_dict(), "methods": results,
                  "ranking_by_rmse": ranking, "best": ranking[0] if ranking else None}
        write_quality(params["OUTPUT"], report)
        out: dict[str, Any] = {"OUTPUT": params["OUTPUT"], "STATISTICS": report}
        if params.get("RESIDUALS") is not None:
            with feedback.timed("residuals"):
                _write_residuals(params["RESIDUALS"], data, predictions)
            out["RESIDUALS"] = params["RESIDUALS"]
        feedback.set_progress(100)
        return out


def _write_residuals(path, data, predictions: dict[str, np.ndarray]) -> None:
    import geopandas as gpd
    import shapely

    from toolbox.io.vector_write import write_layers

    xyz = data.xyz
    columns: dict[str, Any] = {"z": xyz[:, 2]}
    for name, predicted in predictions.items():
        columns[f"{name}_z"] = predicted
        columns[f"{name}_err"] = predicted - xyz[:, 2]
    frame = gpd.GeoDataFrame(columns, geometry=shapely.points(xyz[:, 0], xyz[:, 1], xyz[:, 2]),
                             crs=data.crs)
    write_layers(path, {"residuals": frame}, geometry_types={"residuals": "Point Z"})
