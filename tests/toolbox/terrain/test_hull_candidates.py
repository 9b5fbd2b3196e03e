"""The Akl-Toussaint filter before Qhull (DEM convex-hull masks) keeps every hull vertex and drops
interior points; below HULL_FILTER_MIN_POINTS Qhull takes all points (no compile on a first run)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from toolbox.terrain.gridding import masks


def test_filter_keeps_every_hull_vertex_and_drops_the_interior():
    rng = np.random.default_rng(11)
    xy = rng.uniform(0, 1000, (5000, 2)) + [1_688_000.0, 4_799_500.0]
    xy[:4] = [[1_688_000.0, 4_799_500.0], [1_689_000.0, 4_799_500.0],
              [1_689_000.0, 4_800_500.0], [1_688_000.0, 4_800_500.0]]  # exact corners
    kept = masks._akl_toussaint(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]))
    vertices = ConvexHull(xy).vertices
    assert set(vertices) <= set(kept)
    assert len(kept) < len(xy) // 10  # most interior points are gone


def test_small_inputs_skip_the_filter():
    xy = np.random.default_rng(2).uniform(0, 10, (1000, 2))
    assert np.array_equal(masks._hull_candidates(xy), np.arange(1000))
    ring = masks.convex_hull(xy)
    assert np.allclose(sorted(map(tuple, ring)), sorted(map(tuple, xy[ConvexHull(xy).vertices])))
