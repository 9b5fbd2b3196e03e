"""Round 19 (seamspeed): structured_near's groups of strong cells by OpenCV's connected
components are scipy's 8-connected labels (ndimage.label with a 3 x 3 structure): the same
cells within the radius of the groups large enough, on random gradient differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from toolbox.mosaic.seams import structured_near


def _by_scipy(gradient_difference, threshold, radius):
    strong = gradient_difference > threshold
    groups, n = ndimage.label(strong, structure=np.ones((3, 3), bool))
    sizes = np.bincount(groups.ravel(), minlength=n + 1)
    keep = sizes >= max(3.0, radius / 2.0)
    keep[0] = False
    kept = keep[groups]
    if not kept.any():
        return kept
    return ndimage.distance_transform_edt(~kept) <= radius


@pytest.mark.parametrize("seed", range(6))
def test_structured_near_equals_scipy_labels_and_edt(seed):
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(1, 90, 2)
    # blobs of several sizes (diagonal contacts join groups only 8-connected) and noise
    g = rng.random((rows, cols)) * 0.3
    for _ in range(rng.integers(0, 12)):
        r, c = rng.integers(0, rows), rng.integers(0, cols)
        h, w = rng.integers(1, 6, 2)
        g[r:r + h, c:c + w] = 1.0
    g[rng.random((rows, cols)) < 0.02] = 0.9
    for threshold, radius in ((0.5, 0.0), (0.5, 3.0), (0.5, 9.0), (0.25, 2.5), (0.95, 4.0)):
        expected = _by_scipy(g, threshold, radius)
        assert np.array_equal(structured_near(g, threshold, radius), expected)


def test_diagonal_cells_are_one_group():
    """Two 2-cell pieces touching at a corner: one group of 4 (8-connected), kept at a size
    threshold of 4 (radius 8); two groups of 2 each when only 4-connected, dropped."""
    g = np.zeros((10, 10))
    g[2, 2] = g[2, 3] = g[3, 4] = g[3, 5] = 1.0
    assert structured_near(g, 0.5, 8.0).any()
    assert np.array_equal(structured_near(g, 0.5, 8.0), _by_scipy(g, 0.5, 8.0))
