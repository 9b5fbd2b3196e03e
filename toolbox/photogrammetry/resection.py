"""Single-photo space resection: the exterior orientation of one photo from >= 4 control points.

Method: least squares on the collinearity equations (domain brief section 4), all 6 unknowns
(X0, Y0, Z0, omega, phi, kappa) at once, solved by ``scipy.optimize.least_squares``
(Levenberg-Marquardt) on ground coordinates shifted to a local origin (the centroid of the
control points), so that the normal matrix is well conditioned with projected coordinates of
millions of metres.

Start values need no approximate orientation for near-vertical photos: a plane similarity
image -> ground fitted on the control points gives the scale factor ``m`` (ground metres per
image mm), hence the flying height ``H = m·c`` above the mean control height, the kappa
rotation and the nadir X0, Y0 (the image of the principal point); omega = phi = 0.

Statistics: redundancy ``r = 2n - 6``; ``sigma0 = sqrt(Σv²/r)`` (mm, image); covariance of the
six parameters ``sigma0²·(JᵀJ)⁻¹`` (J the Jacobian of the image coordinates at the solution).
Residuals are **computed minus observed** (the toolbox convention).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from toolbox.errors import ConvergenceError, InputDataError
from toolbox.photogrammetry.rotation import rotation_matrix

PARAMETER_NAMES = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
MIN_POINTS = 4


@dataclass
class ResectionResult:
    """Exterior orientation fitted on control points (angles in radians, ground units metres)."""

    parameters: np.ndarray  # (6,) X0, Y0, Z0 (CRS units), omega, phi, kappa (rad)
    covariance: np.ndarray  # (6, 6), NaN when redundancy is 0
    residuals_mm: np.ndarray  # (n, 2) observed - computed image coordinates, mm
    sigma0_mm: float  # NaN when redundancy is 0
    redundancy: int
    iterations: int

    @property
    def std(self) -> np.ndarray:
        """Standard deviations of the six parameters (CRS units, radians)."""
        return np.sqrt(np.diag(self.covariance))


def project_camera(ground: np.ndarray, params: np.ndarray, c: float) -> np.ndarray:
    """Camera coordinates (mm, principal point at 0, no distortion) of ``ground`` (n, 3) for
    ``params`` = (X0, Y0, Z0, omega, phi, kappa): ``x̄ = -c·(Rᵀ·(P - C))_x / (Rᵀ·(P - C))_z``."""
    r = rotation_matrix(*params[3:])
    d = (ground - params[:3]) @ r  # rows: Rᵀ·(P - C)
    return -c * d[:, :2] / d[:, 2:3]


def similarity_start(camera_xy: np.ndarray, ground: np.ndarray, c: float) -> np.ndarray:
    """Start values for a near-vertical photo from the plane similarity image -> ground."""
    x, y = camera_xy[:, 0], camera_xy[:, 1]
    n = len(x)
    # X = a·x - b·y + tx,  Y = b·x + a·y + ty
    design = np.zeros((2 * n, 4))
    design[0::2] = np.column_stack([x, -y, np.ones(n), np.zeros(n)])
    design[1::2] = np.column_stack([y, x, np.zeros(n), np.ones(n)])
    rhs = ground[:, :2].reshape(-1)
    (a, b, tx, ty), *_ = np.linalg.lstsq(design, rhs, rcond=None)
    scale = math.hypot(a, b)  # ground metres per image mm
    height = scale * c / 1.0  # m (c in mm, scale in m/mm)
    return np.array([tx, ty, float(ground[:, 2].mean()) + height, 0.0, 0.0, math.atan2(b, a)])


RESECTION_SPREAD = 5e-4  # relative to the extent (the shared collinearity test)


def check_geometry(camera_xy: np.ndarray, ground: np.ndarray) -> None:
    """Refuse too few points and points (nearly) on one line, relative to their spread."""
    n = len(ground)
    if n < MIN_POINTS:
        raise InputDataError(f"space resection needs at least {MIN_POINTS} control points measured "
                             f"on the photo, got {n}")
    from toolbox.terrain.points import check_not_collinear

    for what, pts in (("image", camera_xy), ("ground", ground[:, :2])):
        try:  # resection needs a well-spread geometry: RMS off-line spread >= 1/2000 of extent
            check_not_collinear(pts, f"control points in {what} coordinates", RESECTION_SPREAD)
        except ValueError as exc:
            raise InputDataError(f"{exc}: space resection needs points spread over the photo "
                                 f"(collinear in {what} coordinates)") from None


def resect(camera_xy: np.ndarray, ground: np.ndarray, c: float,
           start: np.ndarray | None = None) -> ResectionResult:
    """Fit the exterior orientation.

    Parameters
    ----------
    camera_xy : (n, 2) camera coordinates, mm (reduced to the principal point, distortion removed)
    ground : (n, 3) ground coordinates of the same points, CRS units
    c : principal distance, mm
    start : optional (6,) start values (X0, Y0, Z0, omega, phi, kappa); default
        :func:`similarity_start`.
    """
    from scipy.optimize import least_squares

    camera_xy = np.asarray(camera_xy, dtype=float)
    ground = np.asarray(ground, dtype=float)
    if not (np.isfinite(camera_xy).all() and np.isfinite(ground).all()):
        raise InputDataError("control points and image measurements must be finite numbers")
    check_geometry(camera_xy, ground)
    origin = ground.mean(axis=0)
    local = ground - origin
    x0 = similarity_start(camera_xy, ground, c) if start is None else np.asarray(start, float)
    x0 = x0.copy()
    x0[:3] -= origin

    def residuals(p: np.ndarray) -> np.ndarray:
        d = (local - p[:3]) @ rotation_matrix(*p[3:])
        with np.errstate(divide="ignore", invalid="ignore"):
            computed = -c * d[:, :2] / d[:, 2:3]
        return (computed - camera_xy).ravel()

    # scale: angles ~ 1e-3 rad per mm·m_b; let LM use the Jacobian's column norms
    solution = least_squares(residuals, x0, method="lm", x_scale="jac", xtol=1e-15, ftol=1e-15,
                             gtol=1e-15, max_nfev=2000)
    if not solution.success or not np.isfinite(solution.x).all():
        raise ConvergenceError(f"space resection did not converge: {solution.message}")
    p = solution.x
    d = (local - p[:3]) @ rotation_matrix(*p[3:])
    if (d[:, 2] >= 0).any():
        raise ConvergenceError("space resection converged to a solution with control points "
                               "behind the camera; give start values (approximate orientation)")
    v = residuals(p).reshape(-1, 2)
    n = len(ground)
    redundancy = 2 * n - 6
    sigma0 = math.sqrt(float((v ** 2).sum()) / redundancy) if redundancy > 0 else math.nan
    jac = solution.jac
    try:
        cof = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        cof = np.full((6, 6), np.nan)
    covariance = sigma0 ** 2 * cof if redundancy > 0 else np.full((6, 6), np.nan)
    params = p.copy()
    params[:3] += origin
    params[3:] = (params[3:] + math.pi) % (2 * math.pi) - math.pi
    return ResectionResult(params, covariance, v, sigma0, redundancy, int(solution.nfev))
