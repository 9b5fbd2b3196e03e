"""Collinearity observation model of the bundle, with self-calibration, and its Jacobians.

Image observation of point ``P`` on photo ``j`` of camera ``k`` (image mm in the fiducial system,
``x`` right, ``y`` up)::

    u = x - x0,  v = y - y0,  r² = u² + v²,  dr = k1·r² + k2·r⁴ + k3·r⁶
    x̄ = u - u·dr - [p1·(r² + 2u²) + 2·p2·u·v]           (measured -> ideal camera coordinates)
    ȳ = v - v·dr - [p2·(r² + 2v²) + 2·p1·u·v]
    d = Rᵀ·(P - C),  x' = -c·d₁/d₃,  y' = -c·d₂/d₃        (collinearity, domain brief section 4)
    residual f = (x' - x̄, y' - ȳ)                         (computed minus observed, mm)

This is the film camera's distortion exactly (:mod:`toolbox.photogrammetry.camera`:
``Δr = k1·r³ + k2·r⁵ + k3·r⁷`` corrected as ``x̄ = u·(1 - Δr/r)``, Brown's decentring p1, p2 in
this correction form), so the adjusted terms go into the project camera as they are.
``R = Rx(ω)·Ry(φ)·Rz(κ)``
(:mod:`toolbox.photogrammetry.rotation`).

Calibration parameter order per camera: :data:`CALIBRATION_NAMES`.
"""

from __future__ import annotations

import numpy as np

# camera kinds: film (image mm, correction form), Brown (px, self-calibrable), any other
# interior model of toolbox.cameras (opencv, fisheye: px through Intrinsics, held fixed)
KIND_FILM, KIND_BROWN, KIND_MODEL = 0, 1, 2
CALIBRATION_NAMES = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2")
BROWN_NAMES = ("f", "cx", "cy", "k1", "k2", "k3", "p1", "p2")  # a Brown camera's 8 places
EXTERIOR_NAMES = ("X0", "Y0", "Z0", "omega", "phi", "kappa")


def _elementary(omega: np.ndarray, phi: np.ndarray, kappa: np.ndarray):
    """Rx, Ry, Rz and their derivatives, each (n, 3, 3)."""
    n = len(omega)

    # duplicate-ok: the three elementary rotations written out (which entries and signs differ)
    def rx(a, deriv):
        m = np.zeros((n, 3, 3))
        s, c = np.sin(a), np.cos(a)
        if deriv:
            m[:, 1, 1], m[:, 1, 2], m[:, 2, 1], m[:, 2, 2] = -s, -c, c, -s
        else:
            m[:, 0, 0] = 1.0
            m[:, 1, 1], m[:, 1, 2], m[:, 2, 1], m[:, 2, 2] = c, -s, s, c
        return m

    def ry(a, deriv):
        m = np.zeros((n, 3, 3))
        s, c = np.sin(a), np.cos(a)
        if deriv:
            m[:, 0, 0], m[:, 0, 2], m[:, 2, 0], m[:, 2, 2] = -s, c, -c, -s
        else:
            m[:, 1, 1] = 1.0
            m[:, 0, 0], m[:, 0, 2], m[:, 2, 0], m[:, 2, 2] = c, s, -s, c
        return m

    def rz(a, deriv):
        m = np.zeros((n, 3, 3))
        s, c = np.sin(a), np.cos(a)
        if deriv:
            m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1] = -s, -c, c, -s
        else:
            m[:, 2, 2] = 1.0
            m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1] = c, -s, s, c
        return m

    return (rx(omega, False), ry(phi, False), rz(kappa, False),
            rx(omega, True), ry(phi, True), rz(kappa, True))


