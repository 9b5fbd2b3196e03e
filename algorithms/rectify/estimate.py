"""rectify:estimate - plane transform of a photo from control points (similarity, affine, homography).

Kernel :func:`fit_rectification` (arrays in, a result object out) and the thin algorithm
:class:`EstimateRectification`, which reads the control-point table, writes the transform as a
JSON file for ``rectify:image`` and optionally the residuals as a GeoPackage.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from algorithms.common.points import local_origin
from algorithms.common.robust2d import (
    ROBUST_METHODS,
    Rejection,
    RobustFit,
    data_snooping,
    ransac,
    snooping_statistics,
)
from algorithms.common.transforms2d import TRANSFORMS, FitStatistics, Transform2D
from algorithms.rectify.control_points import IMAGE_UNITS, ControlPoints, control_points_from_frame
from algorithms.rectify.relief import FRAME_HALF_DIAGONAL_MM, TABLE4_TOLERANCE_MM, relief_check
from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import (
    Crs,
    Enum,
    Field,
    Number,
    Output,
    OutputFile,
    OutputVector,
    VectorLayer,
)
from toolbox.registry import register

MODELS = tuple(TRANSFORMS)  # similarity, affine, homography
TRANSFORM_FORMAT = "toolbox.rectify.transform"
TRANSFORM_VERSION = 1
ELONGATION_WARNING = 0.05  # smallest/largest spread of the control points (image) below this


@dataclass
class RectificationFit:
    """A fitted image -> ground transform and its quality report.

    transform : image -> ground in full ground coordinates (CRS units)
    local : the fitted transform, image -> ground minus ``origin`` (what the statistics refer to)
    origin : (2,) local origin subtracted from the ground coordinates before the fit
    points : every control and check point (check points never enter the fit)
    used : (N,) bool, the control points of the final fit (not rejected)
    rejected : rejections with ``index`` into ``points``
    residual_ground : (N, 2) ``T(image) - ground``, ground units (check points: their error)
    residual_image : (N, 2) ``T^-1(ground) - image``, image units
    standardized : (N, 2) w or tau of the used points (NaN for the others)
    """

    model: str
    transform: Transform2D
    local: Transform2D
    origin: np.ndarray
    points: ControlPoints
    used: np.ndarray
    rejected: list[Rejection]
    residual_ground: np.ndarray
    residual_image: np.ndarray
    standardized: np.ndarray
    robust: RobustFit
    warnings: list[str] = field(default_factory=list)

    @property
    def fit(self) -> FitStatistics:
        return self.local.fit

    @property
    def roles(self) -> list[str]:
        """Final role of each point: control, check or rejected."""
        out = list(self.points.role)
        for r in self.rejected:
            out[r.index] = "rejected"
        return out

    def ground_pixel_size(self) -> float:
        """Ground size of one image unit at the control points' centroid: sqrt(|det J|)."""
        centre = self.points.image[self.used].mean(axis=0)
        h = 1e-3 * max(1.0, float(np.abs(self.points.image).max()))
        pts = np.array([centre, centre + [h, 0], centre + [0, h]])
        g = self.local(pts)
        jac = np.column_stack([(g[1] - g[0]) / h, (g[2] - g[0]) / h])
        return float(np.sqrt(abs(np.linalg.det(jac))))

    def sigma0_image(self) -> float:
        """``sqrt(Σ v_image² / r)`` over the used points (image units; the fit minimises the
        ground residuals, so this is the image-space equivalent, not a second adjustment)."""
        r = self.fit.redundancy
        if r <= 0:
            return float("nan")
        return float(np.sqrt(np.sum(self.residual_image[self.used] ** 2) / r))

    def check_summary(self) -> dict[str, Any]:
        """Errors at the check points (ground and image units)."""
        mask = self.points.check
        if not mask.any():
            return {"count": 0}
        v = self.residual_ground[mask]
        vi = self.residual_image[mask]
        norms = np.hypot(v[:, 0], v[:, 1])
        return {"count": int(mask.sum()),
                "rmse_x": float(np.sqrt(np.mean(v[:, 0] ** 2))),
                "rmse_y": float(np.sqrt(np.mean(v[:, 1] ** 2))),
                "rmse": float(np.sqrt(np.mean(norms ** 2))),
                "max": float(norms.max()),
                "max_id": self.points.ids[int(np.flatnonzero(mask)[np.argmax(norms)])],
                "rmse_image": float(np.sqrt(np.mean(np.sum(vi ** 2, axis=1))))}

    def point_table(self) -> list[dict[str, Any]]:
        """One dict per point: id, role, observed and fitted coordinates, residuals, test value."""
        fitted_ground = self.transform(self.points.image)
        fitted_image = self.points.image + self.residual_image
        rows = []
        for i, (ident, role) in enumerate(zip(self.points.ids, self.roles, strict=True)):
            rows.append({
                "id": ident, "role": role,
                "image": self.points.image[i].tolist(), "ground": self.points.ground[i].tolist(),
                "z": None if self.points.z is None else float(self.points.z[i]),
                "fitted_ground": fitted_ground[i].tolist(),
                "fitted_image": fitted_image[i].tolist(),
                "residual_ground": self.residual_ground[i].tolist(),
                "residual_image": self.residual_image[i].tolist(),
                "residual_ground_norm": float(np.hypot(*self.residual_ground[i])),
                "residual_image_norm": float(np.hypot(*self.residual_image[i])),
                "standardized": [None if not np.isfinite(v) else float(v)
                                 for v in self.standardized[i]],
            })
        return rows

    def summary(self) -> dict[str, Any]:
        """The statistics reported by ``rectify:estimate`` (JSON-ready)."""
        fit = self.fit
        used = self.used
        return {
            "model": self.model, "parameters": self.transform.n_params,
            "image_units": self.points.units,
            "control_points": int(self.points.control.sum()),
            "used_points": int(used.sum()), "check_points": int(self.points.check.sum()),
            "rejected_points": [self.points.ids[r.index] for r in self.rejected],
            "rejections": [{"id": self.points.ids[r.index], **r.as_dict()} for r in self.rejected],
            "redundancy": fit.redundancy,
            "sigma0": fit.sigma0, "sigma0_image": self.sigma0_image(),
            "rmse_x": fit.rmse[0], "rmse_y": fit.rmse[1],
            "max_residual": float(np.max(np.hypot(*self.residual_ground[used].T))),
            "iterations": fit.iterations,
            "robust": {"method": self.robust.method,
                       "critical_value": self.robust.critical_value,
                       "notes": self.robust.notes},
            "check": self.check_summary(),
            "ground_size_of_image_unit": self.ground_pixel_size(),
            "image_to_ground": self.transform.params.tolist(),
            "local_origin": self.origin.tolist(),
            "warnings": list(self.warnings),
        }


