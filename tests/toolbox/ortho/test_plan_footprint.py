"""The footprint's point-in-polygon test of ortho planning (toolbox.ortho.plan.inside_polygon,
NumPy's even-odd rule: planning a photo no longer imports shapely) against shapely's
contains_xy, and the mean height under a footprint against a direct mean of the cells shapely
finds inside."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from affine import Affine

from toolbox.ortho.plan import inside_polygon, mean_height_inside
from toolbox.photogrammetry.surface import DemSurface


def star(seed: int, n: int) -> np.ndarray:
    """A simple, star-shaped (non-convex) polygon of ``n`` vertices with heights."""
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0, 2 * np.pi, n))
    radii = rng.uniform(40, 100, n)
    return np.column_stack([radii * np.cos(angles) + 500, radii * np.sin(angles) - 300,
                            rng.uniform(0, 50, n)])


@pytest.mark.parametrize(("seed", "n"), [(1, 4), (2, 9), (3, 32), (4, 64)])
def test_inside_polygon_equals_shapely(seed, n):
    vertices = star(seed, n)
    # cell centres off the vertices' coordinates: no point on an edge
    xs, ys = np.arange(380.13, 620, 0.7), np.arange(-180.37, -420, -0.9)
    xx, yy = np.meshgrid(xs, ys)
    ours = inside_polygon(xs, ys, vertices)
    truth = shapely.contains_xy(shapely.Polygon(vertices), xx, yy)
    assert truth.any() and not truth.all()
    np.testing.assert_array_equal(ours, truth)
    # a closed ring (last vertex = first) gives the same
    np.testing.assert_array_equal(inside_polygon(xs, ys, np.vstack([vertices, vertices[:1]])),
                                  truth)


def test_mean_height_inside_a_footprint():
    vertices = star(5, 40)
    rng = np.random.default_rng(7)
    z = rng.uniform(100, 200, (300, 280))
    z[::7, ::5] = np.nan  # no height: left out
    surface = DemSurface.from_transform(z, Affine(0.9, 0, 380.05, 0, -0.8, -180.2), None)
    xx, yy = np.meshgrid(surface.x0 + np.arange(280) * surface.cell_x,
                         surface.y0 - np.arange(300) * surface.cell_y)
    inside = shapely.contains_xy(shapely.Polygon(vertices), xx, yy) & np.isfinite(z)
    assert inside.sum() > 1000
    assert mean_height_inside(surface, vertices) == pytest.approx(z[inside].mean(), rel=1e-12)
