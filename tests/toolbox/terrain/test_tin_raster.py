"""TinTiles' grouping of triangles by tile equals the TIN kernels' own grouping, and tiled
rasterising equals the one-tile raster."""

from __future__ import annotations

import numpy as np
from affine import Affine
from scipy.spatial import Delaunay

from toolbox.io.grid import GridSpec
from toolbox.raster.engine import iter_tiles
from toolbox.terrain.gridding.tin_raster import TinTiles, group_by_tile, tin_tile
from toolbox.terrain.tin.kernels import triangles_by_tile


def random_tin(n=3000, seed=4):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-10, 510, (n, 2))
    z = 3 + 0.2 * xy[:, 0] - 0.1 * xy[:, 1]
    return np.column_stack([xy, z]), Delaunay(xy).simplices.astype(np.int64)


def test_grouping_equals_triangles_by_tile():
    nodes, tri = random_tin()
    for cell, tile, (w, h) in ((1.0, 64, (500, 480)), (2.5, 16, (190, 210)), (0.7, 512, (30, 20))):
        order, start = group_by_tile(nodes, tri.astype(np.int32), 3.0, 490.0, cell, cell, w,
                                     h, tile)
        ref_order, ref_start, _ = triangles_by_tile(nodes[:, :2], tri, 3.0, 490.0, cell, cell,
                                                    w, h, tile)
        assert np.array_equal(start, ref_start) and np.array_equal(order, ref_order)


def test_tiled_tin_equals_one_tile_and_the_plane():
    nodes, tri = random_tin()
    grid = GridSpec(Affine(1.0, 0, 0.0, 0, -1.0, 500.0), 500, 500, None)
    full = np.full(grid.shape, np.nan)
    tiles = TinTiles(nodes, tri, grid, 64)
    for tile in iter_tiles(grid, 64):
        arrays = tiles.plan(tile)
        if arrays is not None:
            w = tile.window
            full[w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] = \
                tin_tile((0.0, 0.0), tile, arrays)
    (one,) = list(iter_tiles(grid, 512))
    whole = tin_tile((0.0, 0.0), one, TinTiles(nodes, tri, grid, 512).plan(one))
    assert np.array_equal(np.isnan(full), np.isnan(whole))
    # the plane is evaluated from each tile's corner: equal up to float64 rounding
    np.testing.assert_allclose(full[~np.isnan(full)], whole[~np.isnan(whole)], rtol=0, atol=1e-12)
    xs, ys = one.cell_centres()
    plane = 3 + 0.2 * xs[None, :] - 0.1 * ys[:, None]
    ok = ~np.isnan(full)
    assert ok.mean() > 0.9
    np.testing.assert_allclose(full[ok], plane[ok], atol=1e-9)


def test_plan_gives_each_tile_its_triangles_renumbered_in_node_order():
    """plan() (one compiled pass with a reused scratch array) equals np.unique's renumbering."""
    nodes, tri = random_tin()
    grid = GridSpec(Affine(1.0, 0, 0.0, 0, -1.0, 500.0), 500, 500, None)
    tiles = TinTiles(nodes, tri, grid, 64)
    for tile in iter_tiles(grid, 64):
        arrays = tiles.plan(tile)
        ids = tiles.order[tiles.start[tile.index]:tiles.start[tile.index + 1]]
        if not len(ids):
            assert arrays is None
            continue
        used, inverse = np.unique(tri[ids].ravel(), return_inverse=True)
        np.testing.assert_array_equal(arrays["nodes"], nodes[used])
        np.testing.assert_array_equal(arrays["triangles"], inverse.reshape(-1, 3))
    assert (tiles._slot == -1).all()  # the scratch is left clean for the next tile
