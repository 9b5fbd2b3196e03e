"""Interior camera models: pinhole, Brown-Conrady, the full OpenCV model and the OpenCV fisheye.

Conventions
-----------
- **Pixels** ``(col, row)``: columns right, rows down, the top-left pixel's centre at
  ``(0.5, 0.5)`` (the product's convention). OpenCV puts that centre at ``(0, 0)``: an OpenCV
  pixel is the product's minus 0.5 (the principal point likewise).
- **Camera frame** (OpenCV's and OpenSfM's): x right, y down, z forward along the optical axis.
  *Normalised* coordinates are ``(x/z, y/z)`` of a point in front of the camera (z > 0).
- Perspective models (Brown, OpenCV; OpenCV's ``projectPoints``)::

      r2 = x² + y²
      x' = x·(1 + k1·r2 + k2·r2² + k3·r2³)/(1 + k4·r2 + k5·r2² + k6·r2³)
           + 2·p1·x·y + p2·(r2 + 2x²) + s1·r2 + s2·r2²
      y' = y·(same ratio) + p1·(r2 + 2y²) + 2·p2·x·y + s3·r2 + s4·r2²
      col = fx·x' + cx,  row = fy·y' + cy

- Fisheye (OpenCV's ``cv2.fisheye``, OpenSfM's ``fisheye_opencv``): ``θ`` the angle between the
  ray and the optical axis, ``θd = θ·(1 + k1·θ² + k2·θ⁴ + k3·θ⁶ + k4·θ⁸)``, then
  ``x' = θd·x/ρ``, ``y' = θd·y/ρ`` (``ρ = √(x² + y²)`` of the ray), pixels as above. Rays past
  90° have an image too.

Validity and inversion
----------------------
A distortion polynomial is a model of the lens only over its field: past the first radius where
it stops increasing it folds back and would put points from outside the field inside the image.
Each model finds that limit once (``valid_radius``: normalised radius, or ``θ`` for the fisheye)
and projects nothing beyond it (NaN). Pixels -> rays invert the distortion by Newton's method
(perspective: 2-D with the analytic Jacobian; fisheye: 1-D in θ) and check the result: a pixel
whose re-projection misses it by more than ``tolerance_px`` (default 0.001 px) or that falls
outside the valid field comes back NaN, and is counted, never returned wrong.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

#: largest re-projection error (pixels) of an accepted undistorted point
DEFAULT_TOLERANCE_PX = 1e-3
_NEWTON_ITERATIONS = 30

PERSPECTIVE_TERMS = {
    "pinhole": (),
    "brown": ("k1", "k2", "k3", "p1", "p2"),
    "opencv": ("k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2", "s1", "s2", "s3", "s4"),
}
FISHEYE_TERMS = ("k1", "k2", "k3", "k4")
#: film-camera attributes a model camera lacks (asking for one is a one-line InputDataError)
FILM_ONLY = frozenset({"c", "principal_distance_mm", "fiducials_mm", "pixel_size_mm",
                       "frame_size_mm", "distortion", "image_to_camera", "camera_to_image",
                       "frame_outline_mm"})


@dataclass(frozen=True, eq=False)
class Intrinsics:
    """An interior camera model (see the module docstring). Build with
    :func:`toolbox.cameras.create_intrinsics` from a camera spec.

    Attributes
    ----------
    kind : str
        ``pinhole``, ``brown``, ``opencv`` or ``fisheye``.
    image_size_px : (int, int)
        ``(width, height)`` in pixels.
    focal_px : (float, float)
        ``(fx, fy)``, pixels.
    principal_point_px : (float, float)
        ``(cx, cy)`` in the product's pixel convention (top-left pixel centre at 0.5).
    coefficients : dict
        The distortion terms of the kind (missing ones are 0).
    name : str
    spec : dict
        The camera spec it was built from (Orthority's interior schema), for writing back.
    """

    kind: str
    image_size_px: tuple[int, int]
    focal_px: tuple[float, float]
    principal_point_px: tuple[float, float]
    coefficients: dict[str, float] = field(default_factory=dict)
    name: str = ""
    spec: dict[str, Any] = field(default_factory=dict)
    tolerance_px: float = DEFAULT_TOLERANCE_PX

    def __post_init__(self) -> None:
        terms = FISHEYE_TERMS if self.kind == "fisheye" else PERSPECTIVE_TERMS.get(self.kind)
        if terms is None:
            raise InputDataError(f"camera {self.name!r}: unknown model type {self.kind!r}; "
                                 f"expected one of pinhole, brown, opencv, fisheye")
        w, h = self.image_size_px
        if not (int(w) > 0 and int(h) > 0):
            raise InputDataError(f"camera {self.name!r}: im_size must be two sizes > 0 px, got "
                                 f"{self.image_size_px!r}")
        fx, fy = self.focal_px
        if not (math.isfinite(fx) and math.isfinite(fy) and fx > 0 and fy > 0):
            raise InputDataError(f"camera {self.name!r}: the focal length must be > 0, got "
                                 f"{self.focal_px!r} px")
        px, py = self.principal_point_px
        if not (0.0 <= px <= w and 0.0 <= py <= h):  # cx, cy in pixels or mm, not normalised
            given = ", ".join(f"{k} = {self.spec[k]!r}" for k in ("cx", "cy") if k in self.spec)
            raise InputDataError(
                f"camera {self.name!r}: the principal point ({px:.6g}, {py:.6g}) px lies off the "
                f"{w} x {h} px image" + (f" ({given})" if given else "") + ": cx, cy are "
                "offsets from the image centre normalised by max(width, height) (Orthority's "
                "and OpenSfM's convention), not pixels or mm")
        extra = set(self.coefficients) - set(terms)
        if extra:
            raise InputDataError(f"camera {self.name!r}: a {self.kind} camera has no "
                                 f"{', '.join(sorted(extra))} (terms: {', '.join(terms) or 'none'})")
        values = {k: float(self.coefficients.get(k, 0.0)) for k in terms}
        if not all(math.isfinite(v) for v in values.values()):
            raise InputDataError(f"camera {self.name!r}: distortion terms must be finite, got "
                                 f"{values}")
        object.__setattr__(self, "coefficients", values)
        object.__setattr__(self, "_valid", self._valid_limit())
        reach, corner = self._reach(), self.corner_radius()
        if self.kind != "fisheye" and not corner <= reach:  # a fisheye's corners may be dark
            raise InputDataError(
                f"camera {self.name!r}: its distortion folds back inside the image (the model "
                f"reaches normalised radius {reach:.4g} at most, the image corners lie at "
                f"{corner:.4g}): the parameters do not fit the image size {w} x {h} px")

    def __getattr__(self, name: str) -> Any:
        """The film camera's attributes (principal distance in mm, fiducials...) do not exist
        here: a step written for film cameras that asks for one stops with a one-line error
        instead of an internal one."""
        if name in FILM_ONLY:
            raise InputDataError(f"camera {self.name!r} is a {self.kind} model without {name}: "
                                 "this step handles film cameras only")
        raise AttributeError(name)

    # -- plain views ----------------------------------------------------------------------------
    @property
    def valid_radius(self) -> float:
        """Largest normalised radius (perspective) or ray angle θ (fisheye, radians) whose
        projection is kept."""
        return self._valid

    @property
    def principal_point_mm(self) -> tuple[float, float]:
        """The principal point in the *image coordinates* of a photo with this camera, which
        for a model camera are ideal normalised coordinates (x right, y up): always (0, 0)."""
        return (0.0, 0.0)

    def matrix(self, opencv: bool = True) -> np.ndarray:
        """The 3 x 3 camera matrix K; ``opencv``: principal point in OpenCV's pixel convention
        (the product's minus 0.5)."""
        shift = 0.5 if opencv else 0.0
        (fx, fy), (cx, cy) = self.focal_px, self.principal_point_px
        return np.array([[fx, 0.0, cx - shift], [0.0, fy, cy - shift], [0.0, 0.0, 1.0]])

    def opencv_coefficients(self) -> np.ndarray:
        """The distortion vector in OpenCV's order: ``(k1, k2, p1, p2, k3, k4, k5, k6, s1, s2,
        s3, s4)`` (perspective) or ``(k1, k2, k3, k4)`` (fisheye)."""
        c = self.coefficients
        order = FISHEYE_TERMS if self.kind == "fisheye" else \
            ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4")
        return np.array([c.get(k, 0.0) for k in order])

    def as_dict(self) -> dict[str, Any]:
        """``{"name": ..., "model": spec}`` for a project YAML."""
        return {"name": self.name, "model": dict(self.spec)}

    # -- the model --------------------------------------------------------------------------------
    def _radial_ratio(self, r2: np.ndarray) -> np.ndarray:
        """Perspective: the radial factor at squared normalised radius ``r2``."""
        c = self.coefficients
        ratio = 1.0 + r2 * (c["k1"] + r2 * (c["k2"] + r2 * c["k3"]))
        if self.kind == "opencv":
            ratio = ratio / (1.0 + r2 * (c["k4"] + r2 * (c["k5"] + r2 * c["k6"])))
        return ratio

    def _distort(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Perspective: normalised ideal -> distorted normalised coordinates."""
        c = self.coefficients
        if self.kind == "pinhole":
            return x, y
        r2 = x * x + y * y
        ratio = self._radial_ratio(r2)
        xy = x * y
        xd = x * ratio + 2.0 * c["p1"] * xy + c["p2"] * (r2 + 2.0 * x * x)
        yd = y * ratio + c["p1"] * (r2 + 2.0 * y * y) + 2.0 * c["p2"] * xy
        if self.kind == "opencv":
            xd = xd + r2 * (c["s1"] + r2 * c["s2"])
            yd = yd + r2 * (c["s3"] + r2 * c["s4"])
        return xd, yd

    def _jacobian(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """Perspective: d(xd, yd)/d(x, y) analytically, as (a, b, c, d) = (dxd/dx, dxd/dy,
        dyd/dx, dyd/dy)."""
        c = self.coefficients
        r2 = x * x + y * y
        num = 1.0 + r2 * (c["k1"] + r2 * (c["k2"] + r2 * c["k3"]))
        dnum = c["k1"] + r2 * (2.0 * c["k2"] + 3.0 * r2 * c["k3"])  # d num / d r2
        den, dden = np.ones_like(r2), np.zeros_like(r2)
        if self.kind == "opencv":
            den = 1.0 + r2 * (c["k4"] + r2 * (c["k5"] + r2 * c["k6"]))
            dden = c["k4"] + r2 * (2.0 * c["k5"] + 3.0 * r2 * c["k6"])
        ratio = num / den
        dratio = (dnum * den - num * dden) / (den * den)  # d ratio / d r2 (dr2/dx = 2x)
        p1, p2 = c["p1"], c["p2"]
        a = ratio + 2 * x * x * dratio + 2 * p1 * y + 6 * p2 * x
        b = 2 * x * y * dratio + 2 * p1 * x + 2 * p2 * y
        cc = 2 * x * y * dratio + 2 * p1 * x + 2 * p2 * y
        d = ratio + 2 * y * y * dratio + 6 * p1 * y + 2 * p2 * x
        if self.kind == "opencv":
            ds1 = c["s1"] + 2 * r2 * c["s2"]
            ds3 = c["s3"] + 2 * r2 * c["s4"]
            a, b = a + 2 * x * ds1, b + 2 * y * ds1
            cc, d = cc + 2 * x * ds3, d + 2 * y * ds3
        return a, b, cc, d

    def _theta_d(self, theta: np.ndarray) -> np.ndarray:
        c = self.coefficients
        t2 = theta * theta
        return theta * (1.0 + t2 * (c["k1"] + t2 * (c["k2"] + t2 * (c["k3"] + t2 * c["k4"]))))

    def _theta_d_slope(self, theta: np.ndarray) -> np.ndarray:
        c = self.coefficients
        t2 = theta * theta
        return 1.0 + t2 * (3 * c["k1"] + t2 * (5 * c["k2"] + t2 * (7 * c["k3"] + 9 * t2 * c["k4"])))

    def _valid_limit(self) -> float:
        """The first radius (θ for the fisheye) where the radial mapping stops increasing,
        searched on a fine grid (fisheye up to π, perspective up to radius 20, about 87°)."""
        if self.kind == "pinhole":
            return math.inf
        if self.kind == "fisheye":
            t = np.linspace(0.0, math.pi, 20001)
            bad = np.flatnonzero(self._theta_d_slope(t) <= 0)
            return float(t[bad[0] - 1]) if len(bad) else math.pi
        r = np.linspace(0.0, 20.0, 40001)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            radial = r * self._radial_ratio(r * r)
        bad = np.flatnonzero((np.diff(radial) <= 0) | ~np.isfinite(radial[1:]))
        return float(r[bad[0]]) if len(bad) else math.inf

    def _reach(self) -> float:
        """The largest distorted radius (θd for the fisheye) of the valid field."""
        if not math.isfinite(self._valid):
            return math.inf
        if self.kind == "fisheye":
            return float(self._theta_d(np.array(self._valid)))
        return float(self._valid * self._radial_ratio(np.array(self._valid ** 2)))

    def corner_radius(self) -> float:
        """The largest distorted normalised radius of the image corners."""
        w, h = self.image_size_px
        (fx, fy), (cx, cy) = self.focal_px, self.principal_point_px
        x = (np.array([0.0, w, w, 0.0]) - cx) / fx
        y = (np.array([0.0, 0.0, h, h]) - cy) / fy
        return float(np.hypot(x, y).max())

    # -- camera frame <-> pixels ----------------------------------------------------------------
    def camera_to_pixel(self, xyz: np.ndarray) -> np.ndarray:
        """Points or ray directions in the camera frame (N, 3) -> pixels (N, 2); NaN for points
        that have no image (behind a perspective camera, outside the model's valid field)."""
        xyz = np.asarray(xyz, dtype="float64").reshape(-1, 3)
        x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.kind == "fisheye":
                rho = np.hypot(x, y)
                theta = np.arctan2(rho, z)
                td = self._theta_d(theta)
                scale = np.where(rho > 0, td / np.where(rho > 0, rho, 1.0), 1.0)
                xd, yd = x * scale, y * scale
                ok = theta <= self._valid
            else:
                xn, yn = x / z, y / z
                ok = (z > 0) & (np.hypot(xn, yn) <= self._valid)
                xd, yd = self._distort(xn, yn)
        (fx, fy), (cx, cy) = self.focal_px, self.principal_point_px
        out = np.column_stack([fx * xd + cx, fy * yd + cy])
        out[~ok] = np.nan
        return out

    def pixel_to_camera(self, pixels: np.ndarray) -> tuple[np.ndarray, int]:
        """Pixels (N, 2) -> unit ray directions in the camera frame (N, 3) and the number of
        pixels that did not converge or lie outside the valid field (their rays are NaN)."""
        px = np.asarray(pixels, dtype="float64").reshape(-1, 2)
        (fx, fy), (cx, cy) = self.focal_px, self.principal_point_px
        xd, yd = (px[:, 0] - cx) / fx, (px[:, 1] - cy) / fy
        given = np.isfinite(xd) & np.isfinite(yd)
        if self.kind == "fisheye":
            rays, ok = self._fisheye_rays(xd, yd)
        else:
            x, y, ok = self._undistort(xd, yd)
            rays = np.column_stack([x, y, np.ones_like(x)])
            rays /= np.linalg.norm(rays, axis=1)[:, None]
        ok &= given
        rays[~ok] = np.nan
        return rays, int(np.count_nonzero(~ok & given))

    def _undistort(self, xd: np.ndarray, yd: np.ndarray):
        """Newton's method on the perspective distortion; (x, y, converged)."""
        x, y = xd.copy(), yd.copy()
        if self.kind == "pinhole":
            return x, y, np.ones(len(x), dtype=bool)
        fx, fy = self.focal_px
        scale = np.array([fx, fy])
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for _ in range(_NEWTON_ITERATIONS):
                ex, ey = self._distort(x, y)
                ex, ey = ex - xd, ey - yd
                if not np.nanmax(np.abs(ex) * scale[0] + np.abs(ey) * scale[1], initial=0.0) \
                        > 1e-4 * self.tolerance_px:
                    break
                a, b, c, d = self._jacobian(x, y)
                det = a * d - b * c
                x = x - (d * ex - b * ey) / det
                y = y - (a * ey - c * ex) / det
            ex, ey = self._distort(x, y)
            error = np.hypot((ex - xd) * fx, (ey - yd) * fy)
            ok = (error <= self.tolerance_px) & (np.hypot(x, y) <= self._valid)
        return x, y, ok

    def _fisheye_rays(self, xd: np.ndarray, yd: np.ndarray):
        """1-D Newton on θd(θ); (unit rays, converged)."""
        td = np.hypot(xd, yd)
        theta = np.minimum(td, self._valid)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for _ in range(_NEWTON_ITERATIONS):
                step = (self._theta_d(theta) - td) / self._theta_d_slope(theta)
                theta = np.clip(theta - step, 0.0, self._valid)
                if not np.nanmax(np.abs(step), initial=0.0) * max(self.focal_px) \
                        > 1e-4 * self.tolerance_px:
                    break
            error = np.abs(self._theta_d(theta) - td) * max(self.focal_px)
            ok = error <= self.tolerance_px
            s = np.where(td > 0, np.sin(theta) / np.where(td > 0, td, 1.0), 0.0)
        rays = np.column_stack([xd * s, yd * s, np.cos(theta)])
        return rays, ok

    # -- normalised coordinates (the photo's "image" coordinates) ------------------------------
    def pixel_to_normalised(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> ideal normalised coordinates (x right, y *up*, i.e. the
        photogrammetric image frame with c = 1: the ray is ``(x, y, -1)``); NaN where the
        pixel does not converge or its ray is not in front of the camera."""
        rays, _ = self.pixel_to_camera(pixels)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.where(rays[:, 2] > 0, rays[:, 2], np.nan)
            return np.column_stack([rays[:, 0] / z, -rays[:, 1] / z])

    def normalised_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`pixel_to_normalised`."""
        xy = np.asarray(xy, dtype="float64").reshape(-1, 2)
        return self.camera_to_pixel(np.column_stack([xy[:, 0], -xy[:, 1], np.ones(len(xy))]))


def as_pair(value: Any, what: str, where: str) -> tuple[float, float]:
    """Two floats from a number (repeated) or a pair; InputDataError naming ``what``."""
    try:
        values = [float(v) for v in (value if isinstance(value, (list, tuple)) else [value])]
    except (TypeError, ValueError):
        values = []
    if len(values) == 1:
        values = values * 2
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise InputDataError(f"{where}: {what} must be one or two numbers, got {value!r}")
    return values[0], values[1]


def coefficients_from(spec: Mapping[str, Any], terms: tuple[str, ...], where: str
                      ) -> dict[str, float]:
    out = {}
    for k in terms:
        if k in spec and spec[k] is not None:
            try:
                out[k] = float(spec[k])
            except (TypeError, ValueError):
                raise InputDataError(f"{where}: {k} must be a number, got {spec[k]!r}") from None
    return out
