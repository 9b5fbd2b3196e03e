"""OrthoReference.sample: bilinear grey values at ground coordinates, checked against scipy's
map_coordinates on the same raster (an independent interpolator), NaN outside and at nodata."""

from __future__ import annotations

import numpy as np
import rasterio
from affine import Affine
from scipy import ndimage

from toolbox.matching.ortho_match import OrthoReference


def test_sample_is_bilinear_at_ground_coordinates_and_nan_at_nodata(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.integers(1, 255, (3, 60, 80)).astype("uint8")
    rgb[:, 40:, 60:] = 0  # nodata corner
    transform = Affine(0.5, 0, 1688000.0, 0, -0.5, 4799000.0)
    path = tmp_path / "ortho.tif"
    with rasterio.open(path, "w", driver="GTiff", width=80, height=60, count=3, dtype="uint8",
                       crs="EPSG:3003", transform=transform, nodata=0) as dst:
        dst.write(rgb)
    ortho = OrthoReference.open(path)
    col = rng.uniform(0.0, 58.0, 200)
    row = rng.uniform(0.0, 38.0, 200)  # pixel-centre coordinates, away from the nodata
    x = transform.c + (col + 0.5) * transform.a
    y = transform.f + (row + 0.5) * transform.e
    grey = rgb.astype("float64").mean(axis=0)
    expected = ndimage.map_coordinates(grey, [row, col], order=1)
    assert np.allclose(ortho.sample(x, y), expected, atol=1e-3)
    # next to nodata, and outside the raster: NaN (a chip touching them is not matched)
    inside_nodata = ortho.sample(np.array([transform.c + 70 * 0.5]),
                                 np.array([transform.f - 50 * 0.5]))
    outside = ortho.sample(np.array([transform.c - 10.0]), np.array([transform.f + 10.0]))
    assert np.isnan(inside_nodata).all() and np.isnan(outside).all()
