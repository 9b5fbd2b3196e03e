"""Rectification models: plane transforms of a photo fitted on control points, their JSON document."""

from __future__ import annotations

import json
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.terrain.points import local_origin
from toolbox.transforms.control_points import IMAGE_UNITS, ControlPoints
from toolbox.transforms.plane import TRANSFORMS, FitStatistics, Transform2D, apply_homography
from toolbox.transforms.robust import (
    ROBUST_METHODS,
    Rejection,
    RobustFit,
    data_snooping,
    ransac,
    snooping_statistics,
)

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
        (thesis eq. [4]-[9], [50]; :mod:`toolbox.transforms.plane`).
    robust : {"none", "snooping", "ransac"}
        Gross-error handling (:mod:`toolbox.transforms.robust`); rejected points are named.
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
    # pixel rows grow down, ground Y up: a similarity between them is a mirrored one, so it is
    # fitted on (col, -row) (with two points, where both forms fit, that is the one kept)
    flip = np.diag([1.0, -1.0, 1.0]) if model == "similarity" and points.units == "pixels" \
        else np.eye(3)
    src = apply_homography(flip, points.image[control])
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
    local = cls(result.transform.params @ flip)
    local.fit = result.transform.fit
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
    if model == "similarity":  # determined by any two distinct points, on a line or not
        return
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


# -- applying a model to a photo -----------------------------------------------------------------

MODES = ("warp", "gcps")
OUTSIDE = ("alpha", "nodata")


def parse_pixel_to_image(text: str, name: str = "PIXEL_TO_IMAGE") -> np.ndarray:
    """The Pixel->Fiducial matrix from 6 (affine) or 8 (homography) numbers, row by row:
    ``a b c d e f [g h]`` means ``x = (a·col + b·row + c)/(g·col + h·row + 1)``, ``y = (d·col +
    e·row + f)/(...)`` (the Z-Map interior-orientation reports' ``p2f`` elements)."""
    parts = [p for p in re.split(r"[,;\s]+", str(text).strip()) if p]
    try:
        numbers = [float(p) for p in parts]
    except ValueError:
        numbers = []
    if len(numbers) not in (6, 8) or not all(math.isfinite(v) for v in numbers):
        raise ParameterError(name, f"must be 6 or 8 numbers (a b c d e f [g h], the Pixel->"
                             f"Fiducial matrix row by row), got {text!r}")
    g, h = (numbers[6], numbers[7]) if len(numbers) == 8 else (0.0, 0.0)
    matrix = np.array([numbers[0:3], numbers[3:6], [g, h, 1.0]])
    if abs(np.linalg.det(matrix)) < 1e-300:
        raise ParameterError(name, f"{text!r} is not invertible")
    return matrix


def pixel_to_ground_matrix(model: RectificationModel,
                           pixel_to_image: np.ndarray | None) -> np.ndarray:
    """Homography from source pixel coordinates (col, row; centres at +0.5) to ground X, Y."""
    if model.image_units == "pixels":
        matrix = model.image_to_ground
    else:
        if pixel_to_image is None:
            raise ParameterError("PIXEL_TO_IMAGE", "is required: the transform maps image mm to "
                                 "the ground, so the pixel -> mm (interior orientation) matrix is "
                                 "needed to warp pixels")
        matrix = model.image_to_ground @ pixel_to_image
    return matrix / matrix[2, 2]


def photo_cells(pixel_to_ground: np.ndarray, transform: Any, window: Any, width: int,
                height: int) -> np.ndarray:
    """(h, w) bool: the cells of ``window`` (of the output grid ``transform``) whose centre
    maps inside the ``width`` x ``height`` photo, in front of the camera."""
    c0, r0 = int(window.col_off), int(window.row_off)
    cols, rows = np.meshgrid(np.arange(c0, c0 + int(window.width)) + 0.5,
                             np.arange(r0, r0 + int(window.height)) + 0.5)
    t = transform
    ground = np.column_stack([(t.c + t.a * cols + t.b * rows).ravel(),
                              (t.f + t.d * cols + t.e * rows).ravel()])
    inverse = np.linalg.inv(pixel_to_ground)
    centre = apply_homography(pixel_to_ground, np.array([[width / 2.0, height / 2.0]]))
    _, front = apply_homography(inverse, centre, return_w=True)
    pixel, w = apply_homography(inverse, ground, return_w=True)
    inside = (w * front[0] > 0) & (pixel[:, 0] >= 0) & (pixel[:, 0] < width) \
        & (pixel[:, 1] >= 0) & (pixel[:, 1] < height)
    return inside.reshape(cols.shape)


