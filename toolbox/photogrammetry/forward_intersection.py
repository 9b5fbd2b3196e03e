"""Space (forward) intersection: 3D points from homologous image points on >= 2 oriented photos.

Method (domain brief section 8, with its Impl. note): instead of the thesis' closed form [29],
which uses only the X equations and breaks down for a base along Y, every point is solved by
least squares from all its collinearity equations (2 per photo):

1. start: the point closest to all rays, ``Σ (I - dᵢdᵢᵀ)·(P - Cᵢ) = 0`` (``dᵢ`` unit ray
   directions ``R·(x̄, ȳ, -c)``, ``Cᵢ`` projection centres), solved on coordinates shifted to a
   local origin;
2. Gauss-Newton on the image residuals ``v = x̄_obs - x̄(P)`` of the collinearity equations
   (section 4), to ``|ΔP| < 1e-9`` m.

Statistics per point: redundancy ``r = 2n - 3``, ``sigma0 = sqrt(Σv²/r)`` (mm, image),
standard deviations ``σX, σY, σZ = sigma0·sqrt(diag(N⁻¹))`` (ground units) when ``r > 0``, and
the largest distance from the point to its rays (ground units; for two photos it measures the
y-parallax left by the orientation).

Observations are *camera* coordinates (reduced to the principal point, distortion-corrected, mm);
:func:`camera_observations` makes them from measured image mm or pixels of oriented photos.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from toolbox.errors import InputDataError
from toolbox.photogrammetry.status import StatusCodes

OK, SINGLE_RAY, PARALLEL_RAYS, BEHIND_CAMERA, NOT_CONVERGED = 0, 1, 2, 3, 4
STATUS_NAMES = {OK: "ok", SINGLE_RAY: "single_ray", PARALLEL_RAYS: "parallel_rays",
                BEHIND_CAMERA: "behind_camera", NOT_CONVERGED: "not_converged"}
CONDITION_LIMIT = 1e10


@dataclass
class IntersectionResult(StatusCodes):
    """Per point: ``xyz`` (P, 3; NaN unless status ok), ``status`` (P,), ``n_rays`` (P,),
    ``sigma0_mm`` (P,; NaN when r = 0), ``std_xyz`` (P, 3), ``max_ray_distance`` (P,),
    ``iterations`` (P,). Per observation: ``residuals_mm`` (M, 2) = computed - observed (the
    toolbox convention: the correction v of l + v = f(x))."""

    STATUS: ClassVar[dict[int, str]] = STATUS_NAMES
    xyz: np.ndarray
    status: np.ndarray
    n_rays: np.ndarray
    sigma0_mm: np.ndarray
    std_xyz: np.ndarray
    max_ray_distance: np.ndarray
    iterations: np.ndarray
    residuals_mm: np.ndarray


def _project(points: np.ndarray, centres: np.ndarray, rotations: np.ndarray, c: np.ndarray):
    """Camera coordinates of ``points`` (M, 3) on the photos of each observation, with the
    rotated vector ``u = Rᵀ(P - C)`` (M, 3)."""
    u = np.einsum("mji,mj->mi", rotations, points - centres)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = -c[:, None] * u[:, :2] / u[:, 2:3]
    return xy, u


def _solve_each(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x`` with ``a[k] @ x[k] = b[k]`` for a stack of 3x3 systems, and which were solvable
    (finite and not singular: a singular one gives NaN instead of stopping the others)."""
    x = np.full(b.shape, np.nan)
    ok = np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=1)
    try:
        x[ok] = np.linalg.solve(a[ok], b[ok][..., None])[..., 0]
    except np.linalg.LinAlgError:  # one at least is singular: solve them one by one
        for k in np.flatnonzero(ok):
            try:
                x[k] = np.linalg.solve(a[k], b[k])
            except np.linalg.LinAlgError:
                ok[k] = False
    ok &= np.isfinite(x).all(axis=1)
    return x, ok


