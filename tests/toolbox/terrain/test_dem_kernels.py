"""DEM gridding kernels on known truth: neighbour search vs cKDTree, exact polynomial surfaces,
IDW properties (eq. 45), fallbacks, sector search, hull masks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from toolbox.terrain.gridding.idw_kernel import idw_grid, idw_loo, nearest_grid
from toolbox.terrain.gridding.masks import convex_hull, hull_mask
from toolbox.terrain.gridding.neighbours import PointBins, grid_knn
from toolbox.terrain.gridding.polynomial import polynomial_grid, polynomial_loo


def scattered(n=3000, seed=0, span=400.0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-span / 2, span / 2, (n, 2))


def grid_axes(step=3.0, half=150.0):
    xs = np.arange(-half, half, step) + step / 2
    ys = (np.arange(-half, half, step) + step / 2)[::-1]  # north-up: row 0 is the top
    return xs, ys


def full_mask(xs, ys):
    return np.ones((len(ys), len(xs)), dtype=bool)


def plane_z(x, y):
    return 312.5 + 0.07 * x - 0.031 * y


def quadratic_z(x, y):
    return 300.0 + 0.05 * x - 0.02 * y + 2e-4 * x * x - 3e-4 * x * y + 1e-4 * y * y


def cubic_z(x, y):
    return quadratic_z(x, y) + 1e-6 * x ** 3 - 2e-6 * x * x * y + 5e-7 * y ** 3


# -- neighbour search ---------------------------------------------------------------------------
@pytest.mark.parametrize("k", [1, 5, 12, 30])
def test_bins_query_matches_kdtree(k):
    xy = scattered(4000, seed=k)
    rng = np.random.default_rng(100 + k)
    q = rng.uniform(-300, 300, (3000, 2))  # also outside the data's box
    d2, idx = PointBins.build(xy).query(q[:, 0], q[:, 1], k)
    dd, ii = cKDTree(xy).query(q, k)
    dd, ii = dd.reshape(len(q), k), ii.reshape(len(q), k)
    np.testing.assert_allclose(np.sqrt(d2), dd, rtol=0, atol=1e-9)
    assert (idx == ii).mean() > 0.999  # only exact ties may be ordered differently
    assert np.allclose(np.hypot(*(xy[idx] - q[:, None, :]).transpose(2, 0, 1)), dd)


def test_bins_query_radius_and_skip():
    xy = scattered(2000, seed=3)
    bins = PointBins.build(xy)
    d2, idx = bins.query(xy[:50, 0], xy[:50, 1], 6, radius=8.0, skip=np.arange(50))
    dd, ii = cKDTree(xy).query(xy[:50], 7, distance_upper_bound=8.0)
    dd, ii = dd[:, 1:], ii[:, 1:]  # drop the point itself (distance 0)
    missing = ~np.isfinite(dd)
    assert (np.isinf(d2) == missing).all() and (idx[missing] == -1).all()
    np.testing.assert_allclose(np.sqrt(d2[~missing]), dd[~missing], atol=1e-9)
    assert not (idx == np.arange(50)[:, None]).any()


def test_grid_knn_block_search_matches_kdtree():
    xy = scattered(5000, seed=7)
    xs, ys = grid_axes(step=1.7, half=210)  # wider than the data: cells outside too
    bins = PointBins.build(xy)
    gx, gy = np.meshgrid(xs, ys)
    dd, _ = cKDTree(xy).query(np.column_stack([gx.ravel(), gy.ravel()]), 12)
    for block in (1, 2, 5, 16):
        d2, idx = grid_knn(bins, xs, ys, 12, block=block)
        np.testing.assert_allclose(np.sqrt(d2.reshape(-1, 12)), dd, atol=1e-9)
        assert (idx >= 0).all()


def test_bins_degenerate_sets():
    line = np.column_stack([np.linspace(0, 10, 11), np.zeros(11)])  # all on y = 0
    d2, idx = PointBins.build(line).query([3.2], [5.0], 2)
    assert list(idx[0]) == [3, 4] and np.isclose(d2[0, 0], 0.2 ** 2 + 25)
    one = PointBins.build(np.array([[5.0, 5.0]]))
    d2, idx = one.query([0.0], [0.0], 3)
    assert idx[0, 0] == 0 and (idx[0, 1:] == -1).all() and np.isinf(d2[0, 1:]).all()
    assert len(PointBins.build(np.zeros((0, 2))).in_rect(0, 0, 1, 1)) == 0


def test_in_rect_is_exact():
    xy = scattered(3000, seed=11)
    bins = PointBins.build(xy)
    got = bins.in_rect(-50.0, -20.0, 35.0, 80.0)
    want = np.flatnonzero((xy[:, 0] >= -50) & (xy[:, 0] <= 35) & (xy[:, 1] >= -20)
                          & (xy[:, 1] <= 80))
    assert np.array_equal(got, want)


# -- local polynomial surfaces (eq. 46-48) ------------------------------------------------------
@pytest.mark.parametrize("order,k", [(1, 8), (2, 12), (3, 20)])
def test_plane_reproduced_exactly_by_every_order(order, k):
    xy = scattered(3000, seed=order)
    xyz = np.column_stack([xy, plane_z(xy[:, 0], xy[:, 1])])
    xs, ys = grid_axes()
    values, used = polynomial_grid(xyz, xs, ys, full_mask(xs, ys), order, k)
    truth = plane_z(xs[None, :], ys[:, None])
    assert np.abs(values - truth).max() < 1e-9
    assert used[order] == values.size and used.sum() == values.size  # no fallback needed


@pytest.mark.parametrize("order,k", [(2, 12), (3, 20)])
def test_quadratic_surface_reproduced_by_quadratic_and_cubic(order, k):
    xy = scattered(3000, seed=5)
    xyz = np.column_stack([xy, quadratic_z(xy[:, 0], xy[:, 1])])
    xs, ys = grid_axes()
    values, _ = polynomial_grid(xyz, xs, ys, full_mask(xs, ys), order, k)
    assert np.abs(values - quadratic_z(xs[None, :], ys[:, None])).max() < 1e-8


def test_plane_does_not_reproduce_a_quadratic_but_cubic_reproduces_a_cubic():
    xy = scattered(3000, seed=9)
    xs, ys = grid_axes()
    quad = np.column_stack([xy, quadratic_z(xy[:, 0], xy[:, 1])])
    plane_fit, _ = polynomial_grid(quad, xs, ys, full_mask(xs, ys), 1, 8)
    assert np.abs(plane_fit - quadratic_z(xs[None, :], ys[:, None])).max() > 1e-3
    cub = np.column_stack([xy, cubic_z(xy[:, 0], xy[:, 1])])
    values, _ = polynomial_grid(cub, xs, ys, full_mask(xs, ys), 3, 20)
    assert np.abs(values - cubic_z(xs[None, :], ys[:, None])).max() < 1e-8


def test_large_projected_coordinates_are_handled_by_centring():
    """The Siena origin (1,688,000 / 4,799,500) without shifting: centring on the cell keeps the
    cubic fit exact (raw monomials x³ ~ 5e18 would lose every digit)."""
    xy = scattered(2000, seed=2, span=200.0) + [1_688_000.0, 4_799_500.0]
    local = xy - [1_688_000.0, 4_799_500.0]
    xyz = np.column_stack([xy, quadratic_z(local[:, 0], local[:, 1])])
    xs, ys = grid_axes(step=4.0, half=80.0)
    values, _ = polynomial_grid(xyz, xs + 1_688_000.0, ys + 4_799_500.0, full_mask(xs, ys), 3, 20)
    assert np.abs(values - quadratic_z(xs[None, :], ys[:, None])).max() < 1e-6


def test_ill_conditioned_neighbourhoods_fall_back_and_are_counted():
    # points on two parallel lines (like two contours): a quadratic is not determined
    # (the product of the two line equations vanishes on every point), a plane is
    x = np.tile(np.linspace(-50, 50, 41), 2)
    y = np.repeat([-5.0, 5.0], 41)
    z = plane_z(x, y)
    xyz = np.column_stack([x, y, z])
    xs = np.array([-10.0, 0.0, 10.0])
    ys = np.array([1.0, 0.0, -1.0])
    values, used = polynomial_grid(xyz, xs, ys, full_mask(xs, ys), 2, 12)
    assert used[2] == 0 and used[1] == 9  # every cell fell back from quadratic to a plane
    assert np.abs(values - plane_z(xs[None, :], ys[:, None])).max() < 1e-9
    # all on one line: even the plane is undetermined -> mean of the neighbours
    line = np.column_stack([np.linspace(-50, 50, 41), np.zeros(41), np.full(41, 7.0)])
    values, used = polynomial_grid(line, xs, ys, full_mask(xs, ys), 1, 8)
    assert used[0] == 9 and np.allclose(values, 7.0)


def test_polynomial_needs_enough_neighbours_within_radius():
    xy = scattered(400, seed=4, span=200)
    xyz = np.column_stack([xy, plane_z(xy[:, 0], xy[:, 1])])
    xs, ys = grid_axes(step=10.0, half=90.0)
    values, used = polynomial_grid(xyz, xs, ys, full_mask(xs, ys), 2, 12, radius=12.0)
    # few points within 12 m: lower orders are used and counted (mean where only 1-2 points)
    assert used[0] > 0 and used[1] > 0 and used[2] > 0
    assert used.sum() == np.isfinite(values).sum()
    strict, used3 = polynomial_grid(xyz, xs, ys, full_mask(xs, ys), 2, 12, radius=12.0,
                                    min_neighbours=3)
    ok = np.isfinite(strict)
    assert used3[0] == 0 and ok.sum() < np.isfinite(values).sum()
    # with >= 3 points every fit is a plane or better: exact for a plane (to 1e-6 m, far below
    # the float32 output's resolution; a nearly degenerate quadratic amplifies rounding by
    # about 1 / MIN_RCOND² in the normal equations)
    assert np.abs(strict - plane_z(xs[None, :], ys[:, None]))[ok].max() < 1e-6


# -- IDW (eq. 45) and nearest -----------------------------------------------------------------
def test_idw_matches_eq45_by_hand():
    # cell centre at the origin; points at distances 1, 2, 4 with heights 10, 20, 40
    xyz = np.array([[1.0, 0.0, 10.0], [0.0, -2.0, 20.0], [-4.0, 0.0, 40.0]])
    xs, ys, mask = np.array([0.0]), np.array([0.0]), np.ones((1, 1), bool)
    p1 = idw_grid(xyz, xs, ys, mask, neighbours=3, power=1.0)[0, 0]
    assert p1 == pytest.approx((10 / 1 + 20 / 2 + 40 / 4) / (1 / 1 + 1 / 2 + 1 / 4))  # eq. 45
    p2 = idw_grid(xyz, xs, ys, mask, neighbours=3, power=2.0)[0, 0]
    assert p2 == pytest.approx((10 + 20 / 4 + 40 / 16) / (1 + 1 / 4 + 1 / 16))
    assert idw_grid(xyz, xs, ys, mask, neighbours=2, power=1.0)[0, 0] == pytest.approx(
        (10 + 10) / 1.5)


def test_idw_exact_at_data_points_and_within_data_range():
    rng = np.random.default_rng(21)
    # points on cell centres of a 2 m grid (every 5th), noisy heights
    xs, ys = grid_axes(step=2.0, half=100.0)
    gx, gy = np.meshgrid(xs, ys)
    pick = rng.random(gx.size) < 0.2
    z = rng.normal(300, 25, pick.sum())
    xyz = np.column_stack([gx.ravel()[pick], gy.ravel()[pick], z])
    for power in (1.0, 2.0, 3.5):
        values = idw_grid(xyz, xs, ys, full_mask(xs, ys), neighbours=12, power=power)
        assert np.array_equal(values.ravel()[pick], z)  # exact at the data
        assert values.min() >= z.min() and values.max() <= z.max()
    nearest = nearest_grid(xyz, xs, ys, full_mask(xs, ys))
    one = idw_grid(xyz, xs, ys, full_mask(xs, ys), neighbours=1)
    assert np.array_equal(nearest, one) and np.isin(nearest, z).all()


def test_nearest_takes_the_nearest_points_height():
    xy = scattered(500, seed=8)
    z = np.arange(500, dtype=float)
    xs, ys = grid_axes(step=7.0)
    values = nearest_grid(np.column_stack([xy, z]), xs, ys, full_mask(xs, ys))
    gx, gy = np.meshgrid(xs, ys)
    _, idx = cKDTree(xy).query(np.column_stack([gx.ravel(), gy.ravel()]))
    assert np.array_equal(values.ravel(), z[idx])


def test_idw_sector_search_balances_one_sided_data():
    # 20 points close to the east of the cell at height 100, 4 farther west at height 0
    east = np.column_stack([np.linspace(1, 2, 20), np.linspace(-0.5, 0.5, 20), np.full(20, 100.0)])
    west = np.array([[-5.0, 0.5, 0.0], [-5.0, -0.5, 0.0], [-5.5, 0.0, 0.0], [-6.0, 0.2, 0.0]])
    xyz = np.vstack([east, west])
    xs, ys, mask = np.array([0.0]), np.array([0.0]), np.ones((1, 1), bool)
    plain = idw_grid(xyz, xs, ys, mask, neighbours=8, power=1.0)[0, 0]
    assert plain == 100.0  # the 8 nearest are all east
    sectors = idw_grid(xyz, xs, ys, mask, neighbours=8, power=1.0, radius=10.0, sectors=4)[0, 0]
    assert 0.0 < sectors < 90.0  # the western sector now contributes
    # by hand: 2 nearest per sector; east sectors (0 and 3 contain the east points)
    d = np.hypot(xyz[:, 0], xyz[:, 1])
    ang = np.mod(np.arctan2(xyz[:, 1], xyz[:, 0]), 2 * np.pi)
    sec = np.minimum((ang * 4 / (2 * np.pi)).astype(int), 3)
    chosen = np.concatenate([np.flatnonzero(sec == s)[np.argsort(d[sec == s])][:2]
                             for s in range(4)])
    want = np.sum(xyz[chosen, 2] / d[chosen]) / np.sum(1 / d[chosen])
    assert sectors == pytest.approx(want)


def test_idw_radius_min_neighbours_and_max_distance():
    xyz = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 2.0], [0.0, 10.0, 3.0]])
    xs, ys = np.array([1.0, 30.0]), np.array([1.0])
    mask = np.ones((1, 2), bool)
    v = idw_grid(xyz, xs, ys, mask, neighbours=3, radius=5.0)
    assert v[0, 0] == 1.0 and np.isnan(v[0, 1])  # only one point within 5 m; none for x = 30
    v = idw_grid(xyz, xs, ys, mask, neighbours=3, radius=5.0, min_neighbours=2)
    assert np.isnan(v).all()
    v = idw_grid(xyz, xs, ys, mask, neighbours=3, max_distance=20.0)
    assert np.isfinite(v[0, 0]) and np.isnan(v[0, 1])  # nearest point of x = 30 is 20.02 m away


def test_masked_cells_stay_nan():
    xy = scattered(300, seed=1)
    xyz = np.column_stack([xy, plane_z(xy[:, 0], xy[:, 1])])
    xs, ys = grid_axes(step=20.0)
    mask = full_mask(xs, ys)
    mask[::2] = False
    for values in (idw_grid(xyz, xs, ys, mask), polynomial_grid(xyz, xs, ys, mask, 2, 12)[0]):
        assert np.isnan(values[~mask]).all() and np.isfinite(values[mask]).all()


# -- leave-one-out kernels ---------------------------------------------------------------------
def test_loo_kernels_match_brute_force():
    xy = scattered(400, seed=12, span=100)
    z = quadratic_z(xy[:, 0], xy[:, 1]) + np.random.default_rng(3).normal(0, 0.1, 400)
    bins = PointBins.build(xy)
    targets = np.arange(400)
    got = idw_loo(bins, z, targets, neighbours=6, power=2.0)
    dd, ii = cKDTree(xy).query(xy, 7)
    w = 1 / dd[:, 1:] ** 2
    want = np.sum(w * z[ii[:, 1:]], axis=1) / w.sum(axis=1)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    pred, used = polynomial_loo(bins, z, targets, order=1, neighbours=8)
    i = 17
    nb = cKDTree(xy).query(xy[i], 9)[1][1:]
    a = np.column_stack([np.ones(8), xy[nb, 0] - xy[i, 0], xy[nb, 1] - xy[i, 1]])
    coef = np.linalg.lstsq(a, z[nb], rcond=None)[0]
    assert pred[i] == pytest.approx(coef[0], abs=1e-9) and used[i] == 1


# -- masks ------------------------------------------------------------------------------------
def test_hull_mask_matches_shapely_and_includes_the_boundary():
    import shapely

    rng = np.random.default_rng(4)
    xy = rng.normal(0, 30, (200, 2))
    ring = convex_hull(xy)
    xs, ys = grid_axes(step=2.5, half=110)
    mask = hull_mask(ring, xs, ys)
    gx, gy = np.meshgrid(xs, ys)
    want = shapely.contains_xy(shapely.Polygon(ring), gx, gy)
    assert np.array_equal(mask, want) or (mask != want).sum() <= 2  # centres on the edge
    # a square hull whose edges pass through cell centres: those centres are inside
    square = convex_hull(np.array([[0.5, 0.5], [9.5, 0.5], [9.5, 9.5], [0.5, 9.5]]))
    centres = np.arange(10) + 0.5
    m = hull_mask(square, centres, centres[::-1], tol=1e-9)
    assert m.all()
    assert convex_hull(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])) is None
    assert math.isclose(float(hull_mask(square, np.array([9.6]), np.array([5.0]))[0, 0]), 0.0)
