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


def test_the_hull_is_qhulls_cycle_and_masks_the_same_cells():
    """GEOS's hull (masks.convex_hull) against Qhull's (scipy, the oracle) on random clouds,
    grids (collinear points along every edge) and rounded coordinates, at Siena's coordinates:
    the same vertices in the same counter-clockwise cycle, so hull_mask gives the same cells
    bit for bit (each edge is interpolated from the same end)."""
    from toolbox.terrain.gridding.masks import hull_mask

    rng = np.random.default_rng(5)
    origin = np.array([1_688_000.0, 4_799_500.0])
    for case in range(60):
        kind = case % 3
        if kind == 0:
            xy = rng.uniform(0, 300, (int(rng.integers(3, 3000)), 2))
        elif kind == 1:
            rows, cols = rng.integers(2, 40, 2)
            xy = np.mgrid[0:rows, 0:cols].reshape(2, -1).T.astype(float) * 0.5
        else:
            xy = np.round(rng.uniform(0, 80, (int(rng.integers(4, 800)), 2)))
        xy = xy + origin
        if np.linalg.matrix_rank(xy - xy.mean(axis=0)) < 2:
            continue
        qhull = xy[ConvexHull(xy).vertices]  # counter-clockwise in 2-D
        ring = masks.convex_hull(xy)
        assert ring is not None and len(ring) == len(qhull), case
        start = int(np.flatnonzero((qhull == ring[0]).all(axis=1))[0])
        assert np.array_equal(np.roll(qhull, -start, axis=0), ring), case
        xs = np.linspace(xy[:, 0].min() - 1, xy[:, 0].max() + 1, 157)
        ys = np.linspace(xy[:, 1].max() + 1, xy[:, 1].min() - 1, 131)
        assert np.array_equal(hull_mask(ring, xs, ys, 1e-9), hull_mask(qhull, xs, ys, 1e-9))