def rotations(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R`` (n, 3, 3) and ``dR/d(ω, φ, κ)`` (n, 3, 3, 3; last-but-two axis the angle) for
    ``angles`` (n, 3) radians."""
    angles = np.asarray(angles, dtype=float).reshape(-1, 3)
    x, y, z, dx, dy, dz = _elementary(angles[:, 0], angles[:, 1], angles[:, 2])
    r = x @ y @ z
    d = np.stack([dx @ y @ z, x @ dy @ z, x @ y @ dz], axis=1)
    return r, d


def ideal(xy: np.ndarray, calib: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ideal camera coordinates from measured image mm ``xy`` (m, 2) with per-observation
    calibration ``calib`` (m, 8), and their derivatives ``d(x̄, ȳ)/d(calibration)`` (m, 2, 8)
    (the ``c`` column is zero: c acts on the projection side)."""
    u = xy[:, 0] - calib[:, 1]
    v = xy[:, 1] - calib[:, 2]
    k1, k2, k3, p1, p2 = (calib[:, i] for i in range(3, 8))
    r2 = u * u + v * v
    dr = k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    ddr = k1 + 2 * k2 * r2 + 3 * k3 * r2 ** 2  # d(dr)/d(r²)
    xb = u - u * dr - (p1 * (r2 + 2 * u * u) + 2 * p2 * u * v)
    yb = v - v * dr - (p2 * (r2 + 2 * v * v) + 2 * p1 * u * v)
    dxb_du = 1 - dr - u * ddr * 2 * u - (6 * p1 * u + 2 * p2 * v)
    dxb_dv = -u * ddr * 2 * v - (2 * p1 * v + 2 * p2 * u)
    dyb_du = -v * ddr * 2 * u - (2 * p2 * u + 2 * p1 * v)
    dyb_dv = 1 - dr - v * ddr * 2 * v - (6 * p2 * v + 2 * p1 * u)
    jac = np.zeros((len(u), 2, 8))
    jac[:, 0, 1], jac[:, 0, 2] = -dxb_du, -dxb_dv
    jac[:, 1, 1], jac[:, 1, 2] = -dyb_du, -dyb_dv
    jac[:, 0, 3], jac[:, 0, 4], jac[:, 0, 5] = -u * r2, -u * r2 ** 2, -u * r2 ** 3
    jac[:, 1, 3], jac[:, 1, 4], jac[:, 1, 5] = -v * r2, -v * r2 ** 2, -v * r2 ** 3
    jac[:, 0, 6], jac[:, 0, 7] = -(r2 + 2 * u * u), -2 * u * v
    jac[:, 1, 6], jac[:, 1, 7] = -2 * u * v, -(r2 + 2 * v * v)
    return np.column_stack([xb, yb]), jac


def image_residuals(xy: np.ndarray, exterior: np.ndarray, point: np.ndarray, calib: np.ndarray,
                    jacobians: bool = True, rotation: tuple[np.ndarray, np.ndarray] | None = None):
    """:func:`image_residuals_numpy`, computed by the compiled kernel
    :func:`toolbox.triangulation.kernels.film_residuals` (same arithmetic, both cores)."""
    from toolbox.triangulation.kernels import film_residuals

    r, dr = rotations(exterior[:, 3:]) if rotation is None else rotation
    m = len(xy)
    out = [np.empty((m, 2)), np.empty(m)]
    jac = [np.empty((m, 2, 6)), np.empty((m, 2, 3)), np.empty((m, 2, 8))] if jacobians else \
        [np.empty((0, 2, 6)), np.empty((0, 2, 3)), np.empty((0, 2, 8))]
    args = (np.ascontiguousarray(a, dtype=float) for a in (xy, exterior, point, calib, r, dr))
    film_residuals(*args, jacobians, *out, *jac)
    return tuple(out + jac) if jacobians else tuple(out)


def image_residuals_numpy(xy: np.ndarray, exterior: np.ndarray, point: np.ndarray,
                          calib: np.ndarray, jacobians: bool = True,
                          rotation: tuple[np.ndarray, np.ndarray] | None = None):
    """Residuals (computed minus observed, mm) of image observations and their Jacobians.

    Parameters (one row per observation)
    ----------
    xy : (m, 2) measured image mm
    exterior : (m, 6) X0, Y0, Z0 (local ground units), omega, phi, kappa (rad)
    point : (m, 3) ground point (local ground units)
    calib : (m, 8) :data:`CALIBRATION_NAMES`
    rotation : optional ``(R, dR)`` of each observation's photo, as :func:`rotations` returns
        (computed once per photo by the caller instead of once per observation)

    Returns
    -------
    f (m, 2), depth d₃ (m,; negative in front of the camera) and, with ``jacobians``,
    ``J_ext`` (m, 2, 6), ``J_point`` (m, 2, 3), ``J_calib`` (m, 2, 8).
    """
    r, dr = rotations(exterior[:, 3:]) if rotation is None else rotation
    delta = point - exterior[:, :3]
    d = np.einsum("mji,mj->mi", r, delta)  # Rᵀ·(P - C)
    c = calib[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = -c[:, None] * d[:, :2] / d[:, 2:3]
    obs, j_obs = ideal(xy, calib)
    f = proj - obs
    if not jacobians:
        return f, d[:, 2]
    # d(proj)/d(d): rows x', y'
    inv = 1.0 / d[:, 2]
    dp = np.zeros((len(c), 2, 3))
    dp[:, 0, 0] = -c * inv
    dp[:, 1, 1] = -c * inv
    dp[:, 0, 2] = c * d[:, 0] * inv ** 2
    dp[:, 1, 2] = c * d[:, 1] * inv ** 2
    j_point = np.einsum("mak,mjk->maj", dp, r)  # dp · Rᵀ
    j_ext = np.empty((len(c), 2, 6))
    j_ext[:, :, :3] = -j_point
    dd_angles = np.einsum("mtji,mj->mti", dr, delta)  # (dR/dt)ᵀ·(P - C), (m, 3 angles, 3)
    j_ext[:, :, 3:] = np.einsum("mak,mtk->mat", dp, dd_angles)
    j_calib = -j_obs
    j_calib[:, :, 0] = proj / c[:, None]
    return f, d[:, 2], j_ext, j_point, j_calib


# -- digital cameras: the Brown model, forward (pixels) ------------------------------------------
#
# For a camera of kind BROWN the calibration vector (same 8 places) holds
# ``(f, cx, cy, k1, k2, k3, p1, p2)``: the focal length fx (px; fy = aspect·fx, aspect fixed),
# the principal point in the product's pixels (top-left pixel centre at 0.5) and OpenCV's
# distortion terms (:mod:`toolbox.cameras.intrinsics`); the observations are pixels
# (col right, row down) and the residual is computed minus observed, px::
#
#     d = Rᵀ·(P - C) (photogrammetric frame),  xn = -d₁/d₃,  yn = d₂/d₃   (OpenCV frame: x, -y, -z)
#     r² = xn² + yn²,  ρ = 1 + k1·r² + k2·r⁴ + k3·r⁶
#     xd = xn·ρ + 2·p1·xn·yn + p2·(r² + 2xn²),  yd = yn·ρ + p1·(r² + 2yn²) + 2·p2·xn·yn
#     col = f·xd + cx,  row = aspect·f·yd + cy

def brown_residuals(px: np.ndarray, exterior: np.ndarray, point: np.ndarray, calib: np.ndarray,
                    aspect: np.ndarray, jacobians: bool = True,
                    rotation: tuple[np.ndarray, np.ndarray] | None = None):
    """:func:`image_residuals` for Brown cameras: pixels ``px`` (m, 2), calibration (m, 8) as
    above, ``aspect`` (m,) fy/fx; same returns (residuals in px)."""
    r, dr = rotations(exterior[:, 3:]) if rotation is None else rotation
    delta = point - exterior[:, :3]
    d = np.einsum("mji,mj->mi", r, delta)
    f, k1, k2, k3, p1, p2 = (calib[:, i] for i in (0, 3, 4, 5, 6, 7))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d[:, 2]
    xn, yn = -d[:, 0] * inv, d[:, 1] * inv
    r2 = xn * xn + yn * yn
    rho = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = xn * rho + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
    yd = yn * rho + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
    fy = aspect * f
    res = np.column_stack([f * xd + calib[:, 1] - px[:, 0], fy * yd + calib[:, 2] - px[:, 1]])
    if not jacobians:
        return res, d[:, 2]
    drho = k1 + r2 * (2 * k2 + 3 * r2 * k3)  # dρ/d(r²)
    a = rho + 2 * xn * xn * drho + 2 * p1 * yn + 6 * p2 * xn  # dxd/dxn
    b = 2 * xn * yn * drho + 2 * p1 * xn + 2 * p2 * yn  # dxd/dyn (= dyd/dxn)
    e = rho + 2 * yn * yn * drho + 6 * p1 * yn + 2 * p2 * xn  # dyd/dyn
    m = len(f)
    dn = np.zeros((m, 2, 3))  # d(xn, yn)/d(d)
    dn[:, 0, 0], dn[:, 0, 2] = -inv, d[:, 0] * inv ** 2
    dn[:, 1, 1], dn[:, 1, 2] = inv, -d[:, 1] * inv ** 2
    dist = np.empty((m, 2, 2))
    dist[:, 0, 0], dist[:, 0, 1] = f * a, f * b
    dist[:, 1, 0], dist[:, 1, 1] = fy * b, fy * e
    dp = dist @ dn  # d(col, row)/d(d)
    j_point = np.einsum("mak,mjk->maj", dp, r)
    j_ext = np.empty((m, 2, 6))
    j_ext[:, :, :3] = -j_point
    dd_angles = np.einsum("mtji,mj->mti", dr, delta)
    j_ext[:, :, 3:] = np.einsum("mak,mtk->mat", dp, dd_angles)
    j_calib = np.zeros((m, 2, 8))
    j_calib[:, 0, 0], j_calib[:, 1, 0] = xd, aspect * yd
    j_calib[:, 0, 1], j_calib[:, 1, 2] = 1.0, 1.0
    for i, t in ((3, r2), (4, r2 ** 2), (5, r2 ** 3)):
        j_calib[:, 0, i], j_calib[:, 1, i] = f * xn * t, fy * yn * t
    j_calib[:, 0, 6], j_calib[:, 1, 6] = f * 2 * xn * yn, fy * (r2 + 2 * yn * yn)
    j_calib[:, 0, 7], j_calib[:, 1, 7] = f * (r2 + 2 * xn * xn), fy * 2 * xn * yn
    return res, d[:, 2], j_ext, j_point, j_calib


def model_residuals(px: np.ndarray, exterior: np.ndarray, point: np.ndarray, intrinsics,
                    jacobians: bool = True,
                    rotation: tuple[np.ndarray, np.ndarray] | None = None):
    """:func:`image_residuals` for a fixed interior model of :mod:`toolbox.cameras` (opencv,
    fisheye): pixels through ``intrinsics.camera_to_pixel`` of the OpenCV camera coordinates
    ``D·Rᵀ·(P - C)`` (``D = diag(1, -1, -1)``); the derivatives by the camera coordinates by
    central differences (relative step 1e-6 of the depth), the rest by the chain rule; no
    calibration unknowns (``J_calib`` zero)."""
    r, dr = rotations(exterior[:, 3:]) if rotation is None else rotation
    delta = point - exterior[:, :3]
    d = np.einsum("mji,mj->mi", r, delta)
    flip = np.array([1.0, -1.0, -1.0])
    cam = d * flip
    res = intrinsics.camera_to_pixel(cam) - px
    if not jacobians:
        return res, d[:, 2]
    m = len(px)
    dcam = np.empty((m, 2, 3))
    h = 1e-6 * np.maximum(np.abs(cam[:, 2]), 1e-9)
    for k in range(3):
        step = np.zeros((m, 3))
        step[:, k] = h
        dcam[:, :, k] = (intrinsics.camera_to_pixel(cam + step)
                         - intrinsics.camera_to_pixel(cam - step)) / (2 * h[:, None])
    dp = dcam * flip  # d(pixels)/d(d)
    j_point = np.einsum("mak,mjk->maj", dp, r)
    j_ext = np.empty((m, 2, 6))
    j_ext[:, :, :3] = -j_point
    dd_angles = np.einsum("mtji,mj->mti", dr, delta)
    j_ext[:, :, 3:] = np.einsum("mak,mtk->mat", dp, dd_angles)
    return res, d[:, 2], j_ext, j_point, np.zeros((m, 2, 8))


def observation_residuals(xy: np.ndarray, exterior: np.ndarray, point: np.ndarray,
                          calib: np.ndarray, kind: np.ndarray | None = None,
                          aspect: np.ndarray | None = None, jacobians: bool = True,
                          rotation: tuple[np.ndarray, np.ndarray] | None = None,
                          cameras: np.ndarray | None = None, models: list | None = None):
    """:func:`image_residuals` (film, image mm), :func:`brown_residuals` or
    :func:`model_residuals` (pixels) per observation by its camera ``kind`` (m,) (KIND_*),
    ``aspect`` (m,) fy/fx of a Brown camera, ``cameras`` (m,) camera index and ``models`` the
    cameras' interior models (KIND_MODEL)."""
    if kind is None or not kind.any():
        return image_residuals(xy, exterior, point, calib, jacobians, rotation)
    if (kind == KIND_BROWN).all():
        return brown_residuals(xy, exterior, point, calib, aspect, jacobians, rotation)
    groups = [(np.flatnonzero(kind == KIND_FILM), None), (np.flatnonzero(kind == KIND_BROWN), None)]
    if (kind == KIND_MODEL).any():
        groups += [(np.flatnonzero((kind == KIND_MODEL) & (cameras == c)), c)
                   for c in np.unique(cameras[kind == KIND_MODEL])]
    merged = None
    for g, (idx, cam) in enumerate(groups):
        if not len(idx):
            continue
        rot = None if rotation is None else (rotation[0][idx], rotation[1][idx])
        args = (xy[idx], exterior[idx], point[idx])
        if g == 0:
            out = image_residuals(*args, calib[idx], jacobians, rot)
        elif g == 1:
            out = brown_residuals(*args, calib[idx], aspect[idx], jacobians, rot)
        else:
            out = model_residuals(*args, models[cam], jacobians, rot)
        if merged is None:
            merged = [np.empty((len(xy),) + a.shape[1:]) for a in out]
        for full, a in zip(merged, out, strict=True):
            full[idx] = a
    return tuple(merged)


def brown_ideal(px: np.ndarray, calib: np.ndarray, aspect: np.ndarray,
                iterations: int = 30) -> np.ndarray:
    """Ideal camera coordinates ``(f·xn, -f·yn)`` (px, y up: the film model's ``(x̄, ȳ)`` with
    ``c = f``) of Brown pixels ``px`` (m, 2), the distortion inverted by fixed-point iteration
    (OpenCV's ``undistortPoints`` scheme), for the approximate values."""
    f, k1, k2, k3, p1, p2 = (calib[:, i] for i in (0, 3, 4, 5, 6, 7))
    xd = (px[:, 0] - calib[:, 1]) / f
    yd = (px[:, 1] - calib[:, 2]) / (aspect * f)
    xn, yn = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = xn * xn + yn * yn
        rho = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xn = (xd - 2 * p1 * xn * yn - p2 * (r2 + 2 * xn * xn)) / rho
        yn = (yd - p1 * (r2 + 2 * yn * yn) - 2 * p2 * xn * yn) / rho
    return np.column_stack([f * xn, -f * yn])
