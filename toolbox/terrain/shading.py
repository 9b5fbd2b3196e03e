"""Shaded relief of a DEM (Horn's slope, Lambertian illumination), arrays in, arrays out."""

from __future__ import annotations

import numpy as np


def hillshade(z: np.ndarray, cell_x: float, cell_y: float, azimuth: float = 315.0,
              altitude: float = 45.0, z_factor: float = 1.0) -> np.ndarray:
    """Illumination in [0, 1] of the inner cells of ``z`` (a (rows+2, cols+2) padded array).

    Slope and aspect use Horn's 3x3 weights; ``azimuth`` is clockwise from north and ``altitude``
    above the horizon, both in degrees. Rows go north to south. NaN cells give NaN.
    """
    zz = z * z_factor
    a, b, c = zz[:-2, :-2], zz[:-2, 1:-1], zz[:-2, 2:]
    d, f = zz[1:-1, :-2], zz[1:-1, 2:]
    g, h, i = zz[2:, :-2], zz[2:, 1:-1], zz[2:, 2:]
    dz_dx = ((c + 2 * f + i) - (a + 2 * d + g)) / (8.0 * cell_x)  # eastward
    dz_dy = ((a + 2 * b + c) - (g + 2 * h + i)) / (8.0 * cell_y)  # northward
    zenith = np.radians(90.0 - altitude)
    az = np.radians(azimuth)
    # unit normal (-dz/dx, -dz/dy, 1)/n; sun direction (sin az cos alt, cos az cos alt, sin alt)
    norm = np.sqrt(1.0 + dz_dx**2 + dz_dy**2)
    shade = (np.cos(zenith) - np.sin(zenith) * (dz_dx * np.sin(az) + dz_dy * np.cos(az))) / norm
    return np.clip(shade, 0.0, 1.0)
