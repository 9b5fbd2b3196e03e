"""Absolute orientation: the 7-parameter spatial similarity model -> ground (thesis S002 eq. [25]).

Convention (fixed here, tested): ``P = λ·R(omega, phi, kappa)·p + T`` with ``p`` the model
coordinates, ``P`` the ground coordinates, ``R`` the rotation matrix of the domain brief's section 3
(the same matrix as the collinearity equations), ``λ`` the scale and ``T`` the translation. The thesis'
eq. [25] multiplies by ``Rᵀ``; its angles are therefore those of ``Rᵀ`` (report them with care).

Method: closed-form start (the rotation aligning the centred point sets, by
``scipy.spatial.transform.Rotation.align_vectors``, scale from the ratio of the spreads), then least
squares on all 3n equations (``scipy.optimize.least_squares``) on coordinates shifted to the
centroids, giving residuals, ``sigma0 = sqrt(Σv²/(3n - 7))`` and the covariance of the 7 parameters.
Control coordinates are taken as error-free, model coordinates with equal weight (as the thesis
says). Residuals are **computed minus observed** (the toolbox convention): transformed model
point minus ground control.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from toolbox.errors import ConvergenceError, InputDataError
from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

PARAMETER_NAMES = ("TX", "TY", "TZ", "omega", "phi", "kappa", "scale")


@dataclass
class SimilarityResult:
    translation: np.ndarray  # (3,) ground units
    angles: np.ndarray  # (3,) omega, phi, kappa, radians
    scale: float
    covariance: np.ndarray  # (7, 7) in the order of PARAMETER_NAMES
    residuals: np.ndarray  # (n, 3) transformed model - ground control, ground units
    sigma0: float
    redundancy: int

    @property
    def rotation(self) -> np.ndarray:
        return rotation_matrix(*self.angles)

    def apply(self, model: np.ndarray) -> np.ndarray:
        """Model (n, 3) -> ground (n, 3)."""
        return self.scale * np.asarray(model, float) @ self.rotation.T + self.translation

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))


def check_control(model: np.ndarray, ground: np.ndarray) -> None:
    n = len(model)
    if n < 3:
        raise InputDataError(f"absolute orientation needs at least 3 control points (2 "
                             f"planimetric and 3 height points, not collinear), got {n}")
    centred = ground - ground.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[0] == 0 or sv[1] / sv[0] < 1e-3:
        raise InputDataError(f"the {n} control points are collinear (spread ratio "
                             f"{sv[1] / sv[0] if sv[0] else 0:.2g}): the rotation about their line "
                             "is undetermined")


def fit_similarity(model: np.ndarray, ground: np.ndarray) -> SimilarityResult:
    """Least-squares 7-parameter similarity from model (n, 3) to ground (n, 3) coordinates."""
    from scipy.optimize import least_squares
    from scipy.spatial.transform import Rotation

    model = np.asarray(model, float)
    ground = np.asarray(ground, float)
    if model.shape != ground.shape or model.ndim != 2 or model.shape[1] != 3:
        raise InputDataError("model and ground points must be (n, 3) arrays of the same points")
    if not (np.isfinite(model).all() and np.isfinite(ground).all()):
        raise InputDataError("model and ground coordinates must be finite numbers")
    check_control(model, ground)
    m0, g0 = model.mean(axis=0), ground.mean(axis=0)
    pm, pg = model - m0, ground - g0
    rot, _ = Rotation.align_vectors(pg, pm)  # pg ≈ R·pm
    r0 = rot.as_matrix()
    scale0 = math.sqrt(float((pg ** 2).sum()) / float((pm ** 2).sum()))
    angles0 = np.array(angles_from_matrix(r0))

    def residuals(x: np.ndarray) -> np.ndarray:
        computed = x[6] * pm @ rotation_matrix(*x[3:6]).T + x[:3]
        return (computed - pg).ravel()

    start = np.concatenate([np.zeros(3), angles0, [scale0]])
    sol = least_squares(residuals, start, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if not sol.success or not np.isfinite(sol.x).all():
        raise ConvergenceError(f"absolute orientation did not converge: {sol.message}")
    x = sol.x
    v = residuals(x).reshape(-1, 3)
    redundancy = 3 * len(model) - 7
    sigma0 = math.sqrt(float((v ** 2).sum()) / redundancy) if redundancy > 0 else math.nan
    try:
        cof = np.linalg.inv(sol.jac.T @ sol.jac)
    except np.linalg.LinAlgError:
        cof = np.full((7, 7), np.nan)
    covariance = sigma0 ** 2 * cof if redundancy > 0 else np.full((7, 7), np.nan)
    r = rotation_matrix(*x[3:6])
    translation = g0 + x[:3] - x[6] * (r @ m0)
    return SimilarityResult(translation, x[3:6].copy(), float(x[6]), covariance, v, sigma0,
                            redundancy)
