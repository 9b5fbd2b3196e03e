"""The compiled seam kernels against the libraries they replace: the A* route against
scikit-image's MCP_Geometric (the optimum's cost), the image terms against scipy's Sobel, the
radius mask against scipy's Euclidean distance transform; coarse-to-fine against the optimum."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from skimage.graph import MCP_Geometric

from toolbox.mosaic.kernels import image_cost, within_radius
from toolbox.mosaic.route import coarse_to_fine, least_cost_path, path_cost


def mcp_optimum(cost, start, end):
    mcp = MCP_Geometric(cost, fully_connected=True)
    cumulative, _ = mcp.find_costs([start], [end])
    return float(cumulative[end]), np.asarray(mcp.traceback(end))


def assert_walk(cost, path, start, end):
    """An 8-connected walk over passable cells from start to end."""
    assert tuple(path[0]) == tuple(start) and tuple(path[-1]) == tuple(end)
    steps = np.abs(np.diff(path, axis=0))
    assert steps.max() == 1 and (steps.sum(axis=1) > 0).all()
    assert (cost[path[:, 0], path[:, 1]] >= 0).all()


@pytest.mark.parametrize("seed", range(6))
def test_route_cost_equals_the_mcp_optimum_on_random_surfaces(seed):
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(20, 120, size=2)
    cost = rng.uniform(0.05, 3.0, (rows, cols)) ** rng.uniform(1, 3)
    cost[rng.random((rows, cols)) < 0.25] = -1.0  # a quarter impassable
    start = (0, int(rng.integers(cols)))
    end = (rows - 1, int(rng.integers(cols)))
    cost[start] = cost[end] = 1.0
    best, mcp_path = mcp_optimum(cost, start, end)
    path, total = least_cost_path(cost, start, end)
    if not np.isfinite(best):
        assert path is None and total == np.inf
        return
    assert total == pytest.approx(best, rel=1e-9)
    assert_walk(cost, path, start, end)
    # the path is what it claims, measured as MCP measures its own path
    assert path_cost(cost, path) == pytest.approx(best, rel=1e-9)
    assert path_cost(cost, mcp_path) == pytest.approx(best, rel=1e-9)


def test_route_through_a_wall_is_none():
    cost = np.ones((30, 30))
    cost[:, 15] = -1.0
    assert least_cost_path(cost, (0, 0), (29, 29)) == (None, np.inf)
    cost[29, 15] = 5.0  # one gap, at the far end: the route must use it
    path, total = least_cost_path(cost, (0, 0), (0, 29))
    assert (29, 15) in set(map(tuple, path))
    assert total == pytest.approx(mcp_optimum(cost, (0, 0), (0, 29))[0], rel=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_coarse_to_fine_is_near_the_optimum_on_smooth_surfaces(seed):
    rng = np.random.default_rng(100 + seed)
    field = ndimage.gaussian_filter(rng.normal(size=(400, 300)), 6)
    cost = 0.1 + np.abs(field) / np.abs(field).max()
    cost[150:250, :200] = -1.0  # a block to go round
    start, end = (0, 150), (399, 150)
    best, _ = mcp_optimum(cost, start, end)
    path = coarse_to_fine(cost, start, end, factor=4)
    assert_walk(cost, path, start, end)
    assert best - 1e-9 <= path_cost(cost, path) <= 1.005 * best


def test_coarse_to_fine_finds_a_passage_the_overview_misses():
    # one-cell gaps in a wall: overview blocks of 8 x 8 average over them, and the corridor
    # may not hold the optimum, but the result is always a valid path (full search fallback)
    cost = np.ones((200, 200))
    cost[100, :] = -1.0
    cost[100, 3] = 1.0
    path = coarse_to_fine(cost, (0, 190), (199, 190), factor=8)
    assert_walk(cost, path, (0, 190), (199, 190))
    assert (100, 3) in set(map(tuple, path))


def _scipy_terms(a, b, scale):
    """diff, grad, gdiff of the seam cost from numpy and scipy's Sobel (the oracle)."""
    ma, mb = a.astype("float64").mean(axis=0), b.astype("float64").mean(axis=0)
    sa = [ndimage.sobel(ma, axis=k, mode="reflect") / 8 for k in (0, 1)]
    sb = [ndimage.sobel(mb, axis=k, mode="reflect") / 8 for k in (0, 1)]
    diff = np.abs(a.astype("float64") - b).mean(axis=0) * scale
    grad = np.maximum(np.hypot(*sa), np.hypot(*sb)) * scale
    return diff, grad, np.hypot(sa[0] - sb[0], sa[1] - sb[1]) * scale


