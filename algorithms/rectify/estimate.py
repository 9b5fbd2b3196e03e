"""rectify:estimate - plane transform of a photo from control points (similarity, affine, homography).

Kernel :func:`fit_rectification` (arrays in, a result object out) and the thin algorithm
:class:`EstimateRectification`, which reads the control-point table, writes the transform as a
JSON file for ``rectify:image`` and optionally the residuals as a GeoPackage.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import Crs, Enum, Field, Number, VectorLayer
from toolbox.parameters.outputs import Layer, Output, OutputFile, OutputVector
from toolbox.registry import register
from toolbox.transforms.control_points import IMAGE_UNITS, ControlPoints, control_points_from_frame
from toolbox.transforms.rectification import (  # noqa: F401
    ELONGATION_WARNING,
    MODELS,
    TRANSFORM_FORMAT,
    TRANSFORM_VERSION,
    RectificationFit,
    RectificationModel,
    _check_geometry,
    _model_class,
    fit_rectification,
    load_transform,
    transform_document,
)
from toolbox.transforms.relief import FRAME_HALF_DIAGONAL_MM, TABLE4_TOLERANCE_MM, relief_check
from toolbox.transforms.robust import ROBUST_METHODS


@register
class EstimateRectification(Algorithm):
    """Estimate the plane transform of a photo from control points.

    The photo of a plane (flat terrain, a facade) is related to the plane by a homography, 8
    parameters (thesis eq. [50], S000 "omografia", S003 eq. (1))::

        X = (a1·ξ + a2·η + a3) / (c1·ξ + c2·η + 1)     Y = (b1·ξ + b2·η + b3) / (c1·ξ + c2·η + 1)

    ``ξ, η`` are image coordinates (pixels: col, row down, pixel centres at +0.5; or image mm:
    fiducial system, y up), ``X, Y`` ground coordinates. Special cases: the affine transform (6
    parameters) and the similarity (4; image plane parallel to the ground, domain brief
    section 6). Least squares with a linear (DLT) start and Gauss-Newton refinement on
    Hartley-normalised coordinates, ground coordinates shifted to a local origin.

    Every point gets its residuals in ground and image units (fitted - observed); the report
    gives sigma naught (ground units, and its image-unit equivalent), the redundancy and the
    standardised residuals. Points marked as checks (a role column: control / check / ignore)
    are left out of the fit and their errors reported separately. Gross errors: ROBUST=snooping
    (iterative data snooping: Baarda's w-test with SIGMA, else Pope's tau test) or ransac
    (OpenCV RANSAC with RANSAC_THRESHOLD, then least squares on the inliers); rejected points are
    named. At least 2 / 3 / 4 control points are needed; collinear and other degenerate
    configurations are refused.

    Accuracy rule (thesis eq. [49], Table 4): with PRINCIPAL_DISTANCE and FLYING_HEIGHT, the
    relief displacement at the image edge ``Δρ = ΔZ·ρ/(c·m_b)`` for half the terrain's height
    range is reported, with a warning to use orthorectification when it exceeds
    RELIEF_TOLERANCE. The tolerance applies at MAP_SCALE, the scale of the product (Table 4 is
    indexed by the rectification scale m_b: for a 1:5000 map from 1:15,000 photos with c = 150 mm
    it allows 7.5 m of relief at 100 mm from the centre, not the 22.5 m the photo scale would
    give); without MAP_SCALE, at the photo scale H / c. Both scales are reported. With MAP_SCALE
    and check points, their RMSE is also judged against the orthophoto/rectification accuracy
    rule (S002 par. 2.6.6: ±0.5 mm at the map scale for 1:5000 and larger, ±0.3 mm for smaller
    scales; STATISTICS ``accuracy``).

    The transform is written as JSON for rectify:image; RESIDUALS optionally writes the points
    with their residuals as a GeoPackage.
    """

    id = "rectify:estimate"
    display_name = "Estimate rectification transform"
    group = "Rectification"
    short_help = "Homography / affine / similarity of a photo from control points, with residuals."
    parameters = [
        VectorLayer("INPUT", "control points: a point layer or CSV (ground X, Y[, Z]) with image "
                    "coordinates in two columns", geometry_types=["point"]),
        Enum("IMAGE_UNITS", "image coordinates: pixels (col, row down) or mm (fiducial x, y up)",
             options=IMAGE_UNITS, default="pixels"),
        Field("IMAGE_X_FIELD", "column of the image x / col (default: detected by name)",
              parent="INPUT", numeric=True, optional=True),
        Field("IMAGE_Y_FIELD", "column of the image y / row (default: detected by name)",
              parent="INPUT", numeric=True, optional=True),
        Field("ID_FIELD", "column of the point ids (default: id/name/point, else row numbers)",
              parent="INPUT", optional=True),
        Field("ROLE_FIELD", "column marking check points: control/check/ignore (default: "
              "role/type/use/check)", parent="INPUT", optional=True),
        Crs("CRS", "CRS of the ground coordinates when the table has none (omit for a local "
            "object system, e.g. a facade)", optional=True),
        Enum("MODEL", "transform", options=MODELS, default="homography"),
        Enum("ROBUST", "gross-error handling", options=ROBUST_METHODS, default="snooping"),
        Number("ALPHA", "significance level of the data-snooping test", default=0.001,
               min_value=0, max_value=0.5, min_exclusive=True),
        Number("SIGMA", "a-priori standard deviation of a ground coordinate, CRS units (w-test; "
               "default: estimated, tau test)", optional=True, min_value=0, min_exclusive=True),
        Number("RANSAC_THRESHOLD", "RANSAC inlier threshold, ground units (ROBUST=ransac)",
               optional=True, min_value=0, min_exclusive=True),
        Number("PRINCIPAL_DISTANCE", "camera principal distance c, mm (relief rule)",
               optional=True, min_value=0, min_exclusive=True),
        Number("FLYING_HEIGHT", "flying height above the mean terrain, m (relief rule)",
               optional=True, min_value=0, min_exclusive=True),
        Number("HEIGHT_RANGE", "terrain height range in the photo, m (default: range of the "
               "control points' Z)", optional=True, min_value=0),
        Number("IMAGE_RADIUS", "radial distance of the image edge from the principal point, mm",
               default=round(FRAME_HALF_DIAGONAL_MM, 2), min_value=0, min_exclusive=True),
        Number("RELIEF_TOLERANCE", "tolerated relief displacement at the edge, mm at the "
               "rectification scale (Table 4: 1 mm)", default=TABLE4_TOLERANCE_MM, min_value=0,
               min_exclusive=True),
        Number("MAP_SCALE", "scale number of the product the rule applies at (e.g. 5000 for "
               "1:5000; default: the photo scale H / c)", optional=True, min_value=1),
        OutputFile("OUTPUT", "transform (JSON, read by rectify:image)", extensions=[".json"]),
        OutputVector("RESIDUALS", "points with residuals (GeoPackage, layer 'residuals')",
                     optional=True, layers=[
                         Layer("residuals", "Point", [
                             ("id", "string", "point id"),
                             ("role", "string", "control, check or rejected"),
                             ("image_x", "real"), ("image_y", "real"),
                             ("res_x", "real", "ground residual x, CRS units"),
                             ("res_y", "real", "ground residual y, CRS units"),
                             ("res_norm", "real", "ground residual length, CRS units"),
                             ("res_image_x", "real"), ("res_image_y", "real"),
                             ("test_x", "real", "standardised residual x"),
                             ("test_y", "real", "standardised residual y")],
                             "control and check points at their ground position",
                             style="residuals")]),
    ]
    outputs = [Output("STATISTICS", "fit report: sigma0, redundancy, per-point residuals, "
                      "check points, rejected points, relief rule", "json")]

    def check(self, params):
        if params["ROBUST"] == "ransac" and params["RANSAC_THRESHOLD"] is None:
            raise self.fail("RANSAC_THRESHOLD", "is required when ROBUST is ransac (the largest "
                            "residual of an inlier, ground units)")
        if (params["IMAGE_X_FIELD"] is None) != (params["IMAGE_Y_FIELD"] is None):
            missing = "IMAGE_Y_FIELD" if params["IMAGE_Y_FIELD"] is None else "IMAGE_X_FIELD"
            raise self.fail(missing, "must be given together with "
                            f"{'IMAGE_X_FIELD' if missing == 'IMAGE_Y_FIELD' else 'IMAGE_Y_FIELD'}")
        if (params["PRINCIPAL_DISTANCE"] is None) != (params["FLYING_HEIGHT"] is None):
            missing = "FLYING_HEIGHT" if params["FLYING_HEIGHT"] is None else "PRINCIPAL_DISTANCE"
            raise self.fail(missing, "is needed with the other one for the relief rule "
                            "(PRINCIPAL_DISTANCE in mm and FLYING_HEIGHT in m)")

    def process(self, params, feedback: Feedback):
        import geopandas as gpd
        import shapely

        from toolbox.io.crs import common_crs, crs_label
        from toolbox.io.vector import read_vector
        from toolbox.io.vector_write import write_layers

        layer = params["INPUT"]
        crs = common_crs({"INPUT": layer.crs}, params["CRS"])
        with feedback.timed("read"):
            frame = read_vector(layer)
        fields = None
        if params["IMAGE_X_FIELD"] is not None:
            fields = (params["IMAGE_X_FIELD"], params["IMAGE_Y_FIELD"])
        points = control_points_from_frame(frame, params["IMAGE_UNITS"], fields,
                                           params["ID_FIELD"], params["ROLE_FIELD"], "INPUT")
        feedback.set_progress(20)
        with feedback.timed("fit"):
            fit = fit_rectification(points, params["MODEL"], params["ROBUST"], params["ALPHA"],
                                    params["SIGMA"], params["RANSAC_THRESHOLD"])
        for text in fit.warnings:
            feedback.push_warning(text)
        if fit.rejected:
            names = ", ".join(f"{points.ids[r.index]} ({r.statistic:.2f} > {r.critical:.2f})"
                              for r in fit.rejected)
            feedback.push_warning(f"gross errors rejected ({fit.robust.method}): {names}")
        stats = fit.summary()
        stats["crs"] = crs_label(crs)
        stats["points"] = fit.point_table()
        relief = self._relief(params, points, fit, feedback)
        if relief is not None:
            stats["relief"] = relief
        if params.get("MAP_SCALE") is not None and stats["check"]["count"]:
            from toolbox.photogrammetry.accuracy import judge_planimetry

            stats["accuracy"] = judge_planimetry(stats["check"]["rmse"], params["MAP_SCALE"])
            if not stats["accuracy"]["passes"]:
                feedback.push_warning(
                    f"check-point RMSE {stats['check']['rmse']:.3f} m exceeds "
                    f"{stats['accuracy']['tolerance_m']:.3f} m, the thesis' accuracy rule at "
                    f"1:{params['MAP_SCALE']:g} (S002 par. 2.6.6)")
        feedback.set_progress(80)
        doc = transform_document(fit, crs)
        doc["statistics"]["relief"] = relief
        params["OUTPUT"].write_text(json.dumps(_jsonable(doc), indent=2) + "\n")
        if params["RESIDUALS"] is not None:
            table = fit.point_table()
            frame_out = gpd.GeoDataFrame({
                "id": [r["id"] for r in table], "role": [r["role"] for r in table],
                "image_x": points.image[:, 0], "image_y": points.image[:, 1],
                "res_x": fit.residual_ground[:, 0], "res_y": fit.residual_ground[:, 1],
                "res_norm": np.hypot(*fit.residual_ground.T),
                "res_image_x": fit.residual_image[:, 0], "res_image_y": fit.residual_image[:, 1],
                "test_x": fit.standardized[:, 0], "test_y": fit.standardized[:, 1],
            }, geometry=shapely.points(points.ground), crs=crs)
            write_layers(params["RESIDUALS"], {"residuals": frame_out})
        return {"OUTPUT": params["OUTPUT"], "RESIDUALS": params["RESIDUALS"],
                "STATISTICS": _jsonable(stats)}

    @staticmethod
    def _relief(params, points: ControlPoints, fit: RectificationFit,
                feedback: Feedback) -> dict | None:
        if params["PRINCIPAL_DISTANCE"] is None:
            return None
        height_range = params["HEIGHT_RANGE"]
        source = "HEIGHT_RANGE"
        if height_range is None:
            if points.z is None:
                raise ParameterError("HEIGHT_RANGE", "is required for the relief rule when the "
                                     "control points have no Z")
            height_range = float(np.ptp(points.z))
            source = "control points' Z (a lower bound of the terrain's range)"
        cell = fit.ground_pixel_size() if points.units == "pixels" else None
        check = relief_check(params["PRINCIPAL_DISTANCE"], params["FLYING_HEIGHT"],
                             height_range, params["IMAGE_RADIUS"], params["RELIEF_TOLERANCE"],
                             cell, params.get("MAP_SCALE"))
        (feedback.push_info if check.flat_enough else feedback.push_warning)(check.message())
        return check.as_dict() | {"height_range_source": source, "message": check.message()}


def _jsonable(value: Any) -> Any:
    from toolbox.report import to_jsonable

    return to_jsonable(value)
