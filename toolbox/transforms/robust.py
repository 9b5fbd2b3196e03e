"""Gross-error handling for the plane transforms of :mod:`toolbox.transforms.plane`.

Two methods, both naming the points they reject:

- **Iterative data snooping** (Baarda), point by point: fit by least squares, test each point's
  residual vector ``v_i`` (2 coordinates) against its 2 x 2 block ``B_i`` of ``Q_vv·P``
  (``T_i = w_i·v_iᵀ·B_i⁻¹·v_i``), reject the point with the largest test value above the
  critical value, refit, repeat. With an a-priori standard deviation ``sigma`` of a ``dst``
  coordinate the statistic is ``T_i / sigma²`` against ``χ²(2)``; without it, sigma is
  estimated *without* the tested point (externally studentised: ``σ²_(i) = (Ω - T_i)/(r - 2)``,
  ``Ω`` the weighted sum of squared residuals) and ``F_i = (T_i / 2) / σ²_(i)`` is tested
  against ``F(2, r - 2)``. A point test sees an error split over x and y, and the leave-one-out
  sigma keeps the gross error from hiding itself by inflating sigma (the per-coordinate tau
  statistic cannot exceed ``sqrt(r)``, too little with a handful of control points).
- **RANSAC** through OpenCV (``cv2.findHomography``, ``cv2.estimateAffine2D``,
  ``cv2.estimateAffinePartial2D``; deterministic): the consensus set within ``threshold``
  (``dst`` units), then a least-squares refit on it and a final classification of every point
  by its residual to the refit model.

Both work on any :class:`~toolbox.transforms.plane.Transform2D` subclass; the coordinates
should already be shifted to a local origin (:func:`toolbox.terrain.points.local_origin`).
:func:`snooping_statistics` gives the per-coordinate standardised residuals
(``v / (sigma·sqrt(r_i))``) for reports.

Example
-------
>>> import numpy as np
>>> from toolbox.transforms.plane import AffineTransform
>>> src = np.array([[0, 0], [10, 0], [0, 10], [10, 10], [5, 5], [2, 8], [8, 2.]])
>>> dst = src * 2 + 1 + np.array([[0.01, 0], [0, -0.01], [-0.01, 0.01], [0, 0], [0, 0],
...                               [0.01, 0.01], [-0.01, 0]])
>>> dst[4] += 3.0  # a gross error on the point with index 4
>>> result = data_snooping(AffineTransform, src, dst)
>>> [r.index for r in result.rejections]
[4]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolbox.errors import InputDataError
from toolbox.transforms.plane import Transform2D

ROBUST_METHODS = ("none", "snooping", "ransac")


@dataclass
class Rejection:
    """One rejected point: its index, the test value that rejected it and the critical value.

    For RANSAC ``statistic`` is the residual norm to the final model (``dst`` units) and
    ``critical`` the threshold; for data snooping they are the point's χ² (a-priori sigma) or F
    (estimated sigma) test value and its critical value. ``step`` counts rejections (1 = first).
    """

    index: int
    statistic: float
    critical: float
    step: int
    method: str

    def as_dict(self) -> dict:
        return {"index": self.index, "statistic": self.statistic, "critical": self.critical,
                "step": self.step, "method": self.method}


@dataclass
class RobustFit:
    """A transform fitted on the accepted points, with what was rejected and why."""

    transform: Transform2D
    inliers: np.ndarray  # (N,) bool: points used in the final fit
    rejections: list[Rejection] = field(default_factory=list)
    method: str = "none"
    critical_value: float = float("nan")
    notes: list[str] = field(default_factory=list)


def point_test_blocks(transform: Transform2D, src: np.ndarray) -> np.ndarray:
    """(N, 2, 2) blocks of ``Q_vv·P`` per point (their diagonals are the redundancy numbers).

    From the thin SVD ``U`` of the weighted Jacobian (the hat matrix is ``U·Uᵀ``):
    ``B_i = I - U_i·U_iᵀ`` with ``U_i`` the two rows of point ``i``.
    """
    fit = transform.fit
    w = np.ones(len(src)) if fit.weights is None else fit.weights
    a = transform._jacobian(np.asarray(src, dtype="float64")) * np.sqrt(np.repeat(w, 2))[:, None]
    a = a / np.linalg.norm(a, axis=0)
    u = np.linalg.svd(a, full_matrices=False)[0].reshape(len(src), 2, -1)
    return np.eye(2)[None] - np.einsum("nik,njk->nij", u, u)


def point_statistics(transform: Transform2D, src: np.ndarray,
                     sigma: float | None = None) -> tuple[np.ndarray, float]:
    """Per-point test values and the critical-value distribution's parameters.

    Returns ``(T, dof)``: with ``sigma``, ``T_i = w_i·v_iᵀ·B_i⁻¹·v_i / sigma²`` (χ² with 2 degrees
    of freedom under H0) and ``dof = inf``; without, the externally studentised
    ``F_i = (T_i / 2) / σ²_(i)`` (F with 2 and ``dof = r - 2`` degrees of freedom). Points whose
    block is singular (uncontrolled: an error there is invisible) get NaN.
    """
    fit = transform.fit
    v = fit.residuals
    w = np.ones(len(v)) if fit.weights is None else fit.weights
    blocks = point_test_blocks(transform, src)
    det = blocks[:, 0, 0] * blocks[:, 1, 1] - blocks[:, 0, 1] * blocks[:, 1, 0]
    ok = det > 1e-10
    t = np.full(len(v), np.nan)
    inv = np.linalg.inv(np.where(ok[:, None, None], blocks, np.eye(2)[None]))
    t[ok] = (w * np.einsum("ni,nij,nj->n", v, inv, v))[ok]
    if sigma is not None:
        return t / float(sigma) ** 2, float("inf")
    r = fit.redundancy
    omega = float(np.sum(w[:, None] * v ** 2))
    fitted = transform(src)
    extent = float(np.ptp(fitted, axis=0).max()) if len(fitted) else 0.0
    if omega <= float(np.sum(w)) * (1e-10 * max(extent, 1e-300)) ** 2:
        # an exact fit (residuals at rounding level): no point can be told from the others;
        # the ratio below would be rounding noise over rounding noise (or 0/0 -> inf)
        f = np.zeros(len(v))
        f[~ok] = np.nan
        return f, float(r - 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma2_without = np.maximum(omega - t, 0.0) / (r - 2)
        f = (t / 2.0) / sigma2_without
    f[ok & (sigma2_without <= 0)] = np.inf
    return f, float(r - 2)


def critical_value(alpha: float, dof: float) -> float:
    """``1 - alpha`` quantile of χ²(2) (``dof = inf``) or of F(2, dof)."""
    from scipy.special import chdtri, fdtri  # scipy.special imports much faster than stats

    if np.isinf(dof):
        return float(chdtri(2, alpha))
    return float(fdtri(2, dof, 1.0 - alpha))


def snooping_statistics(transform: Transform2D, sigma: float | None = None) -> np.ndarray:
    """(N, 2) per-coordinate standardised residuals ``v / (s·sqrt(r_i))``, ``s = sigma`` or the
    fit's sigma0 (Baarda's w / Pope's tau, for reports). Coordinates with a redundancy number
    below 1e-6 (uncontrolled) get NaN."""
    fit = transform.fit
    if fit is None:
        raise ValueError("the transform has no fit statistics")
    scale = fit.sigma0 if sigma is None else float(sigma)
    ri = fit.redundancy_numbers
    with np.errstate(divide="ignore", invalid="ignore"):
        stat = fit.residuals / (scale * np.sqrt(ri))
    stat[ri < 1e-6] = np.nan
    return stat


def data_snooping(cls: type[Transform2D], src: np.ndarray, dst: np.ndarray,
                  alpha: float = 0.001, sigma: float | None = None,
                  max_rejections: int | None = None) -> RobustFit:
    """Iterative data snooping: reject the worst point while its test fails, then refit.

    Parameters
    ----------
    cls : Transform2D subclass
        The model (similarity, affine, homography).
    src, dst : (N, 2) arrays
        Matching points (``dst`` = observed; residuals are in ``dst`` units).
    alpha : float
        Significance level of each point test, 0.001 by default.
    sigma : float, optional
        A-priori standard deviation of one ``dst`` coordinate (χ² test). Without it sigma is
        estimated without the tested point (F test); that needs a redundancy of 3 or more.
    max_rejections : int, optional
        Stop after this many rejections (default: as long as the redundancy allows a test).

    Returns
    -------
    RobustFit
        Rejections in the order they were made (``index`` into the input arrays,
        ``statistic``/``critical`` the χ² or F value and its critical value).
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    if sigma is not None and not sigma > 0:
        raise ValueError(f"sigma must be > 0, got {sigma}")
    src = np.asarray(src, dtype="float64")
    dst = np.asarray(dst, dtype="float64")
    inliers = np.ones(len(src), dtype=bool)
    rejections: list[Rejection] = []
    notes: list[str] = []
    limit = len(src) if max_rejections is None else int(max_rejections)
    critical = float("nan")
    method = "chi2-test" if sigma is not None else "F-test"
    need = cls.min_points_for(cls.n_params)
    while True:
        transform = cls.estimate(src[inliers], dst[inliers])
        r = transform.fit.redundancy
        if r < 1 or (sigma is None and r < 3):
            notes.append(f"redundancy {r} is too low to test for gross errors"
                         + ("" if sigma is not None else " without SIGMA (3 or more needed)"))
            break
        stat, dof = point_statistics(transform, src[inliers], sigma)
        critical = critical_value(alpha, dof)
        score = np.where(np.isnan(stat), -np.inf, stat)
        worst = int(np.argmax(score))
        if not score[worst] > critical:
            break
        if len(rejections) >= limit:
            notes.append(f"stopped after {limit} rejections (max_rejections)")
            break
        if inliers.sum() - 1 < need:
            notes.append("a further rejection would leave too few points; stopped")
            break
        index = int(np.flatnonzero(inliers)[worst])
        inliers[index] = False
        rejections.append(Rejection(index, float(score[worst]), critical, len(rejections) + 1,
                                    method))
    return RobustFit(transform, inliers, rejections, "snooping", critical, notes)


