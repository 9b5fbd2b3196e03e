"""Round 17, determinism sweep: the same deliverable whatever the execution settings (tiles,
blocks, workers) and on a re-run."""

from __future__ import annotations

import numpy as np


def test_contours_are_the_same_features_in_the_same_order_with_any_tile_size():
    # carto:contours with TILE_SIZE 8 wrote the same lines as with 512 but in another order
    # (feature 0 was the 310 m line instead of the 290 m one) and rings starting at another
    # vertex, so the GeoPackage differed with the execution setting
    from toolbox.cartography.contours import dem_contours

    yy, xx = np.mgrid[0:60, 0:80].astype("float64")
    z = 300 + 20 * np.sin(xx / 9) * np.cos(yy / 7) + 0.4 * xx
    z[25:29, 30:36] = np.nan  # a hole: open lines ending at it
    levels = np.arange(280.0, 345.0, 5.0)
    whole = dem_contours(z, levels, 1000.0, 2000.0, 1.0, -1.0)
    assert [c.level for c in whole] == sorted(c.level for c in whole)
    for c in whole:
        if c.closed:  # a ring starts at its least vertex (x, then y)
            ring = c.xy[:-1]
            assert tuple(c.xy[0]) == min(map(tuple, ring))
    for tile in (7, 8, 16, 33):
        tiled = dem_contours(z, levels, 1000.0, 2000.0, 1.0, -1.0, tile=tile)
        assert len(tiled) == len(whole)
        for a, b in zip(whole, tiled, strict=True):
            assert a.level == b.level
            np.testing.assert_array_equal(a.xy, b.xy)


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