def intersect(point_index: np.ndarray, camera_xy: np.ndarray, centres: np.ndarray,
              rotations: np.ndarray, principal_distances: np.ndarray, n_points: int | None = None,
              max_iterations: int = 20, tolerance: float = 1e-9) -> IntersectionResult:
    """Least-squares forward intersection.

    Parameters
    ----------
    point_index : (M,) int
        Point of each observation, 0 .. P-1.
    camera_xy : (M, 2) float
        Camera coordinates (mm) of each observation.
    centres : (M, 3) float
        Projection centre of the observation's photo (ground units).
    rotations : (M, 3, 3) float
        ``R(omega, phi, kappa)`` of the observation's photo.
    principal_distances : (M,) float
        ``c`` (mm) of the observation's camera.
    """
    point_index = np.asarray(point_index, dtype=np.int64)
    obs = np.asarray(camera_xy, dtype="float64")
    centres = np.asarray(centres, dtype="float64")
    rotations = np.asarray(rotations, dtype="float64")
    c = np.asarray(principal_distances, dtype="float64")
    m = len(point_index)
    p = int(point_index.max()) + 1 if n_points is None and m else int(n_points or 0)
    origin = np.round(centres.mean(axis=0)) if m else np.zeros(3)
    local_c = centres - origin
    n_rays = np.bincount(point_index, minlength=p)
    status = np.full(p, OK, dtype=np.int8)
    status[n_rays < 2] = SINGLE_RAY

    # 1. closest point to the rays
    rays = np.einsum("mij,mj->mi", rotations,
                     np.column_stack([obs, -c]))
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    proj = np.eye(3)[None] - rays[:, :, None] * rays[:, None, :]
    a = np.zeros((p, 3, 3))
    b = np.zeros((p, 3))
    np.add.at(a, point_index, proj)
    np.add.at(b, point_index, np.einsum("mij,mj->mi", proj, local_c))
    good = status == OK
    cond = np.full(p, np.inf)
    if good.any():
        cond[good] = np.linalg.cond(a[good])
    status[good & ~(cond < CONDITION_LIMIT)] = PARALLEL_RAYS
    good = status == OK
    xyz = np.full((p, 3), np.nan)
    if good.any():
        xyz[good], solved = _solve_each(a[good], b[good])
        status[np.flatnonzero(good)[~solved]] = PARALLEL_RAYS
        good = status == OK

    # 2. Gauss-Newton on the image residuals
    iterations = np.zeros(p, dtype=np.int32)
    active = good.copy()
    normal = np.zeros((p, 3, 3))
    for _ in range(max_iterations):
        if not active.any():
            break
        sel = active[point_index]
        idx = point_index[sel]
        xy, u = _project(xyz[idx], local_c[sel], rotations[sel], c[sel])
        v = obs[sel] - xy
        r = rotations[sel]
        cc = c[sel][:, None]
        u3 = u[:, 2:3]
        jx = -cc * (u3 * r[:, :, 0] - u[:, 0:1] * r[:, :, 2]) / u3 ** 2
        jy = -cc * (u3 * r[:, :, 1] - u[:, 1:2] * r[:, :, 2]) / u3 ** 2
        n_mat = np.zeros((p, 3, 3))
        g = np.zeros((p, 3))
        np.add.at(n_mat, idx, jx[:, :, None] * jx[:, None, :] + jy[:, :, None] * jy[:, None, :])
        np.add.at(g, idx, jx * v[:, 0:1] + jy * v[:, 1:2])
        act = np.flatnonzero(active)
        step, solved = _solve_each(n_mat[act], g[act])
        if not solved.all():  # a singular normal matrix: the rays do not fix the point
            status[act[~solved]] = PARALLEL_RAYS
            active[act[~solved]] = False
            xyz[act[~solved]] = np.nan
            act, step = act[solved], step[solved]
        xyz[act] += step
        normal[act] = n_mat[act]
        iterations[act] += 1
        done = np.abs(step).max(axis=1) < tolerance
        active[act[done]] = False
    status[active] = NOT_CONVERGED
    status[(status == OK) & ~np.isfinite(xyz).all(axis=1)] = PARALLEL_RAYS

    # statistics on the final point
    ok_obs = (status == OK)[point_index]
    residuals = np.full((m, 2), np.nan)
    xy, u = _project(xyz[point_index], local_c, rotations, c)
    residuals[ok_obs] = (xy - obs)[ok_obs]
    behind = np.zeros(p, dtype=bool)
    np.logical_or.at(behind, point_index, ~(u[:, 2] < 0))
    status[(status == OK) & behind] = BEHIND_CAMERA
    ok = status == OK
    sq = np.bincount(point_index, weights=np.nansum(residuals ** 2, axis=1), minlength=p)
    redundancy = 2 * n_rays - 3
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma0 = np.where(ok & (redundancy > 0), np.sqrt(sq / redundancy), np.nan)
    std = np.full((p, 3), np.nan)
    has_std = ok & (redundancy > 0)
    if has_std.any():
        eye = np.broadcast_to(np.eye(3), (int(has_std.sum()), 3, 3))
        q = np.stack([_solve_each(normal[has_std], eye[:, :, j])[0] for j in range(3)], axis=2)
        with np.errstate(invalid="ignore"):
            std[has_std] = sigma0[has_std, None] * np.sqrt(np.diagonal(q, axis1=1, axis2=2))
    offsets = xyz[point_index] - local_c
    dist = np.linalg.norm(np.einsum("mij,mj->mi", proj, offsets), axis=1)
    max_dist = np.full(p, np.nan)
    if m:
        max_dist = np.full(p, -np.inf)
        np.maximum.at(max_dist, point_index, np.where(np.isfinite(dist), dist, -np.inf))
        max_dist[~ok] = np.nan
    xyz[~ok] = np.nan
    return IntersectionResult(xyz + origin, status, n_rays, sigma0, std, max_dist, iterations,
                              residuals)


