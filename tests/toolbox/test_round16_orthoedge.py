"""Round 16, orthoedge: the DEM's outer half cell. A DEM's heights are defined over its whole
extent (its outer cell edges), the edge value held across the outer half cell, as gdalwarp's
bilinear resampling holds it (and carto:profile, :func:`toolbox.raster.bilinear.bilinear` with
``half_cell``). The ortho's height kernels stopped at the outer cell centres: an ortho made on
one DEM tile of 4 m cells lost 2 m on every side, and orthos of adjacent DEM tiles (one DEM tile
per sheet) left a gap between them.

Truth here: a plane DEM ``z = a + b·x + c·y``, whose height at a point of the outer half cell is
the plane at the nearest cell centre hull point (the clamped point), and a photo whose pixel
values are linear in (col, row), so that bilinear resampling gives back exactly the pixel it
samples: an ortho cell's value names the photo point it was projected to, checked against the
collinearity equations written out here (R = Rx(omega)·Ry(phi)·Rz(kappa))."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox

sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
import ortho_scene as scene  # noqa: E402

CELL = 4.0  # DEM cell, m
X0, X1, X2, Y0, Y1 = 1687800.0, 1688200.0, 1688600.0, 4799000.0, 4799400.0  # two DEM tiles


def plane(x, y):
    return 300.0 + 0.8 * (x - X0) - 0.5 * (y - Y0)  # steep: the half cell shows (0.18 px)


def plane_clamped(x, y, xa, xb, ya, yb):
    """The plane at the point of the cell-centre hull nearest to (x, y): the held edge value."""
    return plane(np.clip(x, xa + CELL / 2, xb - CELL / 2), np.clip(y, ya + CELL / 2, yb - CELL / 2))


def dem_tile(xa, xb, ya=Y0, yb=Y1):
    t = Affine(CELL, 0.0, xa, 0.0, -CELL, yb)
    xc = xa + (np.arange(int(round((xb - xa) / CELL))) + 0.5) * CELL
    yc = yb - (np.arange(int(round((yb - ya) / CELL))) + 0.5) * CELL
    return plane(*np.meshgrid(xc, yc)), t


def collinearity(x, y, z):
    """Photo pixel (col, row) of ground points: the collinearity equations of the scene's photo
    (c = 153 mm, 230 mm frame of scene.SIZE pixels, principal point at the centre)."""
    w, p, k = scene.ANGLES
    rx = np.array([[1, 0, 0], [0, np.cos(w), -np.sin(w)], [0, np.sin(w), np.cos(w)]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rz = np.array([[np.cos(k), -np.sin(k), 0], [np.sin(k), np.cos(k), 0], [0, 0, 1]])
    d = np.stack([x - scene.CENTRE[0], y - scene.CENTRE[1], z - scene.CENTRE[2]], -1) @ (
        rx @ ry @ rz)
    pixel = 230.0 / scene.SIZE
    xi, eta = -153.0 * d[..., 0] / d[..., 2], -153.0 * d[..., 1] / d[..., 2]
    return xi / pixel + scene.SIZE / 2, -eta / pixel + scene.SIZE / 2


def photo_value(col, row):
    return 1000.0 + 40.0 * col + 20.0 * row  # linear: bilinear resampling is exact


def write_linear_photo(folder: Path) -> None:
    """``folder``/p1.tif (:func:`photo_value` at the pixel centres) and its project.yaml."""
    from toolbox.photogrammetry.synthetic import write_photo

    cols, rows = np.meshgrid(np.arange(scene.SIZE) + 0.5, np.arange(scene.SIZE) + 0.5)
    write_photo(folder / "p1.tif", np.rint(photo_value(cols, rows)).astype("uint16"))
    scene.project_yaml(folder / "project.yaml", "p1.tif")


@pytest.fixture(scope="module")
def tiles(tmp_path_factory):
    folder = tmp_path_factory.mktemp("orthoedge")
    write_linear_photo(folder)
    for name, (xa, xb) in {"A": (X0, X1), "B": (X1, X2)}.items():
        z, t = dem_tile(xa, xb)
        scene.write_dem(folder / f"dem_{name}.tif", z.astype("float32"), t)
    return folder


def test_orthos_of_two_dem_tiles_meet_without_a_gap(tiles):
    """ortho:photo on each of two DEM tiles sharing the edge x = 1688200, EXTENT = the tile:
    every cell of each ortho has a value (the old kernels left the outer 2 m, two 1 m columns
    and rows on every side, empty: a 4-column gap between the orthos), equal to the photo
    at the collinearity projection of (x, y, z clamped) within 1 DN (1/40 px)."""
    for name, (xa, xb) in {"A": (X0, X1), "B": (X1, X2)}.items():
        out = tiles / f"ortho_{name}.tif"
        toolbox.run("ortho:photo", {
            "INPUT": tiles / "p1.tif", "PROJECT": tiles / "project.yaml",
            "DEM": tiles / f"dem_{name}.tif", "CELL_SIZE": 1.0,
            "EXTENT": f"{xa},{Y0},{xb},{Y1}", "OUTSIDE": "nodata", "NODATA": 0,
            "OUTPUT": out}, overwrite=True)
        with rasterio.open(out) as src:
            value, t = src.read(1).astype("float64"), src.transform
        assert (t.c, t.f, src.width, src.height) == (xa, Y1, 400, 400)
        xs = t.c + (np.arange(src.width) + 0.5) * t.a
        ys = t.f + (np.arange(src.height) + 0.5) * t.e
        xx, yy = np.meshgrid(xs, ys)
        empty = value == 0
        assert not empty.any(), (name, np.where(empty.all(axis=0))[0])
        col, row = collinearity(xx, yy, plane_clamped(xx, yy, xa, xb, Y0, Y1))
        assert np.abs(value - photo_value(col, row)).max() <= 1.0
        # the outer half cell matters: the unclamped plane puts its pixels elsewhere there
        edge = (xx < xa + CELL / 2) | (xx > xb - CELL / 2) | (yy < Y0 + CELL / 2) | \
            (yy > Y1 - CELL / 2)
        col_u, row_u = collinearity(xx, yy, plane(xx, yy))
        assert np.abs(value - photo_value(col_u, row_u))[edge].max() > 3.0


def test_batch_extent_reaches_the_dem_cell_edges():
    """ortho:batch cuts each ortho's extent to the DEM's cells holding a height
    (``on_heights``): to their outer edges, no longer to their centres."""
    from algorithms.ortho.batch import on_heights
    from toolbox.photogrammetry.surface import DemSurface

    z, t = dem_tile(X0, X1)
    z[:, :3] = np.nan  # nodata columns on the west: the cut follows the valid cells
    surface = DemSurface.from_transform(z, t)
    cut = on_heights((X0 - 500.0, Y0 - 500.0, X1 + 500.0, Y1 + 500.0), surface)
    assert cut == pytest.approx((X0 + 3 * CELL, Y0, X1, Y1), abs=1e-9)
    assert surface.bounds == pytest.approx((X0, Y0, X1, Y1), abs=1e-9)


def edge_points():
    """Points of the tile A: in its outer half cell on each side and at the corners, just
    inside its outer edges, inside, and beyond the edges (no height)."""
    h = CELL / 2
    x = np.array([X0 + 0.3, X1 - 0.3, X0 + 100.0, X0 + 100.0, X0 + 0.01, X1 - 0.01, X0 + 1.0,
                  X0 + 100.0, X0 - 0.01, X1 + 0.01, X0 + 100.0, X0 + 100.0, X0 + h + 1.0])
    y = np.array([Y0 + 200.0, Y0 + 200.0, Y1 - 0.5, Y0 + 1.5, Y1 - 0.01, Y0 + 0.01, Y0 + 1.0,
                  Y0 + 200.0, Y0 + 200.0, Y0 + 200.0, Y1 + 0.01, Y0 - 0.01, Y1 - h - 1.0])
    truth = plane_clamped(x, y, X0, X1, Y0, Y1)
    truth[8:12] = np.nan
    return x, y, truth


@pytest.mark.parametrize("kind", ["compiled", "numpy"])
def test_edge_of_dem_point_gets_the_clamped_height(kind):
    """Every height path of the ortho and of monoplotting at points in the DEM's outer half
    cell: the height of the nearest edge sample (the plane at the clamped point); NaN beyond
    the outer cell edges."""
    if kind == "compiled":
        from toolbox.ortho.heights import heights_at_points, heights_on_grid
        from toolbox.photogrammetry.kernels import _dem_height
    else:
        from toolbox.ortho.grid_numpy import heights_at_points, heights_on_grid
        from toolbox.photogrammetry.kernels_numpy import _dem_height
    from toolbox.photogrammetry.surface import DemSurface

    z, t = dem_tile(X0, X1)
    args = (z, X0 + CELL / 2, Y1 - CELL / 2, CELL, CELL)
    x, y, truth = edge_points()
    out = np.empty(len(x))
    heights_at_points(*args, x, y, out)
    np.testing.assert_allclose(out, truth, atol=1e-9)
    if kind == "compiled":
        got = np.array([_dem_height(a, b, *args)[0] for a, b in zip(x, y, strict=True)])
    else:
        got = _dem_height(x, y, *args)[0]
    np.testing.assert_allclose(got, truth, atol=1e-9)
    grid = np.empty((len(y), len(x)))
    heights_on_grid(*args, x, y, grid)
    xx, yy = np.meshgrid(x, y)
    grid_truth = plane_clamped(xx, yy, X0, X1, Y0, Y1)
    grid_truth[:, 8:10] = grid_truth[10:12, :] = np.nan
    np.testing.assert_allclose(grid, grid_truth, atol=1e-9)
    if kind == "compiled":
        surface = DemSurface.from_transform(z, t)
        np.testing.assert_allclose(surface.height(x, y), truth, atol=1e-9)


def test_fused_window_kernel_holds_the_edge_height():
    """The one-pass kernel of ortho:photo's windows (heights + map) on an output grid reaching
    past the DEM: the heights of the outer half cell are the clamped plane, the cells beyond
    the DEM's edges have none."""
    from toolbox.ortho.kernels import ortho_window_projective
    from toolbox.ortho.sensor import CollinearityMap
    from toolbox.photogrammetry.synthetic import frame_photo

    z, _ = dem_tile(X0, X1)
    photo = frame_photo(scene.CENTRE, scene.ANGLES, width=scene.SIZE, height=scene.SIZE,
                        crs=scene.CRS)
    cmap = CollinearityMap(photo, block=16)
    tile = Affine(1.0, 0.0, X0 - 3.0, 0.0, -1.0, Y1 + 3.0)
    w, h = 406, 406
    xs = tile.c + (np.arange(w) + 0.5)
    ys = tile.f - (np.arange(h) + 0.5)
    cols, rows, _, _, heights = cmap.project_on_dem(
        tile, xs, ys, (z, X0 + CELL / 2, Y1 - CELL / 2, CELL, CELL), np.array(scene.CENTRE),
        300.0, keep_heights=True)
    xx, yy = np.meshgrid(xs, ys)
    inside = (xx > X0) & (xx < X1) & (yy > Y0) & (yy < Y1)
    truth = np.where(inside, plane_clamped(xx, yy, X0, X1, Y0, Y1), np.nan)
    np.testing.assert_allclose(heights, truth, atol=1e-9)
    col, row = collinearity(xx, yy, truth)
    np.testing.assert_allclose(cols[inside], col[inside], atol=2e-3)
    np.testing.assert_allclose(rows[inside], row[inside], atol=2e-3)
    assert ortho_window_projective is not None


