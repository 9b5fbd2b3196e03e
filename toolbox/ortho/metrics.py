"""What the ortho report measures: per-window counts (:class:`TileStatistics`), incidence angle,
relief displacement, ground sample distance and the expected accuracy."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.counters import Counters
from toolbox.errors import InputDataError


@dataclass
class TileStatistics(Counters):
    """Counters of the cells of an ortho window, summed over windows by :meth:`add`."""

    MAXIMA = ("max_relief_m",)

    cells: int = 0  # cells of the window
    outside_dem: int = 0  # cells without a DEM height
    outside_photo: int = 0  # cells whose ray falls outside the photo
    hidden: int = 0  # cells hidden from the camera (true ortho)
    max_relief_m: float = 0.0  # largest relief displacement, m
    blocks: dict[int, int] = field(default_factory=lambda: {0: 0, 1: 0, 2: 0})  # map blocks by kind


def incidence_angle(xs: np.ndarray, ys: np.ndarray, z_halo: np.ndarray, centre: np.ndarray
                    ) -> np.ndarray:
    """Angle (degrees, float32) between the ray cell -> projection centre and the surface normal,
    as GRASS i.ortho.rectify writes it: 0 = seen head-on, 90 = grazing, > 90 = back-facing.

    ``z_halo`` holds the heights of the cells and one cell around them ((h + 2, w + 2)), so the
    normals come from central differences everywhere (no seams between tiles).
    """
    cx = float(xs[1] - xs[0]) if len(xs) > 1 else 1.0
    cy = float(ys[0] - ys[1]) if len(ys) > 1 else 1.0
    dzdx = (z_halo[1:-1, 2:] - z_halo[1:-1, :-2]) / (2 * cx)
    dzdy = (z_halo[:-2, 1:-1] - z_halo[2:, 1:-1]) / (2 * cy)
    z = z_halo[1:-1, 1:-1]
    vx = centre[0] - xs[None, :]
    vy = centre[1] - ys[:, None]
    vz = centre[2] - z
    dot = -dzdx * vx - dzdy * vy + vz
    norm = np.sqrt(dzdx ** 2 + dzdy ** 2 + 1.0) * np.sqrt(vx ** 2 + vy ** 2 + vz ** 2)
    with np.errstate(invalid="ignore"):
        return np.degrees(np.arccos(np.clip(dot / norm, -1.0, 1.0))).astype("float32")


def relief_displacement(x: np.ndarray, y: np.ndarray, z: np.ndarray, centre: np.ndarray,
                        reference_height: float) -> np.ndarray:
    """Ground displacement (m) a rectification on the plane ``Z = reference_height`` would leave
    at each cell: ``ρ·|Z - Zref| / (Z0 - Z)`` with ρ the horizontal distance from the nadir
    point (brief section 15, eq. [49] in ground units). ``x``, ``y`` broadcast to ``z`` (e.g.
    ``xs[None, :]`` and ``ys[:, None]``)."""
    dx, dy = x - centre[0], y - centre[1]
    rho = np.sqrt(dx * dx + dy * dy)  # not hypot: the operations of ortho_window_*
    with np.errstate(invalid="ignore", divide="ignore"):
        return rho * np.abs(z - reference_height) / (centre[2] - z)


def ground_sample_distance(photo: Any, height: float) -> float:
    """Ground size (m) of one photo pixel at the image centre on the plane ``Z = height``: the
    mean of the ground steps of one pixel along the columns and along the rows."""
    w, h = photo.camera.image_size_px
    pts = np.array([[w / 2 - 0.5, h / 2], [w / 2 + 0.5, h / 2], [w / 2, h / 2 - 0.5],
                    [w / 2, h / 2 + 0.5]])
    ground = photo.pixel_to_ground(pts, height)
    return 0.5 * float(np.hypot(*(ground[1, :2] - ground[0, :2])) +
                       np.hypot(*(ground[3, :2] - ground[2, :2])))


def nice_cell_size(value: float) -> float:
    """``value`` rounded to 2 significant digits (a GSD proposal such as 0.053 m or 1.2 m)."""
    if not value > 0:
        raise InputDataError(f"cell size must be > 0, got {value}")
    digits = 1 - int(math.floor(math.log10(value)))
    return round(value, digits)


def expected_accuracy(map_scale: float | None) -> dict[str, float] | None:
    """The seeds' rule (S002 par. 2.6.6): RMS at most ±0.3 mm (small scales) to ±0.5 mm (large
    scales) at the map scale, in ground metres."""
    if map_scale is None:
        return None
    return {"map_scale": float(map_scale), "rms_small_scale_m": 0.3 * map_scale / 1000.0,
            "rms_large_scale_m": 0.5 * map_scale / 1000.0}