def footprint(pixel_to_ground: np.ndarray, width: int, height: int) -> np.ndarray:
    """Ground (X, Y) of the photo's four corners (top-left, top-right, bottom-right,
    bottom-left), (4, 2). Raises :class:`InputDataError` when the plane's vanishing line crosses
    the photo (an oblique view: the footprint is unbounded)."""
    corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype="float64")
    ground, w = apply_homography(pixel_to_ground, corners, return_w=True)
    if not (np.all(w > 0) or np.all(w < 0)):
        raise InputDataError("the ground plane's vanishing line crosses the photo (an oblique "
                             "view): its footprint is unbounded; give EXTENT")
    return ground


def default_cell_size(pixel_to_ground: np.ndarray, width: int, height: int) -> float:
    """Ground size of a source pixel at the photo centre, ``sqrt(|det J|)``, rounded to 3
    significant digits."""
    centre = np.array([width / 2.0, height / 2.0])
    step = 1.0
    pts = np.array([centre, centre + [step, 0], centre + [0, step]])
    g, _ = apply_homography(pixel_to_ground, pts, return_w=True)
    jac = np.column_stack([g[1] - g[0], g[2] - g[0]]) / step
    size = float(np.sqrt(abs(np.linalg.det(jac))))
    if not size > 0 or not math.isfinite(size):
        raise InputDataError("the transform gives a zero or undefined pixel size at the photo "
                             "centre")
    return float(f"{size:.3g}")


def write_gcp_geotiff(source: Any, output: Any, gcps: list[tuple[str, float, float, float,
                                                               float, float]],
                      crs: Any, feedback: Feedback, tags: dict[str, str] | None = None,
                      chunk: int = 2048, overviews: bool = False, cog: bool = False) -> None:
    """Copy ``source`` into a tiled GeoTIFF with embedded GCPs, window by window
    (:class:`~toolbox.raster.writer.RasterWriter`: a photo georeferenced by its points, warped
    by the reader), with internal overviews (``overviews``) and as a Cloud Optimized GeoTIFF
    (``cog``, GDAL's COG driver keeps the GCPs) as the writer's other outputs.

    ``gcps``: (id, col, row, X, Y, Z) with col/row in the source pixel convention (pixel centres
    at +0.5, as GDAL's GCP pixel/line).
    """
    import rasterio
    from rasterio.control import GroundControlPoint
    from rasterio.enums import ColorInterp

    from toolbox.io.grid import GridSpec
    from toolbox.io.raster import gdal_cache_max
    from toolbox.raster.tile import iter_tiles
    from toolbox.raster.writer import RasterWriter, copy_band_names

    with rasterio.Env(GDAL_CACHEMAX=gdal_cache_max(256)), warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(source) as src:
            dtypes = set(src.dtypes)
            if len(dtypes) != 1:
                raise InputDataError(f"INPUT has bands of different types ({', '.join(dtypes)})")
            has_alpha = src.count > 1 and src.colorinterp[-1] == ColorInterp.alpha
            points = [GroundControlPoint(row=r, col=c, x=x, y=y, z=z, id=str(i), info=str(i))
                      for i, c, r, x, y, z in gcps]
            grid = GridSpec(src.transform, src.width, src.height, crs)
            with RasterWriter(output, grid, src.count, src.dtypes[0], src.nodata,
                              alpha=has_alpha, overviews=overviews, cog=cog, tags=tags,
                              gcps=points) as dst:
                copy_band_names(src, dst.dataset, range(1, src.count + 1))
                windows = [t.window for t in iter_tiles(grid, chunk)]
                for window in feedback.iterate(windows):
                    dst.write(window, src.read(window=window))