@pytest.mark.parametrize("shape", [(1, 70, 90), (3, 70, 90), (1, 7, 9), (4, 1, 5), (2, 33, 3)])
@pytest.mark.parametrize("workers", [1, 2])
def test_image_cost_equals_scipy_sobel_terms(shape, workers):
    rng = np.random.default_rng(sum(shape))
    a = rng.uniform(0, 4000, shape).astype("float32")
    b = (a + rng.normal(0, 300, a.shape)).astype("float32")
    scale = 1 / 173.3
    diff, grad, gdiff = _scipy_terms(a, b, scale)
    for w_diff, base, w_grad in ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.3, 0.07, 2.5)):
        cost, gdiff2 = image_cost(a, b, scale, w_diff, base, w_grad, workers=workers)
        np.testing.assert_allclose(cost, base + w_diff * diff + w_grad * grad, rtol=1e-9,
                                   atol=1e-12)
        np.testing.assert_allclose(gdiff2, gdiff, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(("density", "radius"), [(0.0, 3.0), (0.001, 20.0), (0.02, 4.5),
                                                 (0.3, 1.0), (1.0, 2.0)])
def test_within_radius_equals_scipy_edt(density, radius):
    rng = np.random.default_rng(int(density * 1000))
    mask = rng.random((90, 130)) < density
    expected = ndimage.distance_transform_edt(~mask) <= radius if mask.any() else \
        np.zeros(mask.shape, bool)
    assert np.array_equal(within_radius(mask, radius), expected)


def test_kernels_in_row_bands_on_threads_equal_one_call(monkeypatch):
    """Bands of rows on threads (the banded kernels write rows of shared arrays; each band's
    Sobel reads its neighbours' rows) give the one call's arrays bit for bit, and scipy's."""
    import toolbox.executor

    rng = np.random.default_rng(11)
    a = rng.uniform(0, 255, (3, 61, 47)).astype("float32")
    b = (a + rng.normal(0, 20, a.shape)).astype("float32")
    mask = rng.random((61, 47)) < 0.01
    whole = image_cost(a, b, 0.01, 1.0, 0.1, 1.0, workers=1), within_radius(mask, 6.0, workers=1)
    monkeypatch.setattr(toolbox.executor, "ROW_BAND_MIN_CELLS", 100)
    calls = []
    real = toolbox.executor.in_row_bands
    monkeypatch.setattr(toolbox.executor, "in_row_bands",
                        lambda task, rows, *args, **kw: real(
                            lambda r0, r1: (calls.append((r0, r1)), task(r0, r1)), rows,
                            *args, **kw))
    for workers in (2, 3, 7):
        calls.clear()
        terms = image_cost(a, b, 0.01, 1.0, 0.1, 1.0, workers=workers)
        near = within_radius(mask, 6.0, workers=workers)
        assert len(calls) == 3 * workers  # every kernel split: image terms, columns, rows
        for banded, one in zip(terms, whole[0], strict=True):
            assert np.array_equal(banded, one)
        assert np.array_equal(near, whole[1])
    assert np.array_equal(whole[1], ndimage.distance_transform_edt(~mask) <= 6.0)


def test_overview_is_the_block_mean_of_passable_cells():
    from toolbox.mosaic.route import overview

    rng = np.random.default_rng(7)
    cost = rng.uniform(0.1, 2.0, (10, 7))
    cost[0:3, 0:3] = -1.0  # a whole block impassable
    cost[5, 4] = -1.0
    small = overview(cost, 3)
    assert small.shape == (4, 3)
    assert small[0, 0] == -1.0
    assert small[1, 1] == pytest.approx(np.mean([cost[r, c] for r in range(3, 6)
                                                 for c in range(3, 6) if (r, c) != (5, 4)]))
    assert small[3, 2] == pytest.approx(cost[9, 6])  # the partial corner block


def test_compiled_centre_term_equals_the_numpy_one():
    from affine import Affine

    from toolbox.mosaic.seams import add_centre, centre_term

    transform = Affine(0.5, 0, 1_688_100.0, 0, -0.5, 4_799_300.0)  # large projected coordinates
    a, b = (1_688_120.0, 4_799_250.0), (1_688_160.0, 4_799_210.0)
    cost = np.full((80, 120), 0.1)
    add_centre(cost, transform, a, b, 0.5)
    np.testing.assert_allclose(cost, 0.1 + 0.5 * centre_term(transform, (80, 120), a, b),
                               rtol=0, atol=1e-9)