def _model_class(model: str) -> type[Transform2D]:
    if model not in TRANSFORMS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}, got {model!r}")
    return TRANSFORMS[model]


def fit_rectification(points: ControlPoints, model: str = "homography", robust: str = "none",
                      alpha: float = 0.001, sigma: float | None = None,
                      ransac_threshold: float | None = None) -> RectificationFit:
    """Fit image -> ground by least squares on the control points; report every point.

    Parameters
    ----------
    points : ControlPoints
        Check points (``role == "check"``) are excluded from the fit and only evaluated.
    model : {"similarity", "affine", "homography"}
        4, 6 or 8 parameters (minimum 2, 3 or 4 control points). The homography starts from
        the linear DLT solution on Hartley-normalised coordinates and is refined by Gauss-Newton
        (thesis eq. [4]-[9], [50]; :mod:`algorithms.common.transforms2d`).
    robust : {"none", "snooping", "ransac"}
        Gross-error handling (:mod:`algorithms.common.robust2d`); rejected points are named.
    alpha, sigma : data-snooping level and a-priori ground standard deviation (optional).
    ransac_threshold : float
        RANSAC inlier threshold, ground units (required with ``robust="ransac"``).

    Raises
    ------
    InputDataError
        Too few control points, collinear or otherwise degenerate configurations, or a
        homography whose vanishing line separates the control points.
    """
    cls = _model_class(model)
    if robust not in ROBUST_METHODS:
        raise ValueError(f"robust must be one of {', '.join(ROBUST_METHODS)}, got {robust!r}")
    control = points.control
    need = cls.min_points_for(cls.n_params)
    n_control = int(control.sum())
    if n_control < need:
        raise InputDataError(f"a {model} needs at least {need} control points, got {n_control} "
                             f"({int(points.check.sum())} check points are not used in the fit)")
    index = np.flatnonzero(control)
    origin = local_origin(points.ground[control])
    src = points.image[control]
    dst = points.ground[control] - origin
    try:
        if robust == "none":
            transform = cls.estimate(src, dst)
            result = RobustFit(transform, np.ones(len(src), dtype=bool), [], "none")
        elif robust == "snooping":
            result = data_snooping(cls, src, dst, alpha=alpha, sigma=sigma)
        else:
            if ransac_threshold is None:
                raise ValueError("ransac_threshold is required with robust='ransac'")
            result = ransac(cls, src, dst, ransac_threshold)
    except InputDataError as exc:
        text = str(exc).replace("the source points", "the control points' image positions") \
            .replace("the target points", "the control points' ground positions")
        raise InputDataError(f"cannot fit a {model} to the {n_control} control points: "
                             f"{text}") from None
    local = result.transform
    warnings: list[str] = []
    used = np.zeros(len(points), dtype=bool)
    used[index[result.inliers]] = True
    rejected = [Rejection(int(index[r.index]), r.statistic, r.critical, r.step, r.method)
                for r in result.rejections]
    _check_geometry(local, points.image[used], model, warnings)
    shift = np.array([[1.0, 0.0, origin[0]], [0.0, 1.0, origin[1]], [0.0, 0.0, 1.0]])
    full = shift @ local.params
    transform = cls(full / full[2, 2])
    residual_ground = local(points.image) - (points.ground - origin)
    residual_image = local.inverse(points.ground - origin) - points.image
    standardized = np.full((len(points), 2), np.nan)
    if local.fit.redundancy > 0:
        standardized[used] = snooping_statistics(local, sigma if robust == "snooping" else None)
    for note in result.notes:
        warnings.append(note)
    return RectificationFit(model, transform, local, origin, points, used, rejected,
                            residual_ground, residual_image, standardized, result, warnings)