def test_occlusion_sees_the_dsm_edge_held_across_the_outer_half_cell():
    """The true ortho's visibility test walks the DSM over its outer half cell too: a ground
    cell 0.3 cells north of the DSM's first row of centres, seen from far west along that row,
    is hidden by a wall 30 m high across the DSM (the held edge value under its ray); the old
    test took the ray off the DSM there and saw the cell."""
    from toolbox.ortho.visibility import visibility_mask
    from toolbox.photogrammetry.surface import DemSurface

    dsm = np.zeros((20, 40))
    dsm[:, 10] = 30.0  # a wall north-south at column 10
    surface = DemSurface.from_transform(dsm, Affine(1.0, 0.0, 0.0, 0.0, -1.0, 20.0))
    centre = np.array([-2000.0, 19.8, 1000.0])  # far west, at the ground cells' y
    xs = np.array([30.5, 30.5])
    ys = np.array([19.8, 25.0])  # in the outer half cell (row 0's centre at 19.5), beyond
    hidden = visibility_mask(xs, ys[:1], np.zeros((1, 2)), centre, surface)
    assert hidden.tolist() == [[1, 1]]
    free = visibility_mask(xs, ys[1:], np.zeros((1, 2)), centre, surface)
    assert free.tolist() == [[0, 0]]


