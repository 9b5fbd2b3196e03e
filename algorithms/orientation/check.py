"""orientation:check - residuals of control/check points through the whole orientation chain."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Number
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.photogrammetry import (
    control_parameter,
    ground_residuals_layer,
    measured_inputs,
    measurement_parameters,
    report_output,
)


@register
class CheckOrientation(Algorithm):
    """Check orientation results against control and check points measured on the photos.

    INPUT lists image measurements (``point_id``, ``photo``, ``col_px``/``row_px`` or
    ``x_mm``/``y_mm``, as for orientation:intersect); CONTROL the surveyed ground coordinates
    (``id``, ``X``, ``Y``, ``Z``, optional ``role`` control/check). For every measurement of a
    known point, the point is projected through the photo's full model (collinearity with the
    exterior orientation, principal point, radial distortion, interior orientation to pixels)
    and compared with the measurement: image residuals in µm and pixels, **computed minus
    observed** (the toolbox convention). Every known point seen on two or more photos is also
    intersected from its
    measurements (least squares, as orientation:intersect): ground residuals dX, dY, dZ =
    intersected minus surveyed.

    RMSE per photo and for the block (image µm and px, of the residual vectors' lengths,
    sqrt(Σ(vx² + vy²) / n); ground XY, sqrt(Σ(dX² + dY²) / n), and Z separately for control and
    check points); measurements with a residual over THRESHOLD_PX are flagged. With MAP_SCALE
    (denominator, e.g. 5000) the block is judged against the seeds' planimetric rule (thesis
    S002 par. 2.6.6: RMS <= 0.5 mm at the map scale for large scales, 1:5,000 and larger;
    0.3 mm for smaller scales) using the check points' ground RMSE (the control points' when
    there are no check points).

    Outputs: REPORT (JSON: observations, points, photos, block, judgement) and OUTPUT, a
    GeoPackage with ``observations`` (PointZ at the surveyed point, one row per measurement:
    photo, role, res_x_um, res_y_um, res_um, res_px, flagged) and ``ground_residuals``
    (LineStringZ from the surveyed to the intersected point: dx_m, dy_m, dz_m).
    """

    id = "orientation:check"
    display_name = "Check orientation"
    group = "Orientation"
    short_help = "Image and ground residuals of control/check points, RMSE, map-scale judgement."
    parameters = [
        *measurement_parameters(),
        control_parameter(),
        Number("THRESHOLD_PX", "flag measurements whose residual exceeds this, pixels",
               default=1.0, min_value=0, min_exclusive=True),
        Number("MAP_SCALE", "map scale denominator to judge the block against (e.g. 5000)",
               optional=True, min_value=1),
        OutputVector("OUTPUT", "GeoPackage with layers observations and ground_residuals",
                     optional=True, layers=[
                         Layer("observations", "Point Z", [
                             ("point_id", "string"), ("photo", "string"), ("role", "string"),
                             ("res_x_um", "real", "computed - observed, µm"),
                             ("res_y_um", "real"), ("res_um", "real"), ("res_px", "real"),
                             ("flagged", "boolean", "over THRESHOLD_PX")],
                             "one row per measurement of a known point, at the point"),
                         ground_residuals_layer("surveyed -> intersected point")]),
        report_output(optional=False),
    ]
    outputs = [Output("STATISTICS", "block RMSE (µm, m), flagged measurements, judgement",
                      "dict")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.photogrammetry.accuracy import judge_planimetry
        from toolbox.photogrammetry.orientation_check import check_block
        from toolbox.photogrammetry.tables import write_json

        project, measurements, control = measured_inputs(params, control=True)
        result = check_block(project, measurements, control, params["THRESHOLD_PX"])
        block = result["block"]
        if params["MAP_SCALE"] is not None:
            role = "check" if "check_rmse_xy_m" in block else "control"
            rms = block.get(f"{role}_rmse_xy_m")
            if rms is None:
                feedback.push_warning("no known point was intersected (each needs >= 2 photos): "
                                      "the block cannot be judged at MAP_SCALE")
            else:
                result["judgement"] = judge_planimetry(rms, params["MAP_SCALE"]) | {
                    "points_used": role}
                if not result["judgement"]["passes"]:
                    feedback.push_warning(
                        f"the block fails the 1:{params['MAP_SCALE']:g} rule: {role} RMSE XY "
                        f"{rms:.3f} m > {result['judgement']['tolerance_m']:.3f} m")
        behind = [o for o in result["observations"]
                  if o["flagged"] and o["res_um"] is None and o["res_px"] is None]
        if behind:
            feedback.push_warning(
                f"{len(behind)} known point(s) lie behind the photo they are measured on (no "
                "image, no residual; flagged: check their ids): " + ", ".join(
                    f"{o['point_id']} on {o['photo']}" for o in behind[:10]))
        if block["flagged"] > len(behind):
            feedback.push_warning(f"{block['flagged'] - len(behind)} measurement(s) over "
                                  f"{params['THRESHOLD_PX']:g} px")
        result["residual_sign"] = "computed minus observed"
        write_json(params["REPORT"], {"algorithm": self.id, **result})
        if params["OUTPUT"] is not None:
            _write_vectors(params["OUTPUT"], result, project.crs)
        stats = {k: v for k, v in block.items()} | (
            {"passes": result["judgement"]["passes"]} if "judgement" in result else {})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}


def _write_vectors(path, result: dict, crs) -> None:
    import geopandas as gpd
    import shapely

    from toolbox.io.vector_write import write_layers

    obs = [{k: v for k, v in o.items() if k != "xyz"} | {"geometry": shapely.Point(o["xyz"])}
           for o in result["observations"]]
    lines = [{"point_id": p["point_id"], "role": p["role"], "dx_m": p["dx_m"], "dy_m": p["dy_m"],
              "dz_m": p["dz_m"],
              "geometry": shapely.LineString([p["known"], p["intersected"]])}
             for p in result["points"] if "dx_m" in p]
    empty = {"point_id": [], "role": [], "dx_m": [], "dy_m": [], "dz_m": []}
    write_layers(path, {
        "observations": gpd.GeoDataFrame(obs, geometry="geometry", crs=crs),
        "ground_residuals": gpd.GeoDataFrame(lines, geometry="geometry", crs=crs) if lines else
        gpd.GeoDataFrame(empty, geometry=[], crs=crs)},
        crs=crs, geometry_types={"observations": "Point Z", "ground_residuals": "LineString Z"})
