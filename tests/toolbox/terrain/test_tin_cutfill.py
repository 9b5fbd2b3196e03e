"""Cut/fill volumes: exact on prisms and pyramids, clipped by masks, on grids."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from toolbox.terrain.tin.cutfill import grid_cut_fill, plane_cut_fill, positive_part

X0, Y0 = 1_688_000.0, 4_799_500.0


def pyramid(height: float = 6.0, base: float = 10.0):
    """Square pyramid: base corners at z = 0, apex at the centre; volume = base^2 * h / 3."""
    xyz = np.array([[0, 0, 0], [base, 0, 0], [base, base, 0], [0, base, 0],
                    [base / 2, base / 2, height]], dtype=float) + [X0, Y0, 0.0]
    triangles = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    return xyz, triangles


def test_pyramid_volume_is_exact():
    xyz, tri = pyramid()
    r = plane_cut_fill(xyz, tri, 0.0)
    assert r.cut_volume == pytest.approx(200.0, rel=1e-12)
    assert r.fill_volume == 0.0 and r.area == pytest.approx(100.0)
    # a plane at mid-height: the top pyramid is (1/2)^3 of the whole; the rest is fill
    r = plane_cut_fill(xyz, tri, 3.0)
    assert r.cut_volume == pytest.approx(25.0, rel=1e-12)
    assert r.fill_volume == pytest.approx(300.0 - 200.0 + 25.0, rel=1e-12)
    assert r.cut_area == pytest.approx(25.0, rel=1e-12)  # the top's footprint: 5 x 5
    assert r.fill_area == pytest.approx(75.0, rel=1e-12)
    assert r.net_volume == pytest.approx(200.0 - 300.0, rel=1e-12)


def test_prism_volume_is_exact():
    xyz, tri = pyramid()
    xyz[:, 2] = 5.0  # a flat TIN: a prism over the plane z = 2
    r = plane_cut_fill(xyz, tri, 2.0)
    assert r.cut_volume == pytest.approx(300.0) and r.fill_volume == 0.0
    r = plane_cut_fill(xyz, tri, 7.5)
    assert r.fill_volume == pytest.approx(250.0) and r.cut_volume == 0.0


def test_mask_clips_triangles_exactly():
    xyz, tri = pyramid()
    half = shapely.box(X0 - 5, Y0 - 5, X0 + 5, Y0 + 20)  # the west half of the base
    assert plane_cut_fill(xyz, tri, 0.0, half).cut_volume == pytest.approx(100.0, rel=1e-12)
    quarter = shapely.box(X0 + 5, Y0 + 5, X0 + 10, Y0 + 10)
    r = plane_cut_fill(xyz, tri, 3.0, quarter)
    assert r.cut_volume == pytest.approx(25.0 / 4, rel=1e-12)
    assert r.area == pytest.approx(25.0)
    # a mask with a hole, checked against a fine midpoint grid
    ring = shapely.Polygon([(X0 + 1, Y0 + 1), (X0 + 9, Y0 + 2), (X0 + 8, Y0 + 9), (X0 + 2, Y0 + 8)],
                           [[(X0 + 4, Y0 + 4), (X0 + 6, Y0 + 4.5), (X0 + 5, Y0 + 6)]])
    r = plane_cut_fill(xyz, tri, 2.0, ring)
    n = 2000
    c = (np.arange(n) + 0.5) * 10.0 / n
    gx, gy = np.meshgrid(c, c)
    apex_dist = np.maximum(np.abs(gx - 5), np.abs(gy - 5))
    h = 6.0 * (1 - apex_dist / 5.0) - 2.0
    inside = shapely.contains_xy(ring, gx + X0, gy + Y0)
    cell = (10.0 / n) ** 2
    assert r.cut_volume == pytest.approx(h[inside & (h > 0)].sum() * cell, rel=2e-4)
    assert r.fill_volume == pytest.approx(-h[inside & (h < 0)].sum() * cell, rel=2e-3)
    assert r.area == pytest.approx(ring.area, rel=1e-12)


def test_positive_part_against_brute_force():
    rng = np.random.default_rng(3)
    h = rng.normal(0, 1, (200, 3))
    area = np.ones(200)
    pos_area, pos_vol = positive_part(h, area)
    # brute force on barycentric samples of a unit-area triangle
    n = 400
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    keep = i + j < n
    u, v = (i[keep] + 1 / 3) / n, (j[keep] + 1 / 3) / n
    for k in (0, 1, 7, 42):
        val = h[k, 0] * (1 - u - v) + h[k, 1] * u + h[k, 2] * v
        assert pos_vol[k] == pytest.approx(np.maximum(val, 0).mean(), abs=5e-3)
        assert pos_area[k] == pytest.approx((val > 0).mean(), abs=5e-3)
    neg_area, neg_vol = positive_part(-h, area)
    np.testing.assert_allclose(pos_vol - neg_vol, h.mean(axis=1), atol=1e-12)
    np.testing.assert_allclose(pos_area + neg_area, 1.0, atol=1e-12)


def test_grid_cut_fill_counts_cells():
    tin = np.array([[1.0, 2.0], [np.nan, -1.0]])
    ref = np.zeros((2, 2))
    r = grid_cut_fill(tin, ref, 4.0)
    assert (r.cut_volume, r.fill_volume, r.cut_area, r.fill_area, r.area) == (12.0, 4.0, 8.0,
                                                                               4.0, 12.0)
    r = grid_cut_fill(tin, ref, 4.0, inside=np.array([[True, False], [True, True]]))
    assert r.cut_volume == 4.0 and r.area == 8.0
