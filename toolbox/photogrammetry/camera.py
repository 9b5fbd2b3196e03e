"""Camera model: principal distance, principal point, fiducial marks, image size, lens distortion
(radial and decentring); image (fiducial mm) <-> camera (reduced, distortion-free) coordinates.

Coordinates (domain brief section 1-2)
--------------------------------------
- *image* coordinates ``(x, y)``: millimetres in the fiducial system (origin at the fiducial
  centre, x right, y up), what the pixel -> fiducial transform of the interior orientation gives;
- *camera* coordinates ``(x̄, ȳ)``: image coordinates reduced to the principal point and
  corrected for distortion, i.e. the ideal central projection that the collinearity
  equations use with ``ξ0 = η0 = 0`` (the ray of a point is ``(x̄, ȳ, -c)``).

Distortion (correction form, the convention ``orientation:bundle`` estimates)
-----------------------------------------------------------------------------
Everything is a function of the *measured* reduced coordinates ``u = x - x0``, ``v = y - y0``
(mm), ``r = √(u² + v²)`` (mm, as calibration certificates list it)::

    x̄ = u - u·Δr(r)/r - [p1·(r² + 2u²) + 2·p2·u·v]
    ȳ = v - v·Δr(r)/r - [p2·(r² + 2v²) + 2·p1·u·v]

``Δr(r)`` is the radial displacement (mm) of the imaged point from its ideal position, given

- as a table ``r (mm) -> Δr`` (the Siena logs print R in mm and DR in µm, l.2257-2285),
  interpolated linearly, with ``Δr(0) = 0`` and the last value held beyond the last node; or
- as polynomial coefficients ``Δr = k1·r³ + k2·r⁵ + k3·r⁷`` (S003 l.43; k1 mm⁻², k2 mm⁻⁴,
  k3 mm⁻⁶), with Brown's decentring terms ``p1``, ``p2`` (mm⁻¹; p1 pairs with ``r² + 2u²`` in
  x, as Brown 1971 / Metashape / the bundle's Jacobians; OpenCV's p1, p2 are these swapped).

Positive k1 pulls points inwards on correction (barrel distortion is a negative Δr). Correcting
(image -> camera) is closed form; distorting an ideal point (camera -> image) solves
``correct(m) = ideal`` by Newton's method from ``m = ideal``, to |step| <= 1e-9 mm (0.001 nm),
and gives NaN where it does not converge within 20 steps (a distortion that folds back).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

DISTORTION_NONE, DISTORTION_TABLE, DISTORTION_POLYNOMIAL = 0, 1, 2
DISTORT_TOLERANCE_MM = 1e-9  # Newton step at which distort() has converged (0.001 nm)
DISTORT_ITERATIONS = 20
POLYNOMIAL_TERMS = ("k1", "k2", "k3", "p1", "p2")


@dataclass(frozen=True, eq=False)
class RadialDistortion:
    """Lens distortion in the correction form of the module docstring: radial, a table
    ``r -> Δr`` or the polynomial ``k1·r³ + k2·r⁵ + k3·r⁷`` with decentring ``p1``, ``p2``
    (mm; a table has no decentring).

    Build with :meth:`from_table` or :meth:`from_polynomial`; ``mode`` is
    ``DISTORTION_TABLE`` or ``DISTORTION_POLYNOMIAL``.
    """

    mode: int
    r_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    dr_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    @classmethod
    def from_table(cls, r_mm: Sequence[float], dr: Sequence[float], dr_unit: str = "um"
                   ) -> RadialDistortion:
        """Table of radii (mm, strictly increasing, >= 0) and displacements in ``dr_unit``
        (``"um"`` or ``"mm"``). ``(0, 0)`` is prepended when the first radius is > 0."""
        r = np.asarray(r_mm, dtype="float64").ravel()
        d = np.asarray(dr, dtype="float64").ravel()
        if dr_unit not in ("um", "mm"):
            raise InputDataError(f"distortion table unit must be 'um' or 'mm', got {dr_unit!r}")
        if len(r) != len(d) or len(r) == 0:
            raise InputDataError(f"distortion table needs as many radii as values, got {len(r)} "
                                 f"radii and {len(d)} values")
        if not (np.isfinite(r).all() and np.isfinite(d).all()):
            raise InputDataError("distortion table contains NaN or inf")
        if r[0] < 0 or np.any(np.diff(r) <= 0):
            raise InputDataError(f"distortion table radii must be >= 0 and strictly increasing, "
                                 f"got {r.tolist()}")
        d = d / 1000.0 if dr_unit == "um" else d
        if r[0] > 0:
            r, d = np.concatenate([[0.0], r]), np.concatenate([[0.0], d])
        if len(r) < 2:
            raise InputDataError("distortion table needs at least one radius > 0")
        return cls(DISTORTION_TABLE, r, d)

    @classmethod
    def from_polynomial(cls, k1: float, k2: float = 0.0, k3: float = 0.0, p1: float = 0.0,
                        p2: float = 0.0) -> RadialDistortion:
        """``Δr = k1·r³ + k2·r⁵ + k3·r⁷`` and decentring ``p1``, ``p2``, r and Δr in mm."""
        terms = dict(zip(POLYNOMIAL_TERMS, (k1, k2, k3, p1, p2)))
        bad = {k: v for k, v in terms.items() if not math.isfinite(v)}
        if bad:
            raise InputDataError("distortion coefficients must be finite, got "
                                 + ", ".join(f"{k}={v}" for k, v in bad.items()))
        return cls(DISTORTION_POLYNOMIAL, **{k: float(v) for k, v in terms.items()})

    @property
    def decentring(self) -> bool:
        """True when p1 or p2 is not zero."""
        return self.p1 != 0.0 or self.p2 != 0.0

    def delta_r(self, r: np.ndarray) -> np.ndarray:
        """Radial displacement Δr (mm) at measured radius ``r`` (mm)."""
        r = np.asarray(r, dtype="float64")
        if self.mode == DISTORTION_TABLE:
            return np.interp(r, self.r_mm, self.dr_mm)
        r2 = r * r
        return (self.k1 + r2 * (self.k2 + r2 * self.k3)) * r2 * r

    def _slope(self, r: np.ndarray) -> np.ndarray:
        """dΔr/dr at ``r`` (mm/mm)."""
        if self.mode == DISTORTION_TABLE:
            slopes = np.diff(self.dr_mm) / np.diff(self.r_mm)
            k = np.clip(np.searchsorted(self.r_mm, r, side="right") - 1, 0, len(slopes) - 1)
            return np.where(r >= self.r_mm[-1], 0.0, slopes[k])
        r2 = r * r
        return (3.0 * self.k1 + r2 * (5.0 * self.k2 + 7.0 * r2 * self.k3)) * r2

    def shift(self, xy: np.ndarray) -> np.ndarray:
        """The correction ``δ(m) = m - ideal`` (mm) at measured reduced coordinates ``m``."""
        xy = np.asarray(xy, dtype="float64")
        u, v = xy[..., 0], xy[..., 1]
        r = np.hypot(u, v)
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.where(r > 0, self.delta_r(r) / np.where(r > 0, r, 1.0), 0.0)
        r2 = u * u + v * v
        return np.stack([u * g + (self.p1 * (r2 + 2 * u * u) + 2 * self.p2 * u * v),
                         v * g + (self.p2 * (r2 + 2 * v * v) + 2 * self.p1 * u * v)], axis=-1)

    def correct(self, xy: np.ndarray) -> np.ndarray:
        """Measured (distorted) -> ideal, coordinates relative to the principal point (mm)."""
        xy = np.asarray(xy, dtype="float64")
        return xy - self.shift(xy)

    def _shift_jacobian(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        """``dδ/dm`` as (a, b, c, d) = (dδx/du, dδx/dv, dδy/du, dδy/dv) arrays."""
        r = np.hypot(u, v)
        safe = np.where(r > 0, r, 1.0)
        g = np.where(r > 0, self.delta_r(r) / safe, 0.0)
        h = np.where(r > 0, (self._slope(r) - g) / (safe * safe), 0.0)  # (Δr' - g)/r²
        p1, p2 = self.p1, self.p2
        return (g + u * u * h + 6 * p1 * u + 2 * p2 * v, u * v * h + 2 * p1 * v + 2 * p2 * u,
                u * v * h + 2 * p2 * u + 2 * p1 * v, g + v * v * h + 6 * p2 * v + 2 * p1 * u)

    def distort(self, xy: np.ndarray) -> np.ndarray:
        """Ideal -> measured (distorted), inverse of :meth:`correct`: Newton's method on
        ``correct(m) = ideal`` from ``m = ideal``; NaN where the step is still above
        :data:`DISTORT_TOLERANCE_MM` after :data:`DISTORT_ITERATIONS` steps."""
        xy = np.asarray(xy, dtype="float64")
        ideal = xy.reshape(-1, 2)
        m = ideal.copy()
        done = np.zeros(len(m), dtype=bool)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for _ in range(DISTORT_ITERATIONS):
                todo = ~done
                if not todo.any():
                    break
                mu, mv = m[todo, 0], m[todo, 1]
                res = self.correct(m[todo]) - ideal[todo]
                a, b, c, d = self._shift_jacobian(mu, mv)
                a, b, c, d = 1 - a, -b, -c, 1 - d  # d correct / dm
                det = a * d - b * c
                su = (d * res[:, 0] - b * res[:, 1]) / det
                sv = (a * res[:, 1] - c * res[:, 0]) / det
                m[todo, 0] -= su
                m[todo, 1] -= sv
                done[todo] = np.hypot(su, sv) <= DISTORT_TOLERANCE_MM
        m[~done] = np.nan
        return m.reshape(xy.shape)

    def kernel_arguments(self) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(mode, r_nodes, dr_nodes, (k1, k2, bin width, k3, p1, p2), bin_segments)`` for
        the compiled kernels: ``bin_segments[b]`` is the table segment holding radius
        ``b·width`` (1024 bins over the table), so a lookup is a short scan instead of a
        binary search."""
        if self.mode != DISTORTION_TABLE:
            return (self.mode, np.zeros(2), np.zeros(2),
                    np.array([self.k1, self.k2, 1.0, self.k3, self.p1, self.p2]),
                    np.zeros(1, dtype=np.int64))
        r = np.ascontiguousarray(self.r_mm)
        width = r[-1] / 1024.0
        starts = np.arange(1024) * width
        segments = np.clip(np.searchsorted(r, starts, side="right") - 1, 0, len(r) - 2)
        return (self.mode, r, np.ascontiguousarray(self.dr_mm),
                np.array([0.0, 0.0, width, 0.0, 0.0, 0.0]), segments.astype(np.int64))

    def as_dict(self) -> dict[str, Any]:
        """The project YAML's ``distortion:`` mapping; k3, p1, p2 only when not zero."""
        if self.mode == DISTORTION_TABLE:
            keep = slice(1, None) if self.r_mm[0] == 0 and self.dr_mm[0] == 0 else slice(None)
            return {"table": {"r_mm": self.r_mm[keep].tolist(),
                              "dr_um": (self.dr_mm[keep] * 1000.0).round(9).tolist()}}
        terms = {k: getattr(self, k) for k in POLYNOMIAL_TERMS}
        return {"polynomial": {k: v for k, v in terms.items() if k in ("k1", "k2") or v != 0.0}}

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], where: str = "distortion") -> RadialDistortion:
        """Parse ``{"table": {"r_mm": [...], "dr_um": [...]}}`` (or ``dr_mm``) or
        ``{"polynomial": {"k1": ..., "k2": ..., "k3": ..., "p1": ..., "p2": ...}}`` (k1
        required, the others 0 when missing)."""
        if not isinstance(spec, Mapping) or len(spec) != 1 or \
                next(iter(spec)) not in ("table", "polynomial"):
            raise InputDataError(f"{where} must be a mapping with one key, 'table' or 'polynomial'"
                                 f"; got {spec!r}")
        kind, body = next(iter(spec.items()))
        if not isinstance(body, Mapping):
            raise InputDataError(f"{where}.{kind} must be a mapping, got {body!r}")
        try:
            if kind == "table":
                unit = "um" if "dr_um" in body else "mm"
                return cls.from_table(body["r_mm"], body["dr_um" if unit == "um" else "dr_mm"], unit)
            unknown = sorted(set(map(str, body)) - set(POLYNOMIAL_TERMS))
            if unknown:
                raise InputDataError(f"{where}.polynomial has no {', '.join(unknown)} (terms: "
                                     f"{', '.join(POLYNOMIAL_TERMS)})")
            if "k1" not in body:
                raise KeyError("k1")
            values = []
            for k in POLYNOMIAL_TERMS:
                try:
                    values.append(float(body.get(k, 0.0)))
                except (TypeError, ValueError):
                    raise InputDataError(f"{where}.polynomial.{k} must be a number, got "
                                         f"{body[k]!r}") from None
            return cls.from_polynomial(*values)
        except KeyError as exc:
            raise InputDataError(f"{where}.{kind} lacks {exc.args[0]!r}") from None

    def magnitude_bound(self, radius_mm: float) -> float:
        """Bound of ``|δ|`` (mm), the distortion's shift of a point, for measured radii up to
        ``radius_mm``: a table's largest node value (piecewise linear, last value held); a
        polynomial's radial part sampled densely on [0, 1.05 radius] and widened by 5 %,
        plus the decentring's ``r²·hypot(3|p1| + |p2|, 3|p2| + |p1|)`` at 1.05 radius."""
        if self.mode == DISTORTION_TABLE:
            return float(np.abs(self.dr_mm).max())
        rr = np.linspace(0.0, 1.05 * radius_mm, 4097)
        p1, p2 = abs(self.p1), abs(self.p2)
        return 1.05 * float(np.abs(self.delta_r(rr)).max()) + \
            rr[-1] ** 2 * math.hypot(3 * p1 + p2, 3 * p2 + p1)

    def lipschitz_bound(self, radius_mm: float) -> float:
        """Bound of the Jacobian norm of ``distort(p) - p`` for radii up to ``radius_mm``.

        With ``J`` the Jacobian of the correction's shift δ(m), distort(p) - p = δ(m) has the
        Jacobian ``J·(I - J)⁻¹``, of norm <= ``L/(1 - L)`` where ``L >= |J|``. The radial part
        of J has the eigenvalues ``Δr'`` and ``Δr/r``: a table is piecewise linear (the
        first largest on a segment, the second at a node), a polynomial is sampled densely on
        [0, 1.05 radius] (widened by 5 %); the decentring's part is ``u·A + v·B`` (A, B
        constant: A = [[6p1, 2p2], [2p2, 2p1]], B = [[2p2, 2p1], [2p1, 6p2]]), of norm
        <= ``r·√(|A|² + |B|²)`` (Frobenius) at 1.05 radius. Infinite when
        L >= 1 (the distortion may fold)."""
        if self.mode == DISTORTION_TABLE:
            r, d = self.r_mm, self.dr_mm
            nodes = r > 0
            radial = max(float(np.abs(np.diff(d) / np.diff(r)).max()),
                         float((np.abs(d[nodes]) / r[nodes]).max(initial=0.0)))
        else:
            rr = np.linspace(0.0, 1.05 * radius_mm, 4097)[1:]
            radial = 1.05 * max(float(np.abs(self._slope(rr)).max()),
                                float(np.abs(self.delta_r(rr) / rr).max()))
        p1, p2 = self.p1, self.p2
        frob = math.sqrt(48.0 * (p1 * p1 + p2 * p2))  # |A|² + |B|², A, B of the docstring
        bound = radial + 1.05 * radius_mm * frob
        return bound / (1.0 - bound) if bound < 1.0 else math.inf