def ransac(cls: type[Transform2D], src: np.ndarray, dst: np.ndarray, threshold: float,
           max_trials: int = 2000, confidence: float = 0.999,
           max_refinements: int = 10) -> RobustFit:
    """RANSAC consensus (OpenCV) followed by a least-squares refit on the inliers.

    Parameters
    ----------
    cls : Transform2D subclass
    src, dst : (N, 2) arrays
        Matching points, already shifted to a local origin (OpenCV works in float32).
    threshold : float
        Largest residual norm of an inlier, ``dst`` units.
    max_trials, confidence : RANSAC iterations and confidence.
    max_refinements : int
        Refit / reclassify rounds after the consensus (stops when the inlier set is stable).

    Returns
    -------
    RobustFit
        Every point whose residual norm to the final model exceeds ``threshold`` is rejected.
    """
    import cv2

    if not threshold > 0:
        raise ValueError(f"threshold must be > 0, got {threshold}")
    src = np.asarray(src, dtype="float64")
    dst = np.asarray(dst, dtype="float64")
    need = cls.min_points_for(cls.n_params)
    if len(src) < need:
        raise InputDataError(f"a {cls.name} needs at least {need} points, got {len(src)}")
    # OpenCV samples by row number: the points go in an order of their own coordinates, so the
    # inliers do not depend on the order of the rows in the file (a CSV sorted otherwise)
    canon = np.lexsort((dst[:, 1], dst[:, 0], src[:, 1], src[:, 0]))
    given_src, given_dst = src, dst
    src, dst = src[canon], dst[canon]
    s32, d32 = src.astype("float32"), dst.astype("float32")
    if cls.name == "homography":
        _, mask = cv2.findHomography(s32, d32, cv2.RANSAC, float(threshold), maxIters=max_trials,
                                     confidence=confidence)
    elif cls.name == "affine":
        _, mask = cv2.estimateAffine2D(s32, d32, method=cv2.RANSAC,
                                       ransacReprojThreshold=float(threshold),
                                       maxIters=max_trials, confidence=confidence,
                                       refineIters=0)
    elif cls.name == "similarity":  # direct or mirrored (see SimilarityTransform): both tried
        masks = [cv2.estimateAffinePartial2D(s32 * np.float32([1, sign]), d32, method=cv2.RANSAC,
                                             ransacReprojThreshold=float(threshold),
                                             maxIters=max_trials, confidence=confidence,
                                             refineIters=0)[1] for sign in (1, -1)]
        masks = [m for m in masks if m is not None]
        mask = max(masks, key=lambda m: int(m.sum())) if masks else None
    else:  # pragma: no cover - every Transform2D in TRANSFORMS is handled above
        raise ValueError(f"no RANSAC for model {cls.name!r}")
    if mask is None or int(mask.sum()) < need:
        raise InputDataError(f"RANSAC found no {cls.name} supported by {need} or more points "
                             f"within {threshold:g}; check the points or raise the threshold")
    inliers = mask.ravel().astype(bool)
    for _ in range(max_refinements):
        transform = cls.estimate(src[inliers], dst[inliers])
        norms = np.hypot(*transform.residuals(src, dst).T)
        updated = norms <= threshold
        if updated.sum() < need or np.array_equal(updated, inliers):
            break
        inliers = updated
    src, dst, back = given_src, given_dst, inliers
    inliers = np.empty_like(back)
    inliers[canon] = back  # the final fit in the caller's order (its residuals are per point)
    transform = cls.estimate(src[inliers], dst[inliers])
    norms = np.hypot(*transform.residuals(src, dst).T)
    order = np.argsort(-norms[~inliers], kind="stable")
    rejected = np.flatnonzero(~inliers)[order]
    rejections = [Rejection(int(i), float(norms[i]), float(threshold), k + 1, "ransac")
                  for k, i in enumerate(rejected)]
    return RobustFit(transform, inliers, rejections, "ransac", float(threshold), [])
