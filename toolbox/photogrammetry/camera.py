"""Camera model: principal distance, principal point, fiducial marks, image size, radial distortion;
image (fiducial mm) <-> camera (reduced, distortion-free) coordinates.

Coordinates (domain brief section 1-2)
--------------------------------------
- *image* coordinates ``(x, y)``: millimetres in the fiducial system (origin at the fiducial
  centre, x right, y up), what the pixel -> fiducial transform of the interior orientation gives;
- *camera* coordinates ``(x̄, ȳ)``: image coordinates reduced to the principal point and
  corrected for radial distortion, i.e. the ideal central projection that the collinearity
  equations use with ``ξ0 = η0 = 0`` (the ray of a point is ``(x̄, ȳ, -c)``).

Radial distortion
-----------------
``Δr(r)`` is the radial displacement (mm) of the imaged point from its ideal position, as a
function of the *measured* radial distance ``r`` from the principal point (as calibration
certificates list it). Correction: ``x̄ = x·(1 - Δr(r)/r)`` (brief section 2, Impl. note; the
sources give no sign convention: check against the certificate). Δr is given either

- as a table ``r (mm) -> Δr`` (the Siena logs print R in mm and DR in µm, l.2257-2285),
  interpolated linearly, with ``Δr(0) = 0`` and the last value held beyond the last node; or
- as polynomial coefficients ``Δr = k1·r³ + k2·r⁵`` (S003 l.43; k1 in mm⁻², k2 in mm⁻⁴).

Distorting an ideal point (camera -> image) inverts ``r̄ = r - Δr(r)`` by fixed-point iteration
``r <- r̄ + Δr(r)``, which converges because ``|dΔr/dr| << 1``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

DISTORTION_NONE, DISTORTION_TABLE, DISTORTION_POLYNOMIAL = 0, 1, 2
_DISTORT_ITERATIONS = 8


@dataclass(frozen=True, eq=False)
class RadialDistortion:
    """Symmetric radial distortion, a table ``r -> Δr`` or polynomial ``k1·r³ + k2·r⁵`` (mm).

    Build with :meth:`from_table` or :meth:`from_polynomial`; ``mode`` is
    ``DISTORTION_TABLE`` or ``DISTORTION_POLYNOMIAL``.
    """

    mode: int
    r_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    dr_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    k1: float = 0.0
    k2: float = 0.0

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
    def from_polynomial(cls, k1: float, k2: float = 0.0) -> RadialDistortion:
        """``Δr = k1·r³ + k2·r⁵`` with r and Δr in mm."""
        if not (math.isfinite(k1) and math.isfinite(k2)):
            raise InputDataError(f"distortion coefficients must be finite, got k1={k1}, k2={k2}")
        return cls(DISTORTION_POLYNOMIAL, k1=float(k1), k2=float(k2))

    def delta_r(self, r: np.ndarray) -> np.ndarray:
        """Radial displacement Δr (mm) at measured radius ``r`` (mm)."""
        r = np.asarray(r, dtype="float64")
        if self.mode == DISTORTION_TABLE:
            return np.interp(r, self.r_mm, self.dr_mm)
        return self.k1 * r ** 3 + self.k2 * r ** 5

    def correct(self, xy: np.ndarray) -> np.ndarray:
        """Measured (distorted) -> ideal, coordinates relative to the principal point (mm)."""
        xy = np.asarray(xy, dtype="float64")
        r = np.hypot(xy[..., 0], xy[..., 1])
        with np.errstate(invalid="ignore", divide="ignore"):
            factor = np.where(r > 0, 1.0 - self.delta_r(r) / r, 1.0)
        return xy * factor[..., None]

    def distort(self, xy: np.ndarray) -> np.ndarray:
        """Ideal -> measured (distorted), inverse of :meth:`correct` (fixed-point iteration)."""
        xy = np.asarray(xy, dtype="float64")
        r_ideal = np.hypot(xy[..., 0], xy[..., 1])
        r = r_ideal.copy()
        for _ in range(_DISTORT_ITERATIONS):
            r = r_ideal + self.delta_r(r)
        with np.errstate(invalid="ignore", divide="ignore"):
            factor = np.where(r_ideal > 0, r / r_ideal, 1.0)
        return xy * factor[..., None]

    def kernel_arguments(self) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(mode, r_nodes, dr_nodes, (k1, k2, bin width), bin_segments)`` for the compiled
        kernels: ``bin_segments[b]`` is the table segment holding radius ``b·width`` (1024 bins
        over the table), so a lookup is a short scan instead of a binary search."""
        if self.mode != DISTORTION_TABLE:
            return (self.mode, np.zeros(2), np.zeros(2), np.array([self.k1, self.k2, 1.0]),
                    np.zeros(1, dtype=np.int64))
        r = np.ascontiguousarray(self.r_mm)
        width = r[-1] / 1024.0
        starts = np.arange(1024) * width
        segments = np.clip(np.searchsorted(r, starts, side="right") - 1, 0, len(r) - 2)
        return (self.mode, r, np.ascontiguousarray(self.dr_mm), np.array([0.0, 0.0, width]),
                segments.astype(np.int64))

    def as_dict(self) -> dict[str, Any]:
        if self.mode == DISTORTION_TABLE:
            keep = slice(1, None) if self.r_mm[0] == 0 and self.dr_mm[0] == 0 else slice(None)
            return {"table": {"r_mm": self.r_mm[keep].tolist(),
                              "dr_um": (self.dr_mm[keep] * 1000.0).round(9).tolist()}}
        return {"polynomial": {"k1": self.k1, "k2": self.k2}}

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], where: str = "distortion") -> RadialDistortion:
        """Parse ``{"table": {"r_mm": [...], "dr_um": [...]}}`` (or ``dr_mm``) or
        ``{"polynomial": {"k1": ..., "k2": ...}}``."""
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
            return cls.from_polynomial(float(body["k1"]), float(body.get("k2", 0.0)))
        except KeyError as exc:
            raise InputDataError(f"{where}.{kind} lacks {exc.args[0]!r}") from None


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
