"""carto:contours writes the same features in the same order whatever TILE_SIZE: before, the
lines came in stitching order (which depends on the blocks) and a ring stitched across blocks
started at a block edge, so two runs with another TILE_SIZE gave GeoPackages of the same lines
with other fids and ring starts. The rule (README): features sorted by level, then first vertex,
then second vertex (x, then y); a ring starts at its least vertex (x, then y)."""

from __future__ import annotations

import numpy as np
import pyogrio
import pytest
import rasterio
import shapely
from rasterio.transform import from_origin

import toolbox
from toolbox.cartography.contour_io import canonical_order


def _dem(path, n=70, seed=4, west=1500000.0, north=4800000.0, crs="EPSG:3003"):
    """Smooth relief with noise: many small rings, and lines crossing many 8-16 cell blocks."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:n, 0:n] / n
    z = 100 + 12 * np.sin(3 * xx) * np.cos(2 * yy) + rng.normal(0, 0.4, (n, n))
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs=crs, transform=from_origin(west, north, 1, 1)) as dst:
        dst.write(z.astype("float32"), 1)
    return path


def _features(path):
    _, _, geometry, fields = pyogrio.raw.read(path, layer="contours", return_fids=True)
    return list(geometry), [np.asarray(f) for f in fields]


def _run(dem, out, **params):
    toolbox.run("carto:contours", {"INPUT": str(dem), "INTERVAL": 1.0, "OUTPUT": str(out)}
                | params)
    return _features(out)


def test_contour_features_do_not_depend_on_tile_size(tmp_path):
    dem = _dem(tmp_path / "dem.tif")
    wkb, fields = _run(dem, tmp_path / "whole.gpkg")  # one block (TILE_SIZE 512)
    assert len(wkb) > 50
    for tile in (8, 13, 32):
        wkb_t, fields_t = _run(dem, tmp_path / f"t{tile}.gpkg", TILE_SIZE=tile)
        assert wkb_t == wkb, tile  # the same WKB, in the same order (fid)
        for a, b in zip(fields_t, fields, strict=True):
            np.testing.assert_array_equal(a, b)


def test_contour_features_follow_the_canonical_rule(tmp_path):
    wkb, fields = _run(_dem(tmp_path / "dem.tif", seed=9), tmp_path / "c.gpkg", TILE_SIZE=16)
    lines = [shapely.get_coordinates(g) for g in shapely.from_wkb(wkb)]
    elev = fields[0]
    rings = 0
    for xy in lines:
        if len(xy) > 2 and (xy[0] == xy[-1]).all():  # a ring starts at its least vertex
            rings += 1
            least = min(map(tuple, xy[:-1]))
            assert tuple(xy[0]) == least
    assert rings > 10
    keys = [(lev, *xy[0], *xy[1]) for lev, xy in zip(elev, lines, strict=True)]
    assert keys == sorted(keys) and len(set(keys)) == len(keys)


def test_canonical_order_of_rotated_and_shuffled_lines():
    ring = np.array([[2.0, 1.0], [1.0, 3.0], [1.0, 2.0], [3.0, 0.5], [2.0, 1.0]])
    open_line = np.array([[0.5, 0.0], [0.0, 4.0], [5.0, 5.0]])
    low_ring = np.array([[9.0, 9.0], [8.0, 9.5], [8.0, 9.0], [9.0, 9.0]])
    lines, levels = [ring, open_line, low_ring], np.array([2.0, 2.0, 1.0])
    counts = np.array([len(v) for v in lines])
    order, source = canonical_order(np.concatenate(lines), counts, levels)
    assert order.tolist() == [2, 1, 0]  # level 1 first; then x of the first vertex
    xy = np.concatenate(lines)[source]
    expected = [np.array([[8.0, 9.0], [9.0, 9.0], [8.0, 9.5], [8.0, 9.0]]), open_line,
                np.array([[1.0, 2.0], [3.0, 0.5], [2.0, 1.0], [1.0, 3.0], [1.0, 2.0]])]
    np.testing.assert_array_equal(xy, np.concatenate(expected))
    # the same lines in another order, rings starting elsewhere: the same result
    again = [low_ring[[1, 2, 0, 1]], np.vstack([ring[2:-1], ring[:3]]), open_line]
    order2, source2 = canonical_order(np.concatenate(again), counts[[2, 0, 1]],
                                      levels[[2, 0, 1]])
    np.testing.assert_array_equal(np.concatenate(again)[source2], xy)


@pytest.mark.parametrize("n", [0, 1])
def test_canonical_order_of_few_lines(n):
    xy = np.array([[1.0, 1.0], [0.0, 0.0]])[: 2 * n]
    order, source = canonical_order(xy, np.full(n, 2, dtype=np.int64), np.zeros(n))
    assert order.tolist() == list(range(n)) and source.tolist() == list(range(2 * n))


@pytest.mark.parametrize("tracer", ["kernel", "contourpy"])
def test_either_tracer_gives_the_same_file_whatever_tile_size(tmp_path, monkeypatch, tracer):
    """The tracer is chosen by a cost model of the blocks (TILE_SIZE) and the executor: the
    one-pass kernel interpolated in block coordinates and in other arithmetic than contourpy
    (a vertex in a few thousand 1 ulp off), so TILE_SIZE 256 and 512 wrote other bits. Both
    now interpolate contourpy's way between the nodes' grid coordinates. (Near the origin:
    map coordinates of 1.5e6 m round most such differences away.)"""
    from toolbox.cartography import contour_io

    dem = _dem(tmp_path / "dem.tif", n=90, seed=5, west=0.0, north=90.0, crs="EPSG:3857")
    ref, _ = _run(dem, tmp_path / "ref.gpkg")  # the cost model's choice: contourpy
    monkeypatch.setattr(contour_io, "choose_tracer", lambda *args: tracer)
    for tile in (8, 16, 29, 512):
        wkb, _ = _run(dem, tmp_path / f"{tracer}{tile}.gpkg", TILE_SIZE=tile)
        assert wkb == ref, (tracer, tile)


def test_kernel_vertices_are_contourpys_bit_for_bit():
    """A block of a grid with NaN holes and plateaus, at its place in the grid (nodes at 300 +
    column, 1000 + row): the kernel's lines are contourpy's, vertex for vertex, bit for bit."""
    from scipy.ndimage import gaussian_filter

    from toolbox.cartography.contour_kernel import grid_lines
    from toolbox.cartography.contours import contourpy_lines

    rng = np.random.default_rng(7)
    z = gaussian_filter(rng.normal(size=(60, 75)), 2) * 300 + rng.normal(0, 0.5, (60, 75))
    z[rng.random(z.shape) < 0.05] = np.nan
    z[20:30, 30:50] = np.round(np.nanmean(z[20:30, 30:50]))
    levels = np.arange(np.floor(np.nanmin(z)), np.ceil(np.nanmax(z)), 1.0)
    levels -= 1024 * np.spacing(np.abs(levels))
    xs, ys = 300.0 + np.arange(75), 1000.0 + np.arange(60)

    def lines(points, offsets, level_of):  # a ring's start is the tracer's: compared as a set
        out = set()
        for i, k in enumerate(level_of.tolist()):
            xy = points[offsets[i]:offsets[i + 1]]
            if len(xy) > 2 and (xy[0] == xy[-1]).all():
                j = min(range(len(xy) - 1), key=lambda v: tuple(xy[v]))
                xy = np.vstack([xy[j:-1], xy[:j + 1]])
            out.add((k, xy.tobytes()))
        return out

    kernel = lines(*grid_lines(z, levels, xs, ys))
    assert len(kernel) > 500
    assert kernel == lines(*contourpy_lines(z, levels, 300.0, 1000.0, 1.0, 1.0))