def _check_geometry(local: Transform2D, image: np.ndarray, model: str,
                    warnings: list[str]) -> None:
    """Refuse a homography whose vanishing line passes among the points; warn on weak spread."""
    if model == "homography":
        w = local.params[2, 0] * image[:, 0] + local.params[2, 1] * image[:, 1] + 1.0
        if np.any(w <= 0) and np.any(w > 0):
            raise InputDataError("the fitted homography's vanishing line passes between the "
                                 "control points (some would be behind the camera): the points "
                                 "are inconsistent or badly placed")
    centred = image - image.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[0] > 0 and s[-1] / s[0] < ELONGATION_WARNING:
        warnings.append(f"the control points lie nearly on a line (spread ratio "
                        f"{s[-1] / s[0]:.3f}): the transform is poorly determined across it")


# -- transform file ---------------------------------------------------------------------------
def transform_document(fit: RectificationFit, crs: Any) -> dict[str, Any]:
    """The JSON document ``rectify:image`` reads (matrix, units, CRS, points, statistics)."""
    from toolbox.io.crs import crs_label

    pts = fit.points
    inverse = np.linalg.inv(fit.transform.params)
    return {
        "format": TRANSFORM_FORMAT, "version": TRANSFORM_VERSION,
        "model": fit.model, "image_units": pts.units,
        "image_convention": ("pixels: (col, row) from the top-left corner of the top-left pixel, "
                             "rows down, pixel centres at +0.5" if pts.units == "pixels" else
                             "mm: fiducial system, x right, y up"),
        "image_to_ground": fit.transform.params.tolist(),
        "ground_to_image": (inverse / inverse[2, 2]).tolist(),
        "crs": None if crs is None else crs.to_wkt(),
        "crs_label": crs_label(crs),
        "points": [{"id": i, "role": role, "image": pts.image[k].tolist(),
                    "ground": pts.ground[k].tolist(),
                    "z": None if pts.z is None else float(pts.z[k])}
                   for k, (i, role) in enumerate(zip(pts.ids, fit.roles, strict=True))],
        "statistics": fit.summary(),
    }


