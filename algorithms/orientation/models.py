"""orientation:models - independent-model block adjustment (planimetric or spatial)."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, Enum, File
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register
from toolbox.ui.photogrammetry import TABLE_EXTENSIONS, report_output, table_parameters


@register
class IndependentModels(Algorithm):
    """Block adjustment by independent models (004 sl. 5-16; 002 par. 1.5): every stereo model
    (e.g. from orientation:relative) is transformed onto the ground at once, so that tie points
    (and projection centres, listed as points) coincide and control points fit.

    INPUT: model coordinates, one row per point per model: ``model``, ``point_id``, ``x``, ``y``,
    ``z``. CONTROL: ``id``, ``X``, ``Y``, ``Z`` (blank X/Y: height point, blank Z: planimetric),
    optional ``role`` control/check; the known components of control points are taken as exact
    (the slides' control), check points only compared (adjusted minus surveyed, m).

    MODE ``planimetric``: a plane conformal transformation per model, ``X = Xu + a·x - b·y``,
    ``Y = Yu + a·y + b·x`` (linear), unknown X, Y per tie point; 2 equations per point per model
    (004 sl. 9: 4 models, 4 control and 5 tie points give 26 unknowns, 32 equations,
    redundancy 6). ``spatial``: a 7-parameter similarity per model, X, Y, Z per tie point, the
    height block from mixed control (2 XY + 3 Z suffice); 3 equations per point per model, solved
    by Levenberg-Marquardt from models chained by closed-form similarities. Its result also gives
    start values for orientation:bundle.

    OUTPUT (GeoPackage) layer ``points``: adjusted ground points (role tie/control/isolated,
    number of models, largest residual). REPORT (JSON): unknowns, equations, redundancy, sigma0
    (m), the parameters of each model and every residual (transformed model point minus ground).
    """

    id = "orientation:models"
    display_name = "Independent-model block adjustment"
    group = "Orientation"
    short_help = "Block adjustment by independent models: planimetric (4 parameters per model) " \
                 "or spatial (7), from model coordinates and control."
    parameters = [
        *table_parameters("INPUT", "model coordinates: model, point_id, x, y, z"),
        File("CONTROL", "control points: id, X, Y, Z (blank X/Y or Z allowed)",
             extensions=TABLE_EXTENSIONS),
        Crs("CRS", "CRS of the ground coordinates (e.g. EPSG:3003; projected, metres)",
            optional=True),
        Enum("MODE", "planimetric (plane conformal) or spatial (7-parameter similarity)",
             options=("spatial", "planimetric"), default="spatial"),
        OutputVector("OUTPUT", "GeoPackage with layer points", layers=[
            Layer("points", "Point Z", [("point_id", "string"), ("role", "string"),
                                        ("n_models", "integer"),
                                        ("max_residual_m", "real")],
                  "adjusted ground points (MODE planimetric: X, Y without Z)")]),
        report_output(),
    ]
    outputs = [Output("STATISTICS", "unknowns, equations, redundancy, sigma0 (m)", "dict")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import geopandas as gpd
        import numpy as np
        import shapely

        from toolbox.io.crs import check_coordinates_in_area
        from toolbox.io.vector_write import write_layers
        from toolbox.photogrammetry.tables import (
            column,
            control_crs,
            number,
            read_table,
            write_json,
        )
        from toolbox.triangulation.inputs import read_control
        from toolbox.triangulation.models import ModelsRequest, adjust_models

        path = params["INPUT"]
        header, rows = read_table(path, params["LAYER"])
        c_model = column(header, "model", "model_id", path=path)
        c_id = column(header, "point_id", "id", "point", path=path)
        cols = [column(header, n, n.upper(), path=path) for n in ("x", "y", "z")]
        xyz = np.array([[number(r[c], f"row {k + 1} {c}") for c in cols]
                        for k, r in enumerate(rows)])
        control = read_control(params["CONTROL"])
        crs = control_crs(params["CONTROL"], params["CRS"])
        if crs is not None:  # a pyproj CRS (geographic ones refused by the runner)
            check_coordinates_in_area("CONTROL", crs, control.xyz[:, :2], feedback.push_warning)
        use = [k for k, role in enumerate(control.roles) if role == "control"]
        request = ModelsRequest([r[c_model] for r in rows], [r[c_id] for r in rows], xyz,
                                [control.ids[k] for k in use], control.xyz[use], params["MODE"])
        result = adjust_models(request)
        mi = np.array([result.points.index(r[c_id]) for r in rows])
        n_models = np.bincount(mi, minlength=len(result.points))
        res_norm = np.linalg.norm(result.residuals, axis=1)
        worst = np.zeros(len(result.points))
        np.maximum.at(worst, mi, res_norm)
        known = {control.ids[k] for k in use}
        checks = {}
        for k, role in enumerate(control.roles):
            if role == "check" and control.ids[k] in result.points:
                g = result.ground[result.points.index(control.ids[k])]
                checks[control.ids[k]] = (g - control.xyz[k][:len(g)]).tolist()
        features = []
        for k, pid in enumerate(result.points):
            g = result.ground[k]
            pt = g[:3]  # planimetric: X, Y only (no height was adjusted: none made up)
            role = "control" if pid in known else "check" if pid in checks else \
                ("tie" if n_models[k] > 1 else "isolated")
            features.append({"point_id": pid, "role": role, "n_models": int(n_models[k]),
                             "max_residual_m": float(worst[k]), "geometry": shapely.Point(pt)})
        write_layers(params["OUTPUT"], {"points": gpd.GeoDataFrame(features, geometry="geometry",
                                                                   crs=crs)},
                     crs=crs, geometry_types={"points": "Point Z"})
        stats = {"mode": params["MODE"], "models": len(result.models),
                 "points": len(result.points), "unknowns": result.unknowns,
                 "equations": result.equations, "redundancy": result.redundancy,
                 "sigma0_m": None if np.isnan(result.sigma0_m) else result.sigma0_m,
                 "check_residuals_m": checks}
        if params["REPORT"] is not None:
            names = ("Xu", "Yu", "a", "b") if params["MODE"] == "planimetric" else \
                ("TX", "TY", "TZ", "omega", "phi", "kappa", "scale")
            write_json(params["REPORT"], {
                "algorithm": self.id, **stats, "notes": result.notes,
                "residual": "transformed model point minus ground point, m",
                "model_parameters": [dict(model=m, **dict(zip(names, map(float, p), strict=True)))
                                     for m, p in zip(result.models, result.parameters,
                                                     strict=True)],
                "residuals": [{"model": r[c_model], "point_id": r[c_id],
                               "v": result.residuals[k].tolist()} for k, r in enumerate(rows)]})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}
