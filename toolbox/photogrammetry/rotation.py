"""Rotation matrix R(omega, phi, kappa), its inverse (angles from a matrix) and angle units.

Convention (domain brief section 3; source S000 "ROTAZIONE NELLO SPAZIO", l.295-360): omega is
the primary rotation about X, phi the secondary about the once-rotated Y, kappa the tertiary
about the twice-rotated Z; positive counter-clockwise looking toward the origin. ``R`` maps
image-space vectors onto ground-parallel axes (``X - X0 = lambda * R @ (x, y, -c)``) and equals
``Rx(omega) @ Ry(phi) @ Rz(kappa)`` with the usual counter-clockwise elementary matrices, i.e. the
"omega-phi-kappa" (PATB) convention of most photogrammetric software. Element by element
(S000 l.336)::

    r11 = cos k cos p                    r12 = -sin k cos p                   r13 = sin p
    r21 = cos k sin p sin o + cos o sin k   r22 = cos k cos o - sin p sin o sin k   r23 = -sin o cos p
    r31 = sin o sin k - cos k sin p cos o   r32 = cos o sin p sin k + cos k sin o   r33 = cos p cos o

Angles back (S000 l.346-360): ``omega = atan2(-r23, r33)``, ``phi = asin(r13)``,
``kappa = atan2(-r12, r11)``, the ``cos(phi) > 0`` branch.
"""

from __future__ import annotations

import math

import numpy as np

from toolbox.errors import InputDataError, ParameterError

#: accepted angle units and their aliases (lowercase)
ANGLE_UNITS: dict[str, str] = {
    "rad": "rad", "radian": "rad", "radians": "rad",
    "deg": "deg", "degree": "deg", "degrees": "deg", "°": "deg",
    "gon": "gon", "grad": "gon", "grads": "gon", "gradian": "gon", "gradians": "gon",
}
#: radians per unit
_TO_RADIANS = {"rad": 1.0, "deg": math.pi / 180.0, "gon": math.pi / 200.0}
ORTHONORMAL_TOLERANCE = 1e-6


def angle_unit(value: str, name: str = "ANGLE_UNIT") -> str:
    """The canonical unit name (``"rad"``, ``"deg"`` or ``"gon"``) for ``value``.

    Raises :class:`ParameterError` naming ``name`` for anything else, e.g.
    ``ANGLE_UNIT must be one of rad, deg, gon (or radians, degrees, grad...); got 'mil'``.
    """
    key = str(value).strip().lower() if value is not None else ""
    if key not in ANGLE_UNITS:
        raise ParameterError(name, f"must be one of rad, deg, gon (or radians, degrees, grad...); "
                             f"got {value!r}")
    return ANGLE_UNITS[key]


#: one full turn in each unit
TURN = {"rad": 2.0 * math.pi, "deg": 360.0, "gon": 400.0}


def check_within_turn(values, unit: str, name: str = "ANGLE_UNIT", where: str = "") -> None:
    """:class:`ParameterError` naming ``name`` (what set the unit) when an angle read in
    ``unit`` lies beyond a full turn: no orientation software writes one, so the numbers are in
    another unit (gon read as degrees: 385 gon would become 25 deg instead of 346.5 deg, in
    silence; degrees read as radians). ``where``: the file or row, for the message."""
    unit = angle_unit(unit, name)
    values = np.abs(np.asarray(values, dtype="float64"))
    values = values[np.isfinite(values)]
    if not values.size or values.max() <= TURN[unit] * (1 + 1e-9):
        return
    worst = float(values.max())
    likely = next((u for u in ("deg", "gon") if TURN[u] > TURN[unit] and worst <= TURN[u]),
                  None)
    raise ParameterError(name, f"is {unit}, but {where + ' has ' if where else ''}an angle of "
                         f"{worst:g}, beyond a full turn ({TURN[unit]:g} {unit}): the angles are "
                         f"not in {unit}" + (f" (in {likely}?)" if likely else "") +
                         "; state their unit")


def to_radians(values, unit: str, name: str = "ANGLE_UNIT"):
    """Angles in ``unit`` converted to radians (a float for a scalar, else an array)."""
    converted = np.asarray(values, dtype="float64") * _TO_RADIANS[angle_unit(unit, name)]
    return float(converted) if converted.ndim == 0 else converted


def from_radians(values, unit: str, name: str = "ANGLE_UNIT"):
    """Angles in radians converted to ``unit`` (a float for a scalar, else an array)."""
    converted = np.asarray(values, dtype="float64") / _TO_RADIANS[angle_unit(unit, name)]
    return float(converted) if converted.ndim == 0 else converted