@dataclass
class RectificationModel:
    """A transform read back from a ``rectify:estimate`` JSON file."""

    model: str
    image_units: str
    image_to_ground: np.ndarray
    crs: Any
    points: list[dict[str, Any]]
    path: Path | None = None

    def control_points(self) -> list[dict[str, Any]]:
        """The points used in the fit (role ``control``)."""
        return [p for p in self.points if p.get("role") == "control"]


def load_transform(path: str | Path, name: str = "TRANSFORM") -> RectificationModel:
    """Read a transform file written by ``rectify:estimate``; :class:`ParameterError` naming
    ``name`` when it is not one."""
    from toolbox.io.crs import parse_crs

    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ParameterError(name, f"cannot read '{path}' as a JSON transform: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != TRANSFORM_FORMAT:
        raise ParameterError(name, f"'{path}' is not a transform written by rectify:estimate "
                             f"(expected \"format\": \"{TRANSFORM_FORMAT}\")")
    if doc.get("version") != TRANSFORM_VERSION:
        raise ParameterError(name, f"'{path}' has transform version {doc.get('version')!r}; this "
                             f"toolbox reads version {TRANSFORM_VERSION}")
    try:
        matrix = np.asarray(doc["image_to_ground"], dtype="float64")
        units = str(doc["image_units"])
        model = str(doc["model"])
    except (KeyError, TypeError, ValueError):
        raise ParameterError(name, f"'{path}' lacks a valid image_to_ground matrix, image_units "
                             "or model") from None
    if matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)) \
            or abs(np.linalg.det(matrix)) < 1e-300:
        raise ParameterError(name, f"'{path}': image_to_ground must be an invertible 3 x 3 "
                             "matrix")
    if units not in IMAGE_UNITS:
        raise ParameterError(name, f"'{path}': image_units must be pixels or mm, got {units!r}")
    crs = parse_crs(doc["crs"], name) if doc.get("crs") else None
    return RectificationModel(model, units, matrix, crs, list(doc.get("points") or []), path)


# -- algorithm ----------------------------------------------------------------------------------
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
    RELIEF_TOLERANCE.

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
        OutputFile("OUTPUT", "transform (JSON, read by rectify:image)", extensions=[".json"]),
        OutputVector("RESIDUALS", "points with residuals (GeoPackage, layer 'residuals')",
                     optional=True),
    ]
    outputs = [Output("STATISTICS", "fit report: sigma0, redundancy, per-point residuals, "
                      "check points, rejected points, relief rule", "dict")]

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
        from toolbox.io.vector import read_vector, write_layers

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
                             cell)
        (feedback.push_info if check.flat_enough else feedback.push_warning)(check.message())
        return check.as_dict() | {"height_range_source": source, "message": check.message()}


def _jsonable(value: Any) -> Any:
    from toolbox.report import to_jsonable

    return to_jsonable(value)
