"""The per-cell fusion of dem:match against numpy (median, quantile) group by group, and the
ground filter's openings against a brute-force minimum/maximum."""

from __future__ import annotations

import numpy as np
from affine import Affine

from toolbox.stereo.fusion import cell_index, fuse, group_quantiles, pair_cells


def test_group_quantiles_match_numpy():
    rng = np.random.default_rng(3)
    keys = rng.integers(0, 40, 500)
    values = rng.normal(300, 5, 500)
    cells, median, q25, q75, counts = group_quantiles(keys, values)
    for k, m, a, b, n in zip(cells, median, q25, q75, counts, strict=True):
        group = values[keys == k]
        assert n == len(group)
        assert np.isclose(m, np.median(group))
        assert np.isclose(a, np.quantile(group, 0.25)) and np.isclose(b, np.quantile(group, 0.75))


def test_group_quantiles_large_keys_ties_and_a_constant_group():
    """Cell indices near 2^31 (the combined sort key's worst case), tied heights, heights
    1 mm apart, one group of equal values: still numpy's quantiles group by group (to 0.1 mm)."""
    rng = np.random.default_rng(5)
    keys = rng.choice(np.array([0, 7, 2**31 - 2, 2**31 - 1, 123_456_789]), 4000)
    values = np.round(rng.normal(300, 20, 4000), 3)  # mm steps: ties and near-ties
    values[keys == 7] = 312.5
    cells, median, q25, q75, counts = group_quantiles(keys, values)
    assert list(cells) == sorted(set(keys.tolist()))
    for k, m, a, b, n in zip(cells, median, q25, q75, counts, strict=True):
        group = values[keys == k]
        assert n == len(group)
        np.testing.assert_allclose([a, m, b], np.quantile(group, [0.25, 0.5, 0.75]), atol=1e-4)


def test_fuse_two_pairs():
    t = Affine(2.0, 0, 1000.0, 0, -2.0, 2000.0)  # 5 x 4 cells of 2 m
    rng = np.random.default_rng(5)
    pts = [np.column_stack([rng.uniform(1000, 1010, 300), rng.uniform(1992, 2000, 300),
                            rng.normal(h, 1.0, 300)]) for h in (100.0, 104.0)]
    pts[1] = pts[1][pts[1][:, 0] < 1006]  # the second pair sees only the west part
    dsm, count, spread = fuse([pair_cells(p, t, 5, 4) for p in pts], 5, 4)
    for row in range(4):
        for col in range(5):
            per_pair = []
            for p in pts:
                flat, inside = cell_index(p, t, 5, 4)
                z = p[inside & (flat == row * 5 + col), 2]
                if len(z):
                    per_pair.append(z)
            assert count[row, col] == len(per_pair)
            assert np.isclose(dsm[row, col], np.median([np.median(z) for z in per_pair]),
                              atol=1e-4)
            want = max(np.quantile(z, 0.75) for z in per_pair) - \
                min(np.quantile(z, 0.25) for z in per_pair)
            assert np.isclose(spread[row, col], want, atol=1e-4)
    assert (count[:, :3] == 2).all() and (count[:, 3:] == 1).all()


def test_fuse_leaves_cells_without_points_empty():
    t = Affine(1.0, 0, 0.0, 0, -1.0, 10.0)
    dsm, count, spread = fuse([pair_cells(np.array([[0.5, 9.5, 7.0]]), t, 10, 10)], 10, 10)
    assert np.isfinite(dsm).sum() == 1 and dsm[0, 0] == 7.0 and count.sum() == 1
    assert spread[0, 0] == 0.0 and np.isnan(spread).sum() == 99


def test_epipolar_map_lattice_agrees_with_the_exact_map():
    import sys
    from pathlib import Path

    from rasterio.windows import Window

    from toolbox.raster.tile import Tile
    from toolbox.stereo.epipolar import EpipolarMap, epipolar_geometry

    sys.path.insert(0, str(Path(__file__).parents[2] / "algorithms" / "stereo"))
    import stereo_scene as sc

    left, right = sc.photo("L"), sc.photo("R")
    geometry = epipolar_geometry(left, right)
    for side, photo in enumerate((left, right)):
        tile = Tile(0, Window(37, 11, 301, 203), 0, geometry.transform(side))
        fast = EpipolarMap(geometry, photo, side)(tile, {})
        exact = EpipolarMap(geometry, photo, side, step=1)(tile, {})
        for a, b in zip(fast, exact, strict=True):
            assert a.shape == (203, 301) and np.abs(a - b).max() < 0.01
