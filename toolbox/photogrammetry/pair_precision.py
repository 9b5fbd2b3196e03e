"""Precision of a ground point intersected from its pixels on posed cameras (any
:class:`~toolbox.cameras.base.CameraModel`: pinhole, Brown, OpenCV, fisheye; distortion and
tilts included), by first-order error propagation: the covariance of the least-squares
intersection (the inverse of its normal matrix)::

    Σ_XYZ = σ²·(JᵀJ)⁻¹,   J = ∂(col₁, row₁, col₂, row₂, ...)/∂(X, Y, Z)

``σ`` the standard deviation of each measured image coordinate (pixels, independent and equal),
``J`` by central differences of the cameras' ``project`` (step ``STEP`` times the distance to
the nearest camera). In the normal case (two vertical pinhole photos, no distortion) this gives
the normal-case formula's ``σZ = (Z/B)·(Z/f)·√2·σ`` at the middle of the base.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

STEP = 1e-6  # relative central-difference step


def intersection_covariance(cameras: Sequence[Any], point: Any, sigma_px: float) -> np.ndarray:
    """Covariance (3, 3; ground units squared) of ``point`` (X, Y, Z) intersected from its
    pixels on ``cameras`` (two or more), each coordinate measured with ``sigma_px``; NaN when
    the point does not project into every camera (behind one, or outside a model's valid
    field) or the rays are nearly parallel."""
    x = np.asarray(point, dtype="float64").reshape(3)
    distance = min(float(np.linalg.norm(x - np.asarray(c.centre))) for c in cameras)
    h = STEP * distance
    steps = np.vstack([x + h * e for e in np.eye(3)] + [x - h * e for e in np.eye(3)])
    columns = []
    for camera in cameras:
        px = camera.project(steps)
        columns.append((px[:3] - px[3:]) / (2.0 * h))  # (3 axes, 2 pixel coordinates)
    jacobian = np.hstack(columns).T  # (2n, 3)
    if not np.isfinite(jacobian).all():
        return np.full((3, 3), np.nan)
    normal = jacobian.T @ jacobian
    if np.linalg.cond(normal) > 1e12:
        return np.full((3, 3), np.nan)
    return sigma_px ** 2 * np.linalg.inv(normal)


def pair_sigmas(cameras: Sequence[Any], point: Any, sigma_px: float) -> np.ndarray:
    """σX, σY, σZ (3,; ground units) of :func:`intersection_covariance` (NaN: none)."""
    return np.sqrt(np.diag(intersection_covariance(cameras, point, sigma_px)))


def model_pair_precision(a: Any, b: Any, height: float, sigma_px: float) -> dict[str, Any]:
    """Precision of a stereo pair of posed model cameras (:class:`~toolbox.cameras.frame.
    FrameCamera`) over the terrain height ``height``: at the ground point below the middle of
    the base (``centre``) and the worst of the points seen at the left photo's image corners
    that both photos see (``edge``; None when they see none); metres, with the pair's geometry
    (base, distance, GSD = distance/f). A pair that does not both see the middle point is not
    a stereo pair: :class:`InputDataError`."""
    ca, cb = np.asarray(a.centre, dtype="float64"), np.asarray(b.centre, dtype="float64")
    middle = np.array([(ca[0] + cb[0]) / 2, (ca[1] + cb[1]) / 2, height])
    sx, sy, sz = pair_sigmas([a, b], middle, sigma_px)
    if not np.isfinite([sx, sy, sz]).all():
        raise InputDataError("the ground point below the middle of their base is not seen by "
                             "both photos (or their rays are parallel): not a stereo pair")
    w, h = a.image_size
    corners = a.pixel_to_ground(np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]), height)
    edge = np.array([pair_sigmas([a, b], p, sigma_px) for p in corners])
    edge = edge[np.isfinite(edge).all(axis=1)]
    focal = float(np.mean([*a.intrinsics.focal_px, *b.intrinsics.focal_px]))
    distance = (ca[2] + cb[2]) / 2 - height
    base = float(np.linalg.norm(cb - ca))
    worst = edge.max(axis=0).tolist() if len(edge) else [None, None, None]
    return {"principal_distance_px": focal, "base_m": base, "distance_m": distance,
            "gsd_m": distance / focal, "base_ratio": base / distance, "sigma_pixel_px": sigma_px,
            "sigma_x_centre_m": float(sx), "sigma_y_centre_m": float(sy), "sigma_z_m": float(sz),
            "sigma_x_edge_m": worst[0], "sigma_y_edge_m": worst[1], "sigma_z_edge_m": worst[2],
            "edge_corners": len(edge)}
