"""orientation:absolute - 7-parameter spatial similarity of a model or block to ground control."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, File
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.photogrammetry import report_output, table_parameters


@register
class AbsoluteOrientation(Algorithm):
    """Absolute orientation: scale, rotation and translation taking model coordinates to ground
    coordinates (thesis S002 eq. [25], the 7-parameter spatial similarity).

    INPUT lists model points (``id``, ``X``, ``Y``, ``Z`` in the model system, e.g. a relative
    orientation's or a photogrammetric block's); CONTROL the surveyed ground coordinates of some
    of them (``id``, ``X``, ``Y``, ``Z``, optional ``role`` control/check). Control points fix
    the transform; check points are transformed and compared only.

    Model: ``P = λ·R(omega, phi, kappa)·p + T`` with R the rotation matrix used everywhere in the
    toolbox (brief section 3); eq. [25] of the thesis writes ``Rᵀ``, so its angles are those of
    the transposed matrix. Solved by a closed-form start (the rotation aligning the centred point
    sets) and least squares on all 3n equations, on coordinates shifted to the centroids.
    Needs at least 3 control points, not collinear. Residuals are computed minus observed (the
    toolbox convention): transformed minus surveyed. sigma0 = sqrt(Σv²/(3n - 7)); standard deviations from the
    normal matrix (the translation's at the centroid of the control points).

    Outputs: REPORT (JSON: the 7 parameters with standard deviations, sigma0, residuals of every
    control and check point, check-point RMSE) and OUTPUT (GeoPackage layer ``points``: every
    model point transformed to the ground, PointZ, with its residuals where surveyed).
    """

    id = "orientation:absolute"
    display_name = "Absolute orientation (7-parameter similarity)"
    group = "Orientation"
    short_help = "Scale, rotation, translation of model points onto ground control, with residuals."
    parameters = [
        *table_parameters("INPUT", "model points: id, X, Y, Z in the model system"),
        File("CONTROL", "surveyed points: id, X, Y, Z, optional role (control/check)",
             extensions=[".csv", ".txt", ".gpkg"]),
        Crs("CRS", "CRS of the ground coordinates (e.g. EPSG:3003; projected, metres)",
            optional=True),
        OutputVector("OUTPUT", "GeoPackage with layer points (model points on the ground)",
                     optional=True, layers=[Layer("points", "Point Z", [
                         ("point_id", "string"), ("role", "string"),
                         ("vx", "real", "computed - observed"), ("vy", "real"), ("vz", "real")],
                         "every model point transformed to the ground")]),
        report_output(optional=False),
    ]
    outputs = [Output("STATISTICS", "sigma0, scale, check-point RMSE", "dict")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import numpy as np

        from toolbox.errors import InputDataError
        from toolbox.photogrammetry.absolute import PARAMETER_NAMES, fit_similarity
        from toolbox.photogrammetry.tables import control_crs, ground_points, write_json

        m_ids, m_xyz, _ = ground_points(params["INPUT"], params["LAYER"], name="INPUT")
        c_ids, c_xyz, roles = ground_points(params["CONTROL"])
        crs = control_crs(params["CONTROL"], params["CRS"])
        if crs is not None and len(c_xyz):  # one area-of-use check everywhere
            from toolbox.io.crs import check_coordinates_in_area

            check_coordinates_in_area("CONTROL", crs, c_xyz[:, :2], feedback.push_warning)
        model_index = {pid: k for k, pid in enumerate(m_ids)}
        common = [k for k, pid in enumerate(c_ids) if pid in model_index]
        control = [k for k in common if roles[k] == "control"]
        if not common:
            raise InputDataError("CONTROL has no point id in common with INPUT")
        fit = fit_similarity(m_xyz[[model_index[c_ids[k]] for k in control]], c_xyz[control])
        ground = fit.apply(m_xyz)
        points = []
        for k in common:
            v = ground[model_index[c_ids[k]]] - c_xyz[k]
            points.append({"point_id": c_ids[k], "role": roles[k], "vx": float(v[0]),
                           "vy": float(v[1]), "vz": float(v[2])})
        checks = np.array([[p["vx"], p["vy"], p["vz"]] for p in points if p["role"] == "check"])
        std = dict(zip(PARAMETER_NAMES, map(float, fit.std), strict=True))
        report = {"algorithm": self.id, "model": "P = scale * R(omega, phi, kappa) * p + T",
                  "residual_sign": "computed minus observed (transformed - surveyed)",
                  "translation": fit.translation.tolist(), "angles_rad": fit.angles.tolist(),
                  "scale": fit.scale, "std": std, "sigma0": fit.sigma0,
                  "redundancy": fit.redundancy, "control_points": len(control),
                  "points": points}
        stats = {"sigma0": fit.sigma0, "scale": fit.scale, "control_points": len(control)}
        if len(checks):
            stats["check_rmse_xyz"] = [float(v) for v in np.sqrt((checks ** 2).mean(axis=0))]
            report["check_rmse_xyz"] = stats["check_rmse_xyz"]
        write_json(params["REPORT"], report)
        if params["OUTPUT"] is not None:
            import geopandas as gpd
            import shapely

            from toolbox.io.vector_write import write_layers

            by_id = {p["point_id"]: p for p in points}
            rows = [{"point_id": pid, "role": by_id.get(pid, {}).get("role"),
                     "vx": by_id.get(pid, {}).get("vx"), "vy": by_id.get(pid, {}).get("vy"),
                     "vz": by_id.get(pid, {}).get("vz"), "geometry": shapely.Point(xyz)}
                    for pid, xyz in zip(m_ids, ground, strict=True)]
            write_layers(params["OUTPUT"], {"points": gpd.GeoDataFrame(rows, crs=crs)}, crs=crs,
                         geometry_types={"points": "Point Z"})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}
