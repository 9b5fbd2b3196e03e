"""Plane-to-plane transforms estimated by least squares: similarity (4), affine (6), homography (8).

One interface (after scikit-image's geometric transforms): ``T.estimate(src, dst)`` returns a fitted
transform or raises; a transform maps ``src`` (N, 2) points with ``T(src)``, back with
``T.inverse(dst)``; ``T.params`` is the (3, 3) matrix with ``[x', y', w]^T = params @ [x, y, 1]^T``
and ``params[2, 2] == 1``; ``T.fit`` holds the least-squares statistics.

Homography (domain brief section 5; thesis eq. [4]-[9] and [50]; S003 eq. (1)-(2))::

    x' = (a·x + b·y + c) / (g·x + h·y + 1)        y' = (d·x + e·y + f) / (g·x + h·y + 1)

Start: the linear (DLT) form multiplied by the denominator, solved on Hartley-normalised
coordinates by SVD; refinement: Gauss-Newton on the nonlinear form (linearise, solve ``A·Y = D``,
iterate), as the thesis does for interior orientation. Residuals are ``T(src) - dst`` (fitted minus
observed, in ``dst`` units), as the Siena interior-orientation reports print them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolbox.errors import ConvergenceError, InputDataError


@dataclass
class FitStatistics:
    """Least-squares statistics of a fitted transform.

    residuals : (N, 2) fitted - observed, ``dst`` units
    sigma0 : a-posteriori standard deviation of unit weight, ``sqrt(Σ w v² / r)``; NaN when r = 0
    redundancy : r = 2N - number of parameters
    redundancy_numbers : (N, 2) diagonal of Q_vv·P (0 = uncontrolled observation), for data
        snooping (standardised residual ``v / (sigma0 · sqrt(r_i))``)
    iterations : Gauss-Newton iterations (0 for linear models)
    """

    residuals: np.ndarray
    sigma0: float
    redundancy: int
    redundancy_numbers: np.ndarray
    iterations: int = 0
    weights: np.ndarray | None = field(default=None, repr=False)

    @property
    def variance(self) -> float:
        """``sigma0**2`` = Σv²/r (the Siena reports' "Sigma globale")."""
        return self.sigma0 ** 2

    @property
    def residual_norms(self) -> np.ndarray:
        return np.hypot(self.residuals[:, 0], self.residuals[:, 1])

    @property
    def rmse(self) -> tuple[float, float]:
        """Root mean square residual in x and in y."""
        return tuple(float(v) for v in np.sqrt(np.mean(self.residuals ** 2, axis=0)))

    def standardized_residuals(self) -> np.ndarray:
        """(N, 2) ``v / (sigma0 · sqrt(r_i))`` (Baarda's w-test statistic with sigma0 estimated)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.residuals / (self.sigma0 * np.sqrt(self.redundancy_numbers))


def _as_points(points: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(points, dtype="float64")
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputDataError(f"{name} points must be an (N, 2) array, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise InputDataError(f"{name} points contain NaN or inf")
    return arr


def normalization(points: np.ndarray) -> np.ndarray:
    """Hartley's conditioning matrix: centroid to the origin, mean distance sqrt(2)."""
    centre = points.mean(axis=0)
    dist = np.hypot(*(points - centre).T).mean()
    scale = np.sqrt(2.0) / dist if dist > 0 else 1.0
    return np.array([[scale, 0, -scale * centre[0]], [0, scale, -scale * centre[1]], [0, 0, 1]])


def apply_homography(matrix: np.ndarray, points: np.ndarray, return_w: bool = False):
    """Points ``(..., 2)`` through a 3 x 3 projective matrix: ``(x', y') = (M·[x, y, 1])[:2] / w``
    with ``w = (M·[x, y, 1])[2]`` (the one implementation; ``return_w`` also gives ``w``, whose
    sign tells which side of the vanishing line a point is)."""
    pts = np.asarray(points, dtype="float64")
    w = matrix[2, 0] * pts[..., 0] + matrix[2, 1] * pts[..., 1] + matrix[2, 2]
    x = (matrix[0, 0] * pts[..., 0] + matrix[0, 1] * pts[..., 1] + matrix[0, 2]) / w
    y = (matrix[1, 0] * pts[..., 0] + matrix[1, 1] * pts[..., 1] + matrix[1, 2]) / w
    out = np.stack([x, y], axis=-1)
    return (out, w) if return_w else out


def check_not_collinear(points: np.ndarray, name: str) -> None:
    """Raise :class:`InputDataError` when the points lie (numerically) on one line (the shared
    test of :func:`toolbox.terrain.points.check_not_collinear`)."""
    from toolbox.terrain.points import check_not_collinear as check

    try:
        check(points, f"{name} points")
    except ValueError:  # on one line, or all at one position
        raise InputDataError(f"the {name} points are collinear (or coincident): a plane transform "
                             "needs points spread in two directions") from None


class Transform2D:
    """Base class. Subclasses set ``name``, ``n_params`` and implement ``_estimate_normalised``."""

    name = ""
    n_params = 0
    needs_two_directions = True  # points on one line do not determine it

    def __init__(self, params: np.ndarray | None = None):
        self.params = np.eye(3) if params is None else np.asarray(params, dtype="float64")
        if self.params.shape != (3, 3):
            raise ValueError("params must be a (3, 3) matrix")
        self.fit: FitStatistics | None = None

    @property
    def min_points(self) -> int:
        return (self.n_params + 1) // 2

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return apply_homography(self.params, np.asarray(points, dtype="float64"))

    def inverse(self, points: np.ndarray) -> np.ndarray:
        return apply_homography(np.linalg.inv(self.params), np.asarray(points, dtype="float64"))

    def inverse_transform(self) -> Transform2D:
        """The inverse as a transform of the same kind (matrix normalised to ``[2, 2] = 1``)."""
        inv = np.linalg.inv(self.params)
        return type(self)(inv / inv[2, 2])

    def residuals(self, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        """``T(src) - dst``, (N, 2)."""
        return self(src) - np.asarray(dst, dtype="float64")

    @classmethod
    def estimate(cls, src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None,
                 max_iterations: int = 50, tolerance: float = 1e-12) -> Transform2D:
        """Least-squares fit mapping ``src`` onto ``dst``.

        ``weights`` (N,) apply to both coordinates of a point. Raises :class:`InputDataError`
        for too few or collinear points, :class:`ConvergenceError` if the iteration diverges.
        """
        src = _as_points(src, "source")
        dst = _as_points(dst, "target")
        if len(src) != len(dst):
            raise InputDataError(f"{len(src)} source points but {len(dst)} target points")
        if len(src) < cls.min_points_for(cls.n_params):
            raise InputDataError(f"a {cls.name} needs at least {cls.min_points_for(cls.n_params)} "
                                 f"points, got {len(src)}")
        if cls.needs_two_directions:
            check_not_collinear(src, "source")
            check_not_collinear(dst, "target")
        else:  # two distinct points determine a similarity, on a line or not
            for pts, which in ((src, "source"), (dst, "target")):
                if not np.ptp(pts, axis=0).max() > 0:
                    raise InputDataError(f"the {which} points all coincide: a {cls.name} needs "
                                         "two distinct points")
        w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype="float64")
        if w.shape != (len(src),) or not np.all(w > 0):
            raise InputDataError("weights must be one positive number per point")
        ns, nd = normalization(src), normalization(dst)
        src_n, dst_n = apply_homography(ns, src), apply_homography(nd, dst)
        matrix_n, iterations = cls._estimate_normalised(src_n, dst_n, w, max_iterations, tolerance)
        matrix = np.linalg.inv(nd) @ matrix_n @ ns
        transform = cls(matrix / matrix[2, 2])
        transform.fit = transform._statistics(src, dst, w, iterations)
        return transform

    @staticmethod
    def min_points_for(n_params: int) -> int:
        return (n_params + 1) // 2

    # -- statistics ---------------------------------------------------------------------------
    def _jacobian(self, src: np.ndarray) -> np.ndarray:
        """(2N, n_params) partial derivatives of the mapped coordinates (for redundancy numbers)."""
        raise NotImplementedError

    def _statistics(self, src, dst, w, iterations) -> FitStatistics:
        v = self.residuals(src, dst)
        r = 2 * len(src) - self.n_params
        sigma0 = float(np.sqrt(np.sum(w[:, None] * v ** 2) / r)) if r > 0 else float("nan")
        # r_i = 1 - (leverage of observation i) = diagonal of Q_vv·P; the column space of the
        # weighted Jacobian gives the leverages (columns scaled to unit norm for conditioning)
        a = self._jacobian(src) * np.sqrt(np.repeat(w, 2))[:, None]
        a = a / np.linalg.norm(a, axis=0)
        u = np.linalg.svd(a, full_matrices=False)[0]
        ri = np.clip(1.0 - np.sum(u ** 2, axis=1), 0.0, 1.0).reshape(-1, 2)
        return FitStatistics(v, sigma0, r, ri, iterations, w)


class SimilarityTransform(Transform2D):
    """4 parameters: ``x' = a·x - b·y + tx``, ``y' = b·x + a·y + ty`` (scale, rotation, shift), or
    its mirror image ``x' = a·x + b·y + tx``, ``y' = b·x - a·y + ty`` (``det < 0``) when that fits
    better: between a system whose y axis points down (pixel rows) and one whose y points up
    (ground, fiducial mm) a shape-preserving map includes a reflection. With exactly two points
    both fit; the direct form is kept (callers with rows-down coordinates negate them first)."""

    name = "similarity"
    n_params = 4
    needs_two_directions = False

    @staticmethod
    def _design(x, y, n):
        a = np.zeros((2 * n, 4))
        a[0::2] = np.column_stack([x, -y, np.ones(n), np.zeros(n)])
        a[1::2] = np.column_stack([y, x, np.zeros(n), np.ones(n)])
        return a

    @classmethod
    def _estimate_normalised(cls, src, dst, w, max_iterations, tolerance):
        x, y = src.T
        n = len(src)
        sw = np.sqrt(np.repeat(w, 2))
        best = None
        for sign in (1.0, -1.0):  # direct, then mirrored (y -> -y before the direct form)
            a = cls._design(x, sign * y, n)
            sol = np.linalg.lstsq(a * sw[:, None], dst.ravel() * sw, rcond=None)[0]
            ssr = float(np.sum((sw * (a @ sol - dst.ravel())) ** 2))
            ca, cb, tx, ty = sol
            matrix = np.array([[ca, -cb * sign, tx], [cb, ca * sign, ty], [0, 0, 1.0]])
            scale = float(np.sum((sw * dst.ravel()) ** 2))
            if best is None or ssr < best[0] - 1e-9 * max(scale, 1e-300):
                best = (ssr, matrix)
        return best[1], 0

    def _jacobian(self, src):
        x, y = src.T
        sign = -1.0 if np.linalg.det(self.params[:2, :2]) < 0 else 1.0
        return self._design(x, sign * y, len(src))

    @property
    def scale(self) -> float:
        return float(np.hypot(self.params[0, 0], self.params[1, 0]))

    @property
    def rotation(self) -> float:
        """Counter-clockwise rotation angle, radians."""
        return float(np.arctan2(self.params[1, 0], self.params[0, 0]))


class AffineTransform(Transform2D):
    """6 parameters: ``x' = m11·x + m12·y + m13``, ``y' = m21·x + m22·y + m23``."""

    name = "affine"
    n_params = 6

    @classmethod
    def _estimate_normalised(cls, src, dst, w, max_iterations, tolerance):
        a = np.column_stack([src, np.ones(len(src))])
        sw = np.sqrt(w)[:, None]
        sol = np.linalg.lstsq(a * sw, dst * sw, rcond=None)[0]  # (3, 2)
        return np.vstack([sol.T, [0, 0, 1.0]]), 0

    def _jacobian(self, src):
        n = len(src)
        a = np.zeros((2 * n, 6))
        a[0::2, 0:2], a[0::2, 2] = src, 1
        a[1::2, 3:5], a[1::2, 5] = src, 1
        return a


class HomographyTransform(Transform2D):
    """8 parameters (``params[2, 2] = 1``): the central projection between two planes."""

    name = "homography"
    n_params = 8

    @classmethod
    def _estimate_normalised(cls, src, dst, w, max_iterations, tolerance):
        matrix = cls._dlt(src, dst, w)
        iterations = 0
        for iterations in range(1, max_iterations + 1):  # noqa: B007 (reported)
            h = matrix.ravel()[:8]
            a = cls._jacobian_of(h, src)
            d = (dst - apply_homography(matrix, src)).ravel()
            sw = np.sqrt(np.repeat(w, 2))
            step = np.linalg.lstsq(a * sw[:, None], d * sw, rcond=None)[0]
            matrix = np.append(h + step, 1.0).reshape(3, 3)
            if not np.all(np.isfinite(matrix)):
                raise ConvergenceError("the homography iteration diverged (check the points)")
            if np.max(np.abs(step)) < tolerance * max(1.0, np.max(np.abs(h))):
                break
        else:
            raise ConvergenceError(f"the homography did not converge in {max_iterations} "
                                   "iterations")
        return matrix, iterations

    @staticmethod
    def _dlt(src, dst, w) -> np.ndarray:
        """Linear start: solve the multiplied-out equations (thesis eq. [5]-[8]) by SVD."""
        x, y = src.T
        u, v = dst.T
        n = len(src)
        zeros, ones = np.zeros(n), np.ones(n)
        rows_u = np.column_stack([x, y, ones, zeros, zeros, zeros, -u * x, -u * y, -u])
        rows_v = np.column_stack([zeros, zeros, zeros, x, y, ones, -v * x, -v * y, -v])
        a = np.empty((2 * n, 9))
        a[0::2], a[1::2] = rows_u, rows_v
        a *= np.sqrt(np.repeat(w, 2))[:, None]
        # thin SVD (U of a 2N x 2N size is never needed) unless 2N < 9, where the null vector
        # is only in the full V
        _, s, vt = np.linalg.svd(a, full_matrices=a.shape[0] < a.shape[1])
        if len(s) >= 8 and s[7] < 1e-10 * s[0]:
            raise InputDataError("the points do not determine a homography (at least 4 points, no 3 "
                                 "of any 4 on one line, are needed)")
        h = vt[-1]
        if abs(h[8]) < 1e-12:
            raise InputDataError("degenerate homography (the plane's horizon passes through the "
                                 "points' centroid)")
        return (h / h[8]).reshape(3, 3)

    @staticmethod
    def _jacobian_of(h: np.ndarray, src: np.ndarray) -> np.ndarray:
        x, y = src.T
        num_x = h[0] * x + h[1] * y + h[2]
        num_y = h[3] * x + h[4] * y + h[5]
        den = h[6] * x + h[7] * y + 1.0
        px, py = num_x / den, num_y / den
        n = len(src)
        a = np.zeros((2 * n, 8))
        a[0::2, 0], a[0::2, 1], a[0::2, 2] = x / den, y / den, 1 / den
        a[0::2, 6], a[0::2, 7] = -px * x / den, -px * y / den
        a[1::2, 3], a[1::2, 4], a[1::2, 5] = x / den, y / den, 1 / den
        a[1::2, 6], a[1::2, 7] = -py * x / den, -py * y / den
        return a

    def _jacobian(self, src):
        return self._jacobian_of(self.params.ravel()[:8], src)


TRANSFORMS: dict[str, type[Transform2D]] = {
    "similarity": SimilarityTransform, "affine": AffineTransform, "homography": HomographyTransform,
}
