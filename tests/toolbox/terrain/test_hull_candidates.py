"""The Akl-Toussaint filter before Qhull (DEM convex-hull masks) keeps every hull vertex and drops
interior points; below HULL_FILTER_MIN_POINTS Qhull takes all points (no compile on a first run)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from toolbox.terrain.gridding import masks


def corner_cloud() -> np.ndarray:
    """60,000 points (above HULL_FILTER_MIN_POINTS: the filter runs) with the exact corners."""
    rng = np.random.default_rng(11)
    xy = rng.uniform(0, 1000, (60_000, 2)) + [1_688_000.0, 4_799_500.0]
    xy[:4] = [[1_688_000.0, 4_799_500.0], [1_689_000.0, 4_799_500.0],
              [1_689_000.0, 4_800_500.0], [1_688_000.0, 4_800_500.0]]
    return xy


def test_filtered_hull_is_qhulls_hull_of_every_point():
    xy = corner_cloud()
    assert len(xy) >= masks.HULL_FILTER_MIN_POINTS
    vertices = ConvexHull(xy).vertices
    assert np.array_equal(masks.hull_vertex_indices(xy), np.sort(vertices))
    ring = masks.convex_hull(xy)
    assert sorted(map(tuple, ring)) == sorted(map(tuple, xy[vertices]))


def test_filter_drops_the_interior():
    # private on purpose: what the filter saves (Qhull's input size) has no public observable
    kept = masks._hull_candidates(corner_cloud())
    assert len(kept) < 60_000 // 10  # most interior points are gone


def test_small_inputs_skip_the_filter():
    xy = np.random.default_rng(2).uniform(0, 10, (1000, 2))
    # private on purpose: the skip (no numba compile for small data) has no public observable
    assert np.array_equal(masks._hull_candidates(xy), np.arange(1000))
    ring = masks.convex_hull(xy)
    assert np.allclose(sorted(map(tuple, ring)), sorted(map(tuple, xy[ConvexHull(xy).vertices])))