def test_heights_equal_gdal_bilinear_warp_over_the_whole_dem_extent():
    """The ortho's height kernels (compiled and NumPy) on a grid of 1 m cells covering a
    random 7 x 9 DEM of 4 m cells exactly: GDAL's bilinear warp (rasterio.warp.reproject) of
    the DEM onto that grid, every cell (the old kernels left the outer 2 m NaN: 240 cells)."""
    from rasterio.warp import Resampling, reproject

    from toolbox.ortho.grid_numpy import heights_on_grid as numpy_heights
    from toolbox.ortho.heights import heights_on_grid

    z = 100.0 + 20.0 * np.random.default_rng(1).random((7, 9))
    t = Affine(4.0, 0.0, 1000.0, 0.0, -4.0, 2000.0)
    gdal = np.full((28, 36), np.nan)
    reproject(z, gdal, src_transform=t, dst_transform=Affine(1.0, 0.0, 1000.0, 0.0, -1.0, 2000.0),
              src_crs="EPSG:3003", dst_crs="EPSG:3003", resampling=Resampling.bilinear)
    xs, ys = 1000.0 + np.arange(36) + 0.5, 2000.0 - np.arange(28) - 0.5
    for kernel in (heights_on_grid, numpy_heights):
        out = np.empty((28, 36))
        kernel(z, 1002.0, 1998.0, 4.0, 4.0, xs, ys, out)
        np.testing.assert_allclose(out, gdal, rtol=0, atol=1e-9)