@dataclass(frozen=True, eq=False)
class Camera:
    """A metric camera (frame camera, film or digital).

    Attributes
    ----------
    name : str
    principal_distance_mm : float
        ``c`` (> 0).
    principal_point_mm : (float, float)
        ``(ξ0, η0)`` in the fiducial system; (0, 0) when PP ≡ fiducial centre.
    fiducials_mm : dict
        Mark id -> calibrated ``(x, y)`` in mm (empty for digital cameras).
    image_size_px : (int, int) or None
        ``(width, height)`` of the (scanned) image in pixels.
    pixel_size_mm : float or None
        Nominal pixel size (digital sensor or scan), used when a photo has no fitted interior
        orientation and for ground-sampling figures.
    frame_size_mm : (float, float) or None
        ``(width, height)`` of the image format (e.g. 230 x 230 for aerial film), centred on the
        fiducial centre; used for footprints.
    distortion : RadialDistortion or None
    """

    name: str
    principal_distance_mm: float
    principal_point_mm: tuple[float, float] = (0.0, 0.0)
    fiducials_mm: dict[str, tuple[float, float]] = field(default_factory=dict)
    image_size_px: tuple[int, int] | None = None
    pixel_size_mm: float | None = None
    frame_size_mm: tuple[float, float] | None = None
    distortion: RadialDistortion | None = None

    def __post_init__(self) -> None:
        c = self.principal_distance_mm
        if not (isinstance(c, (int, float)) and math.isfinite(c) and c > 0):
            raise InputDataError(f"camera {self.name!r}: principal distance must be > 0 mm, got {c!r}")
        if len(self.principal_point_mm) != 2 or not all(math.isfinite(v)
                                                         for v in self.principal_point_mm):
            raise InputDataError(f"camera {self.name!r}: principal point must be two finite "
                                 f"numbers (mm), got {self.principal_point_mm!r}")
        if self.pixel_size_mm is not None and not self.pixel_size_mm > 0:
            raise InputDataError(f"camera {self.name!r}: pixel size must be > 0 mm, got "
                                 f"{self.pixel_size_mm!r}")
        if self.image_size_px is not None and (len(self.image_size_px) != 2
                                               or min(self.image_size_px) <= 0):
            raise InputDataError(f"camera {self.name!r}: image size must be (width, height) > 0 px,"
                                 f" got {self.image_size_px!r}")

    @property
    def c(self) -> float:
        """Principal distance (mm)."""
        return self.principal_distance_mm

    # -- image <-> camera ------------------------------------------------------------------------
    def image_to_camera(self, xy_mm: np.ndarray) -> np.ndarray:
        """Image (fiducial, mm) -> camera coordinates: minus the principal point, distortion
        corrected. (N, 2) -> (N, 2)."""
        xy = np.asarray(xy_mm, dtype="float64") - np.asarray(self.principal_point_mm)
        return xy if self.distortion is None else self.distortion.correct(xy)

    def camera_to_image(self, xy: np.ndarray) -> np.ndarray:
        """Camera -> image (fiducial, mm) coordinates: distortion added, plus the principal point."""
        xy = np.asarray(xy, dtype="float64")
        if self.distortion is not None:
            xy = self.distortion.distort(xy)
        return xy + np.asarray(self.principal_point_mm)

    # -- frame -----------------------------------------------------------------------------------
    def frame_outline_mm(self, points_per_side: int = 1) -> np.ndarray | None:
        """Outline of the image format in image mm, counter-clockwise from the top-left corner,
        ``points_per_side`` points per side (corners included once); None if unknown."""
        if self.frame_size_mm is None:
            return None
        w, h = (v / 2.0 for v in self.frame_size_mm)
        return outline_points(np.array([[-w, h], [-w, -h], [w, -h], [w, h]]), points_per_side)

    def as_dict(self) -> dict[str, Any]:
        spec: dict[str, Any] = {"name": self.name, "principal_distance_mm": self.c,
                                "principal_point_mm": list(self.principal_point_mm)}
        if self.fiducials_mm:
            spec["fiducials_mm"] = {k: list(v) for k, v in self.fiducials_mm.items()}
        if self.image_size_px is not None:
            spec["image_size_px"] = list(self.image_size_px)
        if self.pixel_size_mm is not None:
            spec["pixel_size_mm"] = self.pixel_size_mm
        if self.frame_size_mm is not None:
            spec["frame_size_mm"] = list(self.frame_size_mm)
        if self.distortion is not None:
            spec["distortion"] = self.distortion.as_dict()
        return spec


def outline_points(corners: np.ndarray, points_per_side: int) -> np.ndarray:
    """A closed polygon's vertices (not repeated at the end) with ``points_per_side`` evenly
    spaced points on each side, starting at each corner."""
    n = max(1, int(points_per_side))
    t = np.arange(n) / n
    sides = [corners[i] + t[:, None] * (corners[(i + 1) % len(corners)] - corners[i])
             for i in range(len(corners))]
    return np.vstack(sides)
