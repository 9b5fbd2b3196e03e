"""Round 18, gridding on exact ties: the k nearest points kept among equidistant ones (points on a
lattice) do not depend on the tiles, the blocks or the bins. Truth: a brute force (cKDTree for
candidates, squared distances in numpy, then the documented rule: nearer first, then the lower
x, then the lower y)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from toolbox.terrain.gridding.idw_kernel import idw_grid, idw_loo
from toolbox.terrain.gridding.neighbours import PointBins, grid_knn
from toolbox.terrain.gridding.polynomial import polynomial_grid


def _lattice(n=40, step=2.0):
    """n x n points on a lattice, cell centres midway between them: four equidistant nearest
    points per cell and rings of equidistant ones beyond (ties everywhere). Input order
    shuffled, so no rule on the input order can pass for the coordinate rule."""
    gx, gy = np.meshgrid(np.arange(n) * step, np.arange(n) * step)
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    xy = xy[np.random.default_rng(5).permutation(len(xy))]
    z = np.random.default_rng(3).normal(300, 5, len(xy))
    xs = np.arange(n - 1) * step + step / 2
    ys = xs[::-1].copy()
    return xy, z, xs, ys


def _truth(xy, qx, qy, k, skip=None):
    """(q, k) input indices of the k nearest by (d2, x, y): brute force."""
    q = np.column_stack([qx, qy])
    extra = k + 40
    _, cand = cKDTree(xy).query(q, extra)
    out = np.empty((len(q), k), dtype=np.int64)
    for i in range(len(q)):
        c = cand[i] if skip is None else cand[i][cand[i] != skip[i]]
        d2 = (xy[c, 0] - q[i, 0]) ** 2 + (xy[c, 1] - q[i, 1]) ** 2
        o = np.lexsort((xy[c, 1], xy[c, 0], d2))
        assert d2[o[-1]] > d2[o[k - 1]]  # every point tying the k-th is a candidate
        out[i] = c[o[:k]]
    return out


def _tile_points(xy, txs, tys, reach):
    """The points a tile gets (as NeighbourPlanner: those within ``reach``, input order)."""
    return np.flatnonzero((xy[:, 0] >= txs.min() - reach) & (xy[:, 0] <= txs.max() + reach)
                          & (xy[:, 1] >= tys.min() - reach) & (xy[:, 1] <= tys.max() + reach))


@pytest.mark.parametrize("k", [1, 3, 6, 12])
def test_block_search_keeps_the_tie_rule_neighbours_on_a_lattice_with_any_block(k):
    # the block search kept, among equidistant points, the one nearest its block's centre:
    # another block size (it follows TILE_SIZE and the data's density) kept another point
    xy, _, xs, ys = _lattice()
    gx, gy = np.meshgrid(xs, ys)
    truth = np.sort(_truth(xy, gx.ravel(), gy.ravel(), k), axis=1)
    bins = PointBins.build(xy)
    for block in (1, 3, 7, 16):
        _, idx = grid_knn(bins, xs, ys, k, block=block)
        np.testing.assert_array_equal(np.sort(idx.reshape(-1, k), axis=1), truth)


@pytest.mark.parametrize("k", [1, 4, 12])
def test_ring_search_keeps_the_tie_rule_neighbours_whatever_the_bins(k):
    # knn_one (leave-one-out: QUALITY, dem:cross_validate) kept the equidistant point met first
    # in the bins: bins of another point set (a streamed tile's bucket) kept another one
    xy, _, _, _ = _lattice()
    targets = np.arange(0, len(xy), 7)
    truth = np.sort(_truth(xy, xy[targets, 0], xy[targets, 1], k, skip=targets), axis=1)
    _, idx = PointBins.build(xy).query(xy[targets, 0], xy[targets, 1], k, skip=targets)
    np.testing.assert_array_equal(np.sort(idx, axis=1), truth)
    inner = np.flatnonzero((xy[:, 0] >= 20) & (xy[:, 1] >= 10))  # another bin grid
    central = np.isin(targets, inner) & (xy[targets, 0] >= 34) & (xy[targets, 1] >= 24)
    t = targets[central]
    sub = PointBins.build(xy[inner])
    _, idx = sub.query(xy[t, 0], xy[t, 1], k, skip=np.searchsorted(inner, t))
    np.testing.assert_array_equal(np.sort(inner[idx], axis=1), np.sort(truth[central], axis=1))


@pytest.mark.parametrize("k", [4, 12])
def test_idw_and_quadratic_on_a_lattice_are_the_same_with_any_tiles(k):
    # dem:idw gave another height at a lattice cell with TILE_SIZE 16 than 512 (0.066 m),
    # dem:quadratic 1.2 m: another of the equidistant k-th neighbours was kept
    xy, z, xs, ys = _lattice()
    xyz = np.column_stack([xy, z])
    gx, gy = np.meshgrid(xs, ys)
    nb = _truth(xy, gx.ravel(), gy.ravel(), k)
    d2 = (xy[nb, 0] - gx.ravel()[:, None]) ** 2 + (xy[nb, 1] - gy.ravel()[:, None]) ** 2
    truth = ((z[nb] / d2).sum(axis=1) / (1 / d2).sum(axis=1)).reshape(gx.shape)
    mask = np.ones(gx.shape, bool)
    full = idw_grid(xyz, xs, ys, mask, neighbours=k)
    np.testing.assert_allclose(full, truth, rtol=0, atol=1e-9)
    quad_full = polynomial_grid(xyz, xs, ys, mask, order=2, neighbours=k)[0] if k >= 6 else None
    for size in (3, 8, 13):
        tiled = np.full(gx.shape, np.nan)
        quad = np.full(gx.shape, np.nan)
        for r0 in range(0, len(ys), size):
            for c0 in range(0, len(xs), size):
                txs, tys = xs[c0:c0 + size], ys[r0:r0 + size]
                keep = _tile_points(xy, txs, tys, 9.0)
                tmask = np.ones((len(tys), len(txs)), bool)
                tiled[r0:r0 + size, c0:c0 + size] = idw_grid(xyz[keep], txs, tys, tmask,
                                                             neighbours=k)
                if quad_full is not None:
                    quad[r0:r0 + size, c0:c0 + size] = polynomial_grid(
                        xyz[keep], txs, tys, tmask, order=2, neighbours=k)[0]
        np.testing.assert_allclose(tiled, truth, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(tiled.astype("float32"), full.astype("float32"))
        if quad_full is not None:
            np.testing.assert_allclose(quad, quad_full, rtol=0, atol=1e-9)


def test_idw_sectors_on_a_lattice_are_the_same_with_any_tiles():
    # with SECTORS the ring search kept, among equidistant points of a sector, the one first in
    # the tile's own bins
    xy, z, xs, ys = _lattice(24)
    xyz = np.column_stack([xy, z])
    options = {"neighbours": 8, "sectors": 4, "radius": 9.0}
    full = idw_grid(xyz, xs, ys, np.ones((len(ys), len(xs)), bool), **options)
    tiled = np.full(full.shape, np.nan)
    for r0 in range(0, len(ys), 5):
        for c0 in range(0, len(xs), 5):
            txs, tys = xs[c0:c0 + 5], ys[r0:r0 + 5]
            keep = _tile_points(xy, txs, tys, 10.0)
            tiled[r0:r0 + 5, c0:c0 + 5] = idw_grid(
                xyz[keep], txs, tys, np.ones((len(tys), len(txs)), bool), **options)
    np.testing.assert_allclose(tiled, full, rtol=0, atol=1e-9)


def test_leave_one_out_on_a_lattice_follows_the_tie_rule():
    xy, z, _, _ = _lattice(20)
    bins = PointBins.build(xy)
    targets = np.arange(len(xy))
    nb = _truth(xy, xy[:, 0], xy[:, 1], 6, skip=targets)
    d2 = (xy[nb, 0] - xy[:, :1]) ** 2 + (xy[nb, 1] - xy[:, 1:]) ** 2
    truth = (z[nb] / d2).sum(axis=1) / (1 / d2).sum(axis=1)
    np.testing.assert_allclose(idw_loo(bins, z, targets, neighbours=6), truth, rtol=0,
                               atol=1e-9)


def test_dem_idw_and_quadratic_on_a_lattice_are_the_same_with_any_tile_size(tmp_path):
    # toolbox run dem:idw with TILE_SIZE 16 gave one cell 0.066 m off the TILE_SIZE 512 grid,
    # dem:quadratic 1.2 m (exit 0)
    import geopandas as gpd
    import rasterio
    import shapely

    import toolbox

    gx, gy = np.meshgrid(np.arange(0, 120, 2.0), np.arange(0, 80, 2.0))
    x, y = 1_688_000.0 + gx.ravel(), 4_799_500.0 + gy.ravel()
    z = np.round(300 + np.random.default_rng(3).normal(0, 5, x.size), 3)
    points = tmp_path / "lattice.gpkg"
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(x, y, z), crs="EPSG:3003").to_file(points)
    for alg in ("idw", "quadratic"):
        grids = []
        for tile in (512, 16):
            out = tmp_path / f"{alg}_{tile}.tif"
            toolbox.run(f"dem:{alg}", {"INPUT": points, "CELL_SIZE": 2, "TILE_SIZE": tile,
                                       "EXTENT": "1688000,4799500,1688120,4799580",
                                       "OUTPUT": out})
            with rasterio.open(out) as src:
                grids.append(src.read(1))
        np.testing.assert_array_equal(grids[1], grids[0])
