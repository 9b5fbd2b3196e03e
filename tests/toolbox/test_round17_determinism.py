"""Round 17, determinism sweep: the same deliverable whatever the execution settings (tiles,
blocks, workers) and on a re-run."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.terrain.gridding.idw_kernel import idw_grid


def _lattice():
    """Points on a 2 m lattice and cell centres midway between them: every cell has four
    equidistant nearest points, and rings of equidistant ones beyond (ties everywhere)."""
    gx, gy = np.meshgrid(np.arange(0, 40, 2.0), np.arange(0, 30, 2.0))
    x, y = gx.ravel(), gy.ravel()
    z = np.random.default_rng(3).normal(300, 5, x.size)
    return x, y, z, np.arange(1, 40, 2.0), np.arange(29, 0, -2.0)


def _tiled(xyz, xs, ys, size, reach=None, **options):
    """idw_grid tile by tile (each tile's points: those within ``reach`` of it, input order)."""
    out = np.full((len(ys), len(xs)), np.nan)
    for r0 in range(0, len(ys), size):
        for c0 in range(0, len(xs), size):
            txs, tys = xs[c0:c0 + size], ys[r0:r0 + size]
            keep = np.ones(len(xyz), bool)
            if reach is not None:
                keep = ((xyz[:, 0] >= txs.min() - reach) & (xyz[:, 0] <= txs.max() + reach)
                        & (xyz[:, 1] >= tys.min() - reach) & (xyz[:, 1] <= tys.max() + reach))
            out[r0:r0 + size, c0:c0 + size] = idw_grid(
                xyz[keep], txs, tys, np.ones((len(tys), len(txs)), bool), **options)
    return out


@pytest.mark.parametrize("k", [3, 6, 12])
def test_idw_neighbours_among_equidistant_points_do_not_depend_on_the_tiles(k):
    # dem:idw on a lattice gave other heights (0.07 m on the Siena grid) with TILE_SIZE 16 than
    # with 512: among equidistant points the block search kept the one nearest its block's
    # centre. Truth: the k nearest by (distance, x, y), weighted by 1/d^2, computed by brute force
    x, y, z, xs, ys = _lattice()
    xyz = np.column_stack([x, y, z])
    truth = np.empty((len(ys), len(xs)))
    for i, qy in enumerate(ys):
        for j, qx in enumerate(xs):
            d2 = (x - qx) ** 2 + (y - qy) ** 2
            o = np.lexsort((y, x, d2))[:k]
            w = 1.0 / d2[o]
            truth[i, j] = (w * z[o]).sum() / w.sum()
    full = idw_grid(xyz, xs, ys, np.ones((len(ys), len(xs)), bool), neighbours=k)
    np.testing.assert_allclose(full, truth, rtol=0, atol=1e-9)
    for size in (3, 4, 7):  # the same neighbours (their sum's order may differ: 1e-13)
        tiled = _tiled(xyz, xs, ys, size, neighbours=k)
        np.testing.assert_allclose(tiled, truth, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(tiled.astype("float32"), full.astype("float32"))


@pytest.mark.parametrize("k, sectors", [(8, 4), (6, 3)])
def test_idw_sector_neighbours_do_not_depend_on_the_tiles(k, sectors):
    # with SECTORS the ring search kept, among equidistant points of a sector, the one first in
    # the tile's own bins (104-145 of 300 cells differed between 4 x 4 tiles and one tile)
    x, y, z, xs, ys = _lattice()
    xyz = np.column_stack([x, y, z])
    options = {"neighbours": k, "sectors": sectors, "radius": 9.0}
    full = idw_grid(xyz, xs, ys, np.ones((len(ys), len(xs)), bool), **options)
    tiled = _tiled(xyz, xs, ys, 4, reach=10.0, **options)
    np.testing.assert_allclose(tiled, full, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(tiled.astype("float32"), full.astype("float32"))


def test_dem_idw_on_a_lattice_is_the_same_with_any_tile_size(tmp_path):
    # toolbox run dem:idw with TILE_SIZE 16 gave cell (39, 58) 300.758 instead of 300.824 (512):
    # at the grid's corner the 12th neighbour is one of four equidistant points
    import geopandas as gpd
    import rasterio
    import shapely

    import toolbox

    gx, gy = np.meshgrid(np.arange(0, 120, 2.0), np.arange(0, 80, 2.0))
    x, y = 1_688_000.0 + gx.ravel(), 4_799_500.0 + gy.ravel()
    z = np.round(300 + np.random.default_rng(3).normal(0, 5, x.size), 3)
    points = tmp_path / "lattice.gpkg"
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(x, y, z), crs="EPSG:3003").to_file(points)
    grids = []
    for tile in (512, 16, 48):
        out = tmp_path / f"idw_{tile}.tif"
        toolbox.run("dem:idw", {"INPUT": points, "CELL_SIZE": 2, "TILE_SIZE": tile,
                                "EXTENT": "1688000,4799500,1688120,4799580", "OUTPUT": out})
        with rasterio.open(out) as src:
            grids.append(src.read(1))
    np.testing.assert_array_equal(grids[1], grids[0])
    np.testing.assert_array_equal(grids[2], grids[0])


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
