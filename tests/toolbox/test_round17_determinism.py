"""Round 17, determinism sweep: the same deliverable whatever the execution settings (tiles,
blocks, workers) and on a re-run."""

from __future__ import annotations

import numpy as np


def test_ransac_inliers_do_not_depend_on_the_order_of_the_points():
    # rectify:estimate --ROBUST ransac rejected P26 with the GCP rows in file order and P31
    # with them reversed (exit 0 both, different homographies): OpenCV samples by row number.
    # Truth: 40 points of a known homography, 0.6 m noise, P00-P03 moved 20-40 m
    from toolbox.transforms.plane import TRANSFORMS
    from toolbox.transforms.robust import ransac

    rng = np.random.default_rng(5)
    n = 40
    src = np.column_stack([rng.uniform(0, 2000, n), rng.uniform(0, 2000, n)])
    h = np.array([[0.5, 0.02, 1688000], [-0.01, -0.5, 4800000], [1e-6, 2e-6, 1]])
    p = h @ np.vstack([src.T, np.ones(n)])
    dst = (p[:2] / p[2]).T + rng.normal(0, 0.6, (2, n)).T
    dst[:4, 0] += rng.uniform(20, 40, 4)
    src, dst = np.round(src, 2), np.round(dst, 3) - [1688000.0, 4800000.0]
    cls = TRANSFORMS["homography"]
    first = ransac(cls, src, dst, 1.2)
    assert not first.inliers[:4].any()  # the blunders
    for order in (np.arange(n)[::-1], rng.permutation(n)):
        other = ransac(cls, src[order], dst[order], 1.2)
        np.testing.assert_array_equal(other.inliers, first.inliers[order])
        np.testing.assert_allclose(other.transform.params, first.transform.params, rtol=1e-9)
