"""The one bilinear height sampler against scipy's RegularGridInterpolator, and the DEM surface
of monoplotting on it (north-up: rows go south)."""

from __future__ import annotations

import numpy as np
from affine import Affine
from scipy.interpolate import RegularGridInterpolator

from toolbox.photogrammetry.surface import DemSurface
from toolbox.raster.bilinear import bilinear

X0, Y0, CELL = 1_688_000.0, 4_799_500.0, 2.0


def test_bilinear_equals_scipy_inside_and_is_nan_outside():
    rng = np.random.default_rng(3)
    z = rng.normal(300, 20, (23, 31))
    x0, y0 = X0 + 1, Y0 - 1  # centre of cell (0, 0); rows go south
    xs, ys = x0 + CELL * np.arange(31), y0 - CELL * np.arange(23)
    pts = np.column_stack([rng.uniform(xs[0], xs[-1], 500), rng.uniform(ys[-1], ys[0], 500)])
    oracle = RegularGridInterpolator((ys[::-1], xs), z[::-1], method="linear")
    got = bilinear(z, x0, y0, CELL, -CELL, pts)
    np.testing.assert_allclose(got, oracle(pts[:, ::-1]), rtol=1e-12)
    outside = np.array([[xs[0] - 0.1, ys[0]], [xs[-1], ys[-1] - 0.1]])
    assert np.isnan(bilinear(z, x0, y0, CELL, -CELL, outside)).all()
    z[5, 5] = np.nan  # a nodata cell spoils the four cells around it only
    near = np.array([[xs[5] + 0.5, ys[5] - 0.5], [xs[8] + 0.5, ys[8] - 0.5]])
    h = bilinear(z, x0, y0, CELL, -CELL, near)
    assert np.isnan(h[0]) and np.isfinite(h[1])


def test_dem_surface_height_is_the_bilinear_sampler():
    z = np.add.outer(-0.3 * np.arange(12), 0.2 * np.arange(15)) + 250.0  # a plane
    surface = DemSurface.from_transform(z, Affine(CELL, 0, X0, 0, -CELL, Y0))
    x = X0 + CELL / 2 + np.array([0.0, 3.3, 20.1])
    y = Y0 - CELL / 2 - np.array([0.0, 7.7, 15.0])
    expected = 250.0 + 0.2 * (x - X0 - 1) / CELL - 0.3 * (Y0 - 1 - y) / CELL
    np.testing.assert_allclose(surface.height(x, y), expected, rtol=1e-12)