def rotation_matrix(omega, phi, kappa) -> np.ndarray:
    """``R(omega, phi, kappa)`` (radians), element by element as S000 l.336.

    Scalars give a (3, 3) matrix; arrays of shape ``S`` (broadcast together) give ``S + (3, 3)``.

    Examples
    --------
    >>> np.allclose(rotation_matrix(0.0, 0.0, 0.0), np.eye(3))
    True
    >>> R = rotation_matrix(0.0, 0.0, np.pi / 2)   # kappa = 90 deg: image x -> ground Y
    >>> np.round(R @ [1.0, 0.0, 0.0], 12) + 0.0
    array([0., 1., 0.])
    """
    o, p, k = np.broadcast_arrays(*(np.asarray(a, dtype="float64") for a in (omega, phi, kappa)))
    so, co = np.sin(o), np.cos(o)
    sp, cp = np.sin(p), np.cos(p)
    sk, ck = np.sin(k), np.cos(k)
    r = np.empty(o.shape + (3, 3))
    r[..., 0, 0] = ck * cp
    r[..., 0, 1] = -sk * cp
    r[..., 0, 2] = sp
    r[..., 1, 0] = ck * sp * so + co * sk
    r[..., 1, 1] = ck * co - sp * so * sk
    r[..., 1, 2] = -so * cp
    r[..., 2, 0] = so * sk - ck * sp * co
    r[..., 2, 1] = co * sp * sk + ck * so
    r[..., 2, 2] = cp * co
    return r


def check_rotation(matrix, tolerance: float = ORTHONORMAL_TOLERANCE, what: str = "rotation matrix"
                   ) -> np.ndarray:
    """Return ``matrix`` as a float (3, 3) array, or raise :class:`InputDataError` when it is not
    a proper rotation (``R @ R.T == I`` within ``tolerance`` and ``det R = +1``)."""
    r = np.asarray(matrix, dtype="float64")
    if r.shape != (3, 3):
        raise InputDataError(f"{what} must be 3 x 3, got shape {r.shape}")
    if not np.isfinite(r).all():
        raise InputDataError(f"{what} contains NaN or inf")
    error = float(np.abs(r @ r.T - np.eye(3)).max())
    det = float(np.linalg.det(r))
    if error > tolerance:
        raise InputDataError(f"{what} is not orthonormal: max |R·Rᵀ - I| = {error:.3g} "
                             f"(tolerance {tolerance:g})")
    if det < 0:
        raise InputDataError(f"{what} is a reflection (det = {det:.6f}), not a rotation")
    return r


NEAR_GIMBAL_LOCK = 1e-3  # cos(phi) under which angles_from_matrix solves omega after kappa


def angles_from_matrix(matrix, tolerance: float = ORTHONORMAL_TOLERANCE
                       ) -> tuple[float, float, float]:
    """``(omega, phi, kappa)`` in radians from a rotation matrix (the ``cos(phi) >= 0`` branch).

    The matrix is checked first (:func:`check_rotation`). At ``phi = ±pi/2`` (gimbal lock) only
    ``omega ± kappa`` is defined; omega is then set to 0.

    Examples
    --------
    >>> o, p, k = angles_from_matrix(rotation_matrix(0.014, -0.001, 3.122))
    >>> [round(v, 12) for v in (o, p, k)]
    [0.014, -0.001, 3.122]
    """
    r = check_rotation(matrix, tolerance)
    cos_phi = math.hypot(r[0, 0], r[0, 1])
    if cos_phi < NEAR_GIMBAL_LOCK:
        # near phi = ±pi/2 (a camera looking level along X: a facade, a terrestrial photo)
        # omega and kappa each come from elements ~cos(phi) small, their rounding divided by
        # cos(phi) (7e-4 rad at 1e-12 rad from the lock): omega is solved from R·Rz(kappa)ᵀ·
        # Ry(phi)ᵀ = Rx(omega) instead, so the angles give R back to rounding
        phi = math.atan2(r[0, 2], cos_phi)
        if cos_phi < 1e-12:  # cos(phi) = 0: R = Ry(±pi/2)·Rz(kappa), omega = 0
            return 0.0, phi, math.atan2(r[1, 0], r[1, 1])
        kappa = math.atan2(-r[0, 1], r[0, 0])
        m = r @ rotation_matrix(0.0, 0.0, kappa).T @ rotation_matrix(0.0, phi, 0.0).T
        return math.atan2(m[2, 1], m[1, 1]), phi, kappa
    phi = math.asin(max(-1.0, min(1.0, r[0, 2])))
    omega = math.atan2(-r[1, 2], r[2, 2])
    kappa = math.atan2(-r[0, 1], r[0, 0])
    return omega, phi, kappa
