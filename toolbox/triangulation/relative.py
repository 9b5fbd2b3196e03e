"""Relative orientation of a stereo pair from >= 5 homologous points (002 par. 1.5.2, eq. [22]-[24];
003 on relative orientation).

Model frame: photo 1's projection centre at the origin, the base ``b`` from O1 to O2 with
``bx = 1`` (the model's scale is arbitrary). Two parameter sets, both with 5 unknowns:

- ``dependent`` (asymmetric, eq. [24]): photo 1 fixed (``R1 = I``), unknowns ``by, bz, ω2, φ2,
  κ2``;
- ``independent`` (symmetric, eq. [23]): base along X (``by = bz = 0``), unknowns ``φ1, κ1, ω2,
  φ2, κ2`` (``ω1 = 0``).

Condition (coplanarity): the base and the two rays ``rᵢ = Rᵢ·(x̄ᵢ, ȳᵢ, -cᵢ)`` of a point lie in
one plane, ``b · (r1 × r2) = 0``. The residual minimised is the point's y-parallax ``py``: the
model intersection is formed from the X and Z equations (``λ1·r1 - λ2·r2 = b``), ``py`` is the
gap between the two rays along model Y, returned in image mm at photo 1's scale (``py·c1/|Z|``):
the linearised form of this residual is eq. [22]. Solved by Levenberg-Marquardt (scipy) from the
normal case (all zero); the result is exact, not the one-step linearisation of the seeds.

Critical surface (002: "cilindro critico"): points on a circular cylinder through both
projection centres with its axis along the base (e.g. a valley flown along its floor) leave the
orientation undetermined; the condition number of the Jacobian (columns scaled) above
:data:`CRITICAL_CONDITION` raises a warning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from toolbox.errors import ConvergenceError, InputDataError, ParameterError
from toolbox.triangulation.model import rotations

SETS = {"dependent": ("by", "bz", "omega2", "phi2", "kappa2"),
        "independent": ("phi1", "kappa1", "omega2", "phi2", "kappa2")}
CRITICAL_CONDITION = 1e5
MIN_POINTS = 5


@dataclass
class RelativeRequest:
    """Camera coordinates (n, 2) of the same points on photos 1 and 2 (mm, reduced to the
    principal point, distortion corrected), principal distances (mm) and the parameter set."""

    xy1: np.ndarray
    xy2: np.ndarray
    c1: float
    c2: float
    parameters: str = "dependent"


@dataclass
class RelativeResult:
    parameters: dict[str, float]  # the 5 unknowns (rad; by, bz in units of bx)
    std: dict[str, float]
    base: np.ndarray  # (3,) (1, by, bz) or (1, 0, 0)
    rotation1: np.ndarray  # (3, 3)
    rotation2: np.ndarray
    model: np.ndarray  # (n, 3) model coordinates (bx = 1)
    py_mm: np.ndarray  # (n,) residual y-parallaxes, image mm at photo 1's scale
    sigma0_mm: float
    redundancy: int
    condition: float
    warnings: list[str] = field(default_factory=list)


def _setup(p: np.ndarray, kind: str):
    if kind == "dependent":
        base = np.array([1.0, p[0], p[1]])
        a1 = np.zeros(3)
        a2 = p[2:5]
    else:
        base = np.array([1.0, 0.0, 0.0])
        a1 = np.array([0.0, p[0], p[1]])
        a2 = p[2:5]
    r, _ = rotations(np.array([a1, a2]))
    return base, r[0], r[1]


def _rays(xy: np.ndarray, c: float, rot: np.ndarray) -> np.ndarray:
    return np.column_stack([xy, np.full(len(xy), -c)]) @ rot.T


def model_points(base, r1, r2):
    """λ1, λ2 from the X and Z equations, model points and the Y gap (model units)."""
    det = -r1[:, 0] * r2[:, 2] + r2[:, 0] * r1[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam1 = (-base[0] * r2[:, 2] + r2[:, 0] * base[2]) / det
        lam2 = (r1[:, 0] * base[2] - r1[:, 2] * base[0]) / det
    p1 = lam1[:, None] * r1
    p2 = base + lam2[:, None] * r2
    return 0.5 * (p1 + p2), p2[:, 1] - p1[:, 1], lam1, lam2


def relative_orientation(request: RelativeRequest) -> RelativeResult:
    from scipy.optimize import least_squares

    kind = request.parameters
    if kind not in SETS:
        raise ParameterError("PARAMETERS", f"must be dependent or independent, got {kind!r}")
    xy1 = np.asarray(request.xy1, dtype=float).reshape(-1, 2)
    xy2 = np.asarray(request.xy2, dtype=float).reshape(-1, 2)
    n = len(xy1)
    if n != len(xy2):
        raise InputDataError(f"photo 1 has {n} points, photo 2 {len(xy2)}: homologous points "
                             "must pair up")
    if n < MIN_POINTS:
        raise InputDataError(f"relative orientation needs at least {MIN_POINTS} homologous "
                             f"points (6-12 recommended, in the Gruber positions), got {n}")
    if not (np.isfinite(xy1).all() and np.isfinite(xy2).all()):
        raise InputDataError("image coordinates must be finite numbers")
    c1 = float(request.c1)

    def residuals(p):
        base, r1, r2 = _setup(p, kind)
        model, gap, _, _ = model_points(base, _rays(xy1, c1, r1), _rays(xy2, request.c2, r2))
        return gap * c1 / np.abs(model[:, 2])

    sol = least_squares(residuals, np.zeros(5), method="lm", x_scale="jac", xtol=1e-15,
                        ftol=1e-15, gtol=1e-15, max_nfev=5000)
    if not np.isfinite(sol.x).all():
        raise ConvergenceError(f"relative orientation did not converge: {sol.message}")
    base, r1, r2 = _setup(sol.x, kind)
    model, gap, lam1, lam2 = model_points(base, _rays(xy1, c1, r1), _rays(xy2, request.c2, r2))
    warnings = []
    if (lam1 <= 0).any() or (lam2 <= 0).any():
        warnings.append(f"{int(((lam1 <= 0) | (lam2 <= 0)).sum())} point(s) lie behind a "
                        "camera in the model: check the homologous points")
    py = residuals(sol.x)
    redundancy = n - 5
    sigma0 = math.sqrt(float(py @ py) / redundancy) if redundancy > 0 else math.nan
    jac = sol.jac
    norms = np.linalg.norm(jac, axis=0)
    sv = np.linalg.svd(jac / np.where(norms > 0, norms, 1.0), compute_uv=False)
    condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    if condition > CRITICAL_CONDITION:
        warnings.append(f"weak relative orientation (condition number {condition:.3g}): the "
                        "points are near a critical surface (a cylinder through both projection "
                        "centres with its axis along the base) or badly distributed")
    std = np.full(5, np.nan)
    if redundancy > 0 and math.isfinite(condition):
        std = sigma0 * np.sqrt(np.diag(np.linalg.pinv(jac.T @ jac)))
    names = SETS[kind]
    return RelativeResult(dict(zip(names, map(float, sol.x), strict=True)),
                          dict(zip(names, map(float, std), strict=True)), base, r1, r2, model, py,
                          sigma0, redundancy, condition, warnings)
