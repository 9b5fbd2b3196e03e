"""Precision of stereo restitution in the normal case (domain brief section 7).

Formulas (S000 l.605-649; S002 eq. [35]-[40]), c and B error-free, ``m_b = Z/c`` the photo
scale factor and ``B/Z`` the base ratio (|Z| the distance from the projection centres)::

    σZ = m_b·(Z/B)·σp
    σX = m_b·sqrt((ξ·Z/(c·B))²·σp² + σξ²)
    σY = m_b·sqrt((η·Z/(c·B))²·σp² + ση²)

``σp`` is the standard deviation of the x-parallax ``p = ξ1 - ξ2``; with σ per image coordinate,
``σp = √2·σ`` (eq. [35]). S000's rules table assumes ``σp = 5 µm`` (its σZ column is exactly
``m_b·(Z/B)·5 µm``). Image quantities are in mm (σ in µm where noted), ground ones in metres.

The table's σXY column is not σX of one axis: it is the two-axis (radial) figure
``σXY = sqrt(σX² + σY²)`` with ``σξ = ση = σp = 5 µm`` at a point ``ρ = c/3`` from the principal
point (:func:`rules_table_sigma_xy`), i.e. ``σXY = m_b·σ·sqrt(2 + (Z/B)²/9)``: 0.72 dm at 1:10,000
for B/Z = 1:1, 3.41 dm for 1:20 (our derivation; it fits all 20 printed values to their rounding).
"""

from __future__ import annotations

import math
from typing import Any

from toolbox.errors import InputDataError


def normal_case_precision(principal_distance_mm: float, base_m: float, distance_m: float,
                          sigma_parallax_um: float, sigma_image_um: float | None = None,
                          xi_mm: float = 0.0, eta_mm: float = 0.0) -> dict[str, Any]:
    """σX, σY, σZ (metres) of a point at image position (ξ, η) of the left photo.

    ``sigma_image_um`` (σξ = ση) defaults to ``sigma_parallax_um / √2``.

    Examples
    --------
    >>> r = normal_case_precision(150.0, 1000.0, 3000.0, 5.0)   # m_b = 20000, B/Z = 1:3
    >>> round(r["sigma_z_m"], 6), r["photo_scale"]
    (0.3, 20000.0)
    """
    for name, value in (("principal distance", principal_distance_mm), ("base", base_m),
                        ("distance", distance_m), ("sigma of the parallax", sigma_parallax_um)):
        if not (math.isfinite(value) and value > 0):
            raise InputDataError(f"{name} must be > 0, got {value!r}")
    sigma_image_um = sigma_parallax_um / math.sqrt(2.0) if sigma_image_um is None \
        else sigma_image_um
    c = principal_distance_mm
    m_b = distance_m * 1000.0 / c
    ratio = distance_m / base_m  # Z/B
    sp = sigma_parallax_um / 1000.0  # mm
    si = sigma_image_um / 1000.0
    sz = m_b * ratio * sp / 1000.0
    sx = m_b * math.sqrt((xi_mm * ratio / c) ** 2 * sp ** 2 + si ** 2) / 1000.0
    sy = m_b * math.sqrt((eta_mm * ratio / c) ** 2 * sp ** 2 + si ** 2) / 1000.0
    return {"principal_distance_mm": c, "base_m": base_m, "distance_m": distance_m,
            "photo_scale": m_b, "base_ratio": base_m / distance_m,
            "sigma_parallax_um": sigma_parallax_um, "sigma_image_um": sigma_image_um,
            "xi_mm": xi_mm, "eta_mm": eta_mm, "sigma_x_m": sx, "sigma_y_m": sy, "sigma_z_m": sz}


def rules_table_sigma_xy(principal_distance_mm: float, base_m: float, distance_m: float,
                         sigma_um: float = 5.0) -> float:
    """The σXY that S000's rules table prints (metres): ``sqrt(σX² + σY²)`` with
    ``σξ = ση = σp = sigma_um`` at ``ρ = c/3`` from the principal point."""
    p = normal_case_precision(principal_distance_mm, base_m, distance_m, sigma_um, sigma_um,
                              principal_distance_mm / 3.0, 0.0)
    q = normal_case_precision(principal_distance_mm, base_m, distance_m, sigma_um, sigma_um)
    return math.hypot(p["sigma_x_m"], q["sigma_y_m"])
