"""Vectorised collinearity: ground -> image, image -> ground on a height, monoplotting on a DEM.

Formulas (domain brief section 4; S000 l.401-446, S002 eq. [26])::

    ξ = ξ0 - c·[r11(X-X0) + r21(Y-Y0) + r31(Z-Z0)] / [r13(X-X0) + r23(Y-Y0) + r33(Z-Z0)]
    η = η0 - c·[r12(X-X0) + r22(Y-Y0) + r32(Z-Z0)] / [r13(X-X0) + r23(Y-Y0) + r33(Z-Z0)]

    X = X0 + (Z-Z0)·[r11(ξ-ξ0) + r12(η-η0) - r13·c] / [r31(ξ-ξ0) + r32(η-η0) - r33·c]
    Y = Y0 + (Z-Z0)·[r21(ξ-ξ0) + r22(η-η0) - r23·c] / [r31(ξ-ξ0) + r32(η-η0) - r33·c]

with radial distortion applied between ideal and measured image coordinates (see
:mod:`toolbox.photogrammetry.camera`) and, optionally, a plane projective matrix between image mm
and pixels (the interior orientation, :mod:`toolbox.photogrammetry.fiducials`), all fused in one
compiled pass (:mod:`toolbox.photogrammetry.kernels`; numba, parallel, fastmath off).

These functions take plain arrays and numbers; :class:`toolbox.photogrammetry.photo.Photo` wraps
them with a camera, an exterior and an interior orientation. Points are ``(N, 3)`` / ``(N, 2)``
arrays, or *tuples* of coordinate arrays of any (broadcastable) shape; the result has the point
set's shape plus a last axis of 2 or 3.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from toolbox.errors import ConvergenceError, InputDataError, ParameterError
from toolbox.photogrammetry.camera import RadialDistortion
from toolbox.photogrammetry.status import StatusCodes

#: monoplot status codes (``MonoplotResult.status``)
OK, OUTSIDE, NODATA, NOT_CONVERGED, RAY_UPWARD, NO_INTERSECTION = 0, 1, 2, 3, 4, 5
STATUS_NAMES = {OK: "ok", OUTSIDE: "outside_dem", NODATA: "dem_nodata",
                NOT_CONVERGED: "not_converged", RAY_UPWARD: "ray_not_descending",
                NO_INTERSECTION: "no_intersection"}
METHODS = {"march": 0, "fixed_point": 1}
_IDENTITY = np.eye(3)


NUMPY_POINTS = 1 << 16  # up to this many distortion-free points: NumPy (no numba start-up)


def _kernels(points: int | None = None, dmode: int = 1, method: int = 0):
    """The compiled kernels; their NumPy versions for a small distortion-free point set (a
    footprint: a few hundred rays, where numba's start-up would cost far more)."""
    from toolbox.photogrammetry import kernels_numpy

    if points is not None and points <= NUMPY_POINTS and kernels_numpy.supports(dmode, method):
        return kernels_numpy
    from toolbox.photogrammetry import kernels

    return kernels


def _components(points, ncoords: int, name: str) -> tuple[list[np.ndarray], tuple[int, ...]]:
    """Flat contiguous float64 coordinate arrays and the shape of the point set.

    A *tuple* of ``ncoords`` arrays is taken as separate coordinates (broadcast together);
    anything else as an array whose last axis holds the ``ncoords`` coordinates.
    """
    if isinstance(points, tuple) and len(points) == ncoords:
        arrays = np.broadcast_arrays(*(np.asarray(p, dtype="float64") for p in points))
        return [np.ascontiguousarray(a.ravel()) for a in arrays], arrays[0].shape
    arr = np.asarray(points, dtype="float64")
    if arr.shape[-1:] != (ncoords,):
        raise InputDataError(f"{name} must be an (N, {ncoords}) array or a tuple of {ncoords} "
                             f"coordinate arrays, got shape {arr.shape}")
    flat = arr.reshape(-1, ncoords)
    return [np.ascontiguousarray(flat[:, k]) for k in range(ncoords)], arr.shape[:-1]


def _distortion_args(distortion: RadialDistortion | None):
    if distortion is None:
        return (0, np.zeros(2), np.zeros(2), np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
                np.zeros(1, dtype=np.int64))
    return distortion.kernel_arguments()


def _model(centre, rotation, principal_distance, principal_point):
    centre = np.ascontiguousarray(centre, dtype="float64").ravel()
    rot = np.ascontiguousarray(rotation, dtype="float64")
    pp = np.ascontiguousarray(principal_point, dtype="float64").ravel()
    if centre.shape != (3,) or rot.shape != (3, 3) or pp.shape != (2,):
        raise InputDataError("centre must have 3 values, rotation 3 x 3, principal point 2")
    if not principal_distance > 0:
        raise InputDataError(f"principal distance must be > 0 mm, got {principal_distance!r}")
    return centre, rot, float(principal_distance), pp


def _matrix(matrix) -> np.ndarray:
    return _IDENTITY if matrix is None else np.ascontiguousarray(matrix, dtype="float64")


def ground_to_image(points, centre, rotation, principal_distance: float,
                    principal_point=(0.0, 0.0), distortion: RadialDistortion | None = None,
                    fiducial_to_pixel=None, behind: str = "raise", out: np.ndarray | None = None
                    ) -> np.ndarray:
    """Project ground points into the image.

    Parameters
    ----------
    points : (..., 3) array or (X, Y, Z) arrays
        Ground coordinates (CRS units).
    centre, rotation : projection centre (3,) and ``R(omega, phi, kappa)`` (3, 3)
    principal_distance : float, mm
    principal_point : (ξ0, η0), mm
    distortion : RadialDistortion, optional
        Added to the ideal image coordinates (measured = distorted).
    fiducial_to_pixel : (3, 3) array, optional
        When given, the result is in pixels ``(col, row)``; otherwise image mm ``(x, y)``.
    behind : {"raise", "nan"}
        Points on or behind the plane of the projection centre have no image: raise
        :class:`InputDataError` (default) or return NaN for them (the caller masks them).
    out : (N, 2) float64 array, optional
        Written in place (contiguous) to avoid an allocation in tiled loops.

    Returns
    -------
    (..., 2) array
    """
    if behind not in ("raise", "nan"):
        raise ParameterError("behind", f"must be 'raise' or 'nan', got {behind!r}")
    (x, y, z), shape = _components(points, 3, "ground points")
    centre, rot, c, pp = _model(centre, rotation, principal_distance, principal_point)
    result = np.empty((len(x), 2)) if out is None else out
    if result.shape != (len(x), 2) or not result.flags.c_contiguous or result.dtype != np.float64:
        raise InputDataError(f"out must be a contiguous float64 ({len(x)}, 2) array")
    count = _kernels().ground_to_image(x, y, z, centre, rot, c, pp, *_distortion_args(distortion),
                                       _matrix(fiducial_to_pixel), result)
    if count and behind == "raise":
        _refuse(result, f"{count} ground point(s) lie on or behind the plane of the projection "
                "centre and have no image")
    return result.reshape(shape + (2,))


def image_to_ground(points, z, centre, rotation, principal_distance: float,
                    principal_point=(0.0, 0.0), distortion: RadialDistortion | None = None,
                    pixel_to_fiducial=None, invalid: str = "raise") -> np.ndarray:
    """Intersect image rays with horizontal planes ``Z = z``.

    Parameters
    ----------
    points : (..., 2) array or (u, v) arrays
        Image mm ``(x, y)``, or pixels ``(col, row)`` when ``pixel_to_fiducial`` is given.
    z : float or array broadcastable to the points' shape
        Ground height(s) of the plane(s).
    invalid : {"raise", "nan"}
        Rays parallel to the plane or meeting it behind the camera: raise
        :class:`InputDataError` (default) or NaN.

    Returns
    -------
    (..., 3) array X, Y, Z
    """
    if invalid not in ("raise", "nan"):
        raise ParameterError("invalid", f"must be 'raise' or 'nan', got {invalid!r}")
    (u, v), shape = _components(points, 2, "image points")
    zz = np.asarray(z, dtype="float64")
    heights = np.ascontiguousarray(zz.ravel()) if zz.size == 1 else \
        np.ascontiguousarray(np.broadcast_to(zz, shape).ravel())
    centre, rot, c, pp = _model(centre, rotation, principal_distance, principal_point)
    xyz = np.empty((len(u), 3))
    args = _distortion_args(distortion)
    count = _kernels(len(u), args[0]).image_to_ground_at_z(u, v, heights, centre, rot, c, pp,
                                                           *args, _matrix(pixel_to_fiducial),
                                                           xyz)
    if count and invalid == "raise":
        _refuse(xyz, f"{count} image ray(s) do not meet the height plane in front of the camera")
    return xyz.reshape(shape + (3,))


def _refuse(result: np.ndarray, message: str) -> None:
    """InputDataError ``message`` naming the first NaN row of ``result``."""
    first = int(np.flatnonzero(np.isnan(result[:, 0]))[0])
    raise InputDataError(f"{message} (first: index {first})")


@dataclass
class MonoplotResult(StatusCodes):
    """Ray/DEM intersections: ``xyz`` (…, 3; NaN where failed), ``status`` (…; int8 codes of
    :data:`STATUS_NAMES`) and ``iterations`` (…; refinement or fixed-point iterations)."""

    STATUS: ClassVar[dict[int, str]] = STATUS_NAMES
    xyz: np.ndarray
    status: np.ndarray
    iterations: np.ndarray

    def raise_on_failure(self, what: str = "rays") -> MonoplotResult:
        """Raise (ConvergenceError for non-convergence, InputDataError otherwise) if any failed."""
        failed = np.flatnonzero(self.status.ravel() != OK)
        if len(failed):
            first = int(failed[0])
            code = int(self.status.ravel()[first])
            summary = ", ".join(f"{k}: {n}" for k, n in self.counts().items() if k != "ok")
            cls = ConvergenceError if code == NOT_CONVERGED else InputDataError
            raise cls(f"{len(failed)} of {self.status.size} {what} did not meet the DEM "
                      f"({summary}; first: index {first}, {STATUS_NAMES[code]})")
        return self


def monoplot(points, surface, centre, rotation, principal_distance: float,
             principal_point=(0.0, 0.0), distortion: RadialDistortion | None = None,
             pixel_to_fiducial=None, method: str = "march", tolerance: float = 1e-10,
             max_iterations: int = 100, z_start: float | None = None) -> MonoplotResult:
    """Intersect image rays with a DEM (monoplotting).

    Parameters
    ----------
    points : (..., 2) array or (u, v) arrays
        Image mm, or pixels when ``pixel_to_fiducial`` is given.
    surface : :class:`~toolbox.photogrammetry.surface.DemSurface`
        Heights, bilinear between cell centres.
    method : {"march", "fixed_point"}
        ``march`` (default) walks down each ray from the DEM's top in half-cell steps and refines
        the first crossing (Illinois regula falsi): it returns the first visible surface point and
        converges on steep terrain. A ray rising from a camera below the DEM's top (a valley
        flight, an oblique view up a slope) is walked up from the camera; ``ray_not_descending``
        is then a ray that rises over every height of the DEM (the sky). A camera beside the
        DEM starts where the ray comes over its extent. ``fixed_point`` is the classical
        ``Z <- DEM(X(Z), Y(Z))`` iteration from ``z_start`` (default: mean DEM height); it fails
        (``not_converged``) where the terrain is steeper than the ray.
    tolerance : float
        Height misclosure ``|Z_ray - Z_dem|`` accepted (CRS units).

    Returns
    -------
    MonoplotResult
        Failed rays are flagged in ``status`` (never a silent NaN); call
        :meth:`MonoplotResult.raise_on_failure` to turn them into an error.
    """
    if method not in METHODS:
        raise ParameterError("METHOD", f"must be one of {', '.join(METHODS)}; got {method!r}")
    if not tolerance > 0 or max_iterations < 1:
        raise ParameterError("TOLERANCE", f"must be > 0 (with max_iterations >= 1), got "
                             f"{tolerance!r}")
    (u, v), shape = _components(points, 2, "image points")
    centre, rot, c, pp = _model(centre, rotation, principal_distance, principal_point)
    dem, gx0, gy0, cx, cy, zmin, zmax = surface.kernel_arguments()
    start = float(np.nanmean(dem)) if z_start is None else float(z_start)
    n = len(u)
    xyz = np.empty((n, 3))
    status = np.empty(n, dtype=np.int8)
    iterations = np.empty(n, dtype=np.int32)
    args = _distortion_args(distortion)
    _kernels(n, args[0], METHODS[method]).monoplot(
        u, v, centre, rot, c, pp, *args, _matrix(pixel_to_fiducial), dem, gx0, gy0, cx, cy,
        zmin, zmax, METHODS[method], start, float(tolerance), int(max_iterations), xyz, status,
        iterations)
    return MonoplotResult(xyz.reshape(shape + (3,)), status.reshape(shape),
                          iterations.reshape(shape))