def principal_distance(photo) -> float:
    """``c`` of :func:`camera_observations`: the film camera's, mm; a camera model's mean focal
    length in pixels (its observations are ideal normalised coordinates times it)."""
    if photo.is_model:
        return float(np.mean(photo.camera.focal_px))
    return photo.camera.c


def intersect_measured(photos, points, point_index: np.ndarray, n_points: int,
                       coordinates: str = "pixel") -> IntersectionResult:
    """:func:`intersect` of points measured on oriented photos: ``photos`` (M,) the photo of each
    observation, ``points`` (M, 2) its measurement (:func:`camera_observations`), ``point_index``
    (M,) its point, 0 .. ``n_points`` - 1."""
    return intersect(point_index, camera_observations(photos, points, coordinates),
                     np.array([p.exterior.centre for p in photos]),
                     np.array([p.exterior.rotation for p in photos]),
                     np.array([principal_distance(p) for p in photos]), n_points)


def camera_observations(photos, points, coordinates: str) -> np.ndarray:
    """Camera coordinates of measured points: mm for a film camera; for a camera model (pinhole,
    Brown, OpenCV, fisheye) its undistorted ideal coordinates scaled by
    :func:`principal_distance` (pixel-sized units: the same rays).

    ``photos`` (M,) :class:`~toolbox.photogrammetry.photo.Photo` objects, ``points`` (M, 2)
    measured pixels (``coordinates="pixel"``) or image mm (``"image"``; film cameras only).
    """
    points = np.asarray(points, dtype="float64")
    out = np.empty_like(points)
    by_photo: dict[str, list[int]] = {}
    for k, photo in enumerate(photos):
        by_photo.setdefault(photo.id, []).append(k)
    for rows in by_photo.values():
        photo = photos[rows[0]]
        xy = points[rows]
        if photo.is_model:
            if coordinates != "pixel":
                raise InputDataError(f"photo {photo.id!r}: its camera is a {photo.camera.kind} "
                                     "model: measure it in pixels (col_px, row_px), not image mm")
            ideal = photo.camera.pixel_to_normalised(xy)
            bad = int(np.isnan(ideal).any(axis=1).sum())
            if bad:
                raise InputDataError(f"photo {photo.id!r}: {bad} measured pixel(s) have no ray "
                                     "(outside the camera model's valid field, or its "
                                     "undistortion does not converge)")
            out[rows] = ideal * principal_distance(photo)
            continue
        if coordinates == "pixel":
            xy = photo.require_pixel_transform().pixel_to_image(xy)
        out[rows] = photo.camera.image_to_camera(xy)
    return out


def normal_case_coordinates(xi1: np.ndarray, eta1: np.ndarray, xi2: np.ndarray,
                            principal_distance: float, base: float):
    """Normal case of stereo restitution (S000 l.528-663; brief section 7): ``O1 = (0, 0, 0)``,
    ``O2 = (B, 0, 0)``, ``R1 = R2 = I``; with ``p = ξ1 - ξ2``::

        Z = -c·B/p      X = B·ξ1/p      Y = B·η1/p

    (image coordinates in mm, ``c`` in mm, B and the result in ground units).
    """
    p = np.asarray(xi1, dtype="float64") - np.asarray(xi2, dtype="float64")
    with np.errstate(divide="ignore", invalid="ignore"):
        return base * np.asarray(xi1) / p, base * np.asarray(eta1) / p, \
            -principal_distance * base / p
