"""Streamed dem:tin_linear (toolbox/terrain/gridding/stream_tin.py): the same cells as the
in-memory TIN (the oracle) and as scipy's LinearNDInterpolator (Qhull's Delaunay TIN of the
same distinct points), on an even cloud and on a clustered one whose big triangles force the
buckets to grow."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from scipy.interpolate import LinearNDInterpolator

import toolbox
import toolbox.io.pointcloud as pointcloud
from toolbox.io.pointcloud import write_point_cloud

X0, Y0 = 1_688_000.0, 4_799_500.0


def _write(path, x, y, z):
    x, y = np.round(X0 + x, 3), np.round(Y0 + y, 3)  # the LAZ's 1 mm lattice
    write_point_cloud(path, np.column_stack([x, y, z]), "EPSG:3003")
    return path


@pytest.fixture(scope="module")
def even(tmp_path_factory):
    """30,000 points over 200 x 150 m, 300 of them exact XY duplicates of others."""
    rng = np.random.default_rng(2029)
    n = 30_000
    x, y = rng.uniform(0, 200, n), rng.uniform(0, 150, n)
    x[-300:], y[-300:] = x[:300], y[:300]
    z = 250 + 8 * np.sin(x / 35) * np.cos(y / 25) + rng.normal(0, 0.1, n)
    return _write(tmp_path_factory.mktemp("tin") / "even.laz", x, y, z)


@pytest.fixture(scope="module")
def clustered(tmp_path_factory):
    """Three dense clusters and 40 sparse points over 400 x 300 m: triangles across the gaps
    have circumcircles far wider than the first buckets."""
    rng = np.random.default_rng(7)
    parts = [rng.normal((60, 60), 12, (6000, 2)), rng.normal((330, 90), 8, (6000, 2)),
             rng.normal((200, 250), 15, (6000, 2)), rng.uniform((0, 0), (400, 300), (40, 2))]
    xy = np.clip(np.vstack(parts), 0, (400, 300))
    z = 100 + 0.05 * xy[:, 0] + 20 * np.sin(xy[:, 1] / 40) + rng.normal(0, 0.3, len(xy))
    return _write(tmp_path_factory.mktemp("tin") / "clustered.laz", xy[:, 0], xy[:, 1], z)


def _grid(path):
    with rasterio.open(path) as ds:
        return ds.read(1, masked=True).filled(np.nan), ds.transform


def _run(cloud, out, extra=None):
    params = {"INPUT": str(cloud), "CELL_SIZE": 2.0, "TILE_SIZE": 32, "OUTPUT": str(out),
              "OVERVIEWS": False, **(extra or {})}
    return toolbox.run("dem:tin_linear", params)["STATISTICS"]


def _scipy(cloud, transform, shape):
    """Qhull's linear interpolation at the cell centres, on the distinct XY (duplicates
    merged by the mean, the default DUPLICATES rule)."""
    xyz, _ = pointcloud.read_xyz(pointcloud.open_point_cloud(cloud))
    xy, inverse = np.unique(xyz[:, :2], axis=0, return_inverse=True)
    inverse = inverse.ravel()
    z = np.bincount(inverse, xyz[:, 2]) / np.bincount(inverse)
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    cx = transform.c + (cols + 0.5) * transform.a - X0
    cy = transform.f + (rows + 0.5) * transform.e - Y0
    return LinearNDInterpolator(xy - (X0, Y0), z)(cx, cy)


def _streamed(cloud, tmp_path, monkeypatch, extra=None):
    memory = _run(cloud, tmp_path / "memory.tif", extra)
    assert "streamed" not in memory
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    streamed = _run(cloud, tmp_path / "stream.tif", extra)
    a, ta = _grid(tmp_path / "memory.tif")
    b, tb = _grid(tmp_path / "stream.tif")
    assert ta == tb and a.shape == b.shape
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=0)
    assert streamed["duplicates"] == memory["duplicates"]
    assert streamed["cells"]["cells_with_value"] == memory["cells"]["cells_with_value"]
    return streamed, b, tb


def test_streamed_tin_equals_in_memory_and_qhull(even, tmp_path, monkeypatch):
    stats, grid, transform = _streamed(even, tmp_path, monkeypatch)
    info = stats["streamed"]
    assert info["tiles"] >= 12 and info["bucket_points_max"] < 30_000 / 3
    assert stats["duplicates"]["duplicate_groups"] >= 250
    expected = _scipy(even, transform, grid.shape)
    inside = np.isfinite(expected) & np.isfinite(grid)
    assert inside.sum() > 0.95 * np.isfinite(expected).sum()
    # float32 GeoTIFF cells: Qhull's plane rounded to float32
    np.testing.assert_allclose(grid[inside], expected[inside].astype(np.float32), rtol=1e-6)


def test_clustered_cloud_grows_the_buckets(clustered, tmp_path, monkeypatch):
    stats, grid, transform = _streamed(clustered, tmp_path, monkeypatch)
    info = stats["streamed"]
    assert info["tiles_retried"] > 0 and info["passes"] >= 2
    assert info["rim_points"] > 0  # the redone tiles' buckets got the hull's rim
    expected = _scipy(clustered, transform, grid.shape)
    inside = np.isfinite(expected) & np.isfinite(grid)
    assert inside.sum() > 0.95 * np.isfinite(expected).sum()
    np.testing.assert_allclose(grid[inside], expected[inside].astype(np.float32), rtol=1e-6)


def test_streamed_tin_max_distance_and_extent(even, tmp_path, monkeypatch):
    extent = f"{X0 - 20},{Y0 - 10},{X0 + 210},{Y0 + 160}"
    stats, grid, _ = _streamed(even, tmp_path, monkeypatch,
                               {"MAX_DISTANCE": 1.5, "EXTENT": extent, "CELL_SIZE": 0.5})
    assert stats["streamed"]["reach_max"] >= 1.5
    assert np.isnan(grid).sum() > 0.1 * grid.size  # outside the hull, and far from points


def test_circumcircle_test_against_analytic_discs():
    """Circumcircles of right triangles (centre: the hypotenuse's midpoint), and which discs
    may hold a point of the cloud outside the bucket's rectangle."""
    from shapely.geometry import Polygon, box

    from toolbox.terrain.gridding.stream_tin import circumcircles, empty_outside

    xy = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [10.0, 0.0], [10.0, 2.0], [8.0, 0.0]])
    centres, radius = circumcircles(xy, np.array([[0, 1, 2], [3, 4, 5]]))
    np.testing.assert_allclose(centres, [[1.0, 1.0], [9.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(radius, [np.sqrt(2.0)] * 2, atol=1e-15)
    rect = np.array([-1.0, -1.0, 3.0, 3.0])
    bounds = (-5.0, -5.0, 20.0, 20.0)
    hull = Polygon([(-5, -5), (20, -5), (20, 20), (-5, 20)])
    outer = hull.difference(box(*rect))
    # the first disc (x in 1 +- 1.414) lies in the rectangle, the second outside it
    assert empty_outside(centres, radius, rect, bounds, outer).tolist() == [True, False]
    # a rectangle whose left and bottom sides are beyond the cloud: only the other sides count
    tight = np.array([0.0, 0.0, 2.5, 2.5])
    assert not empty_outside(centres[:1], radius[:1], tight, bounds, hull.difference(box(*tight)))
    assert empty_outside(centres[:1], radius[:1], tight, (0.0, 0.0, 20.0, 20.0),
                         Polygon([(0, 0), (20, 0), (20, 20), (0, 20)]).difference(box(*tight)))
    # the disc reaches above the rectangle's top side (y = 1, inside the bounds): the part
    # of the hull above it holds points there...
    small = Polygon([(0, 0), (2.5, 0), (0, 2.5)])
    flat = np.array([0.0, 0.0, 2.5, 1.0])
    assert not empty_outside(centres[:1], radius[:1], flat, (0.0, 0.0, 2.5, 2.5),
                             small.difference(box(*flat))).any()
    # ... unless the hull outside the rectangle lies away from the disc (shapely's distance)
    assert empty_outside(centres[:1], radius[:1], flat, (0.0, 0.0, 10.0, 3.0),
                         box(6.0, 1.0, 10.0, 3.0)).all()
    # a bucket that holds the whole hull: every triangle counts
    assert empty_outside(centres, radius, rect, bounds, box(*rect).difference(box(*rect))).all()


def test_supports_hull_exact_signs():
    """Segments on the hull's boundary (two vertices, or points on a straight edge between
    them, at map-sized coordinates), a diagonal, and a point one ulp inside the edge."""
    from toolbox.terrain.gridding.stream_tin import supports_hull

    o = 1_000_000.0
    ring = np.array([[o, o], [o + 3, o + 1], [o + 3, o + 5], [o, o + 5]])
    mid = [o + 1.5, o + 0.5]  # exactly on the edge (o, o) - (o + 3, o + 1)
    nudged = [o + 1.5, np.nextafter(o + 0.5, np.inf)]  # one ulp inside it
    a = np.array([ring[0], mid, ring[1], ring[0], nudged, [o, o + 2]])
    b = np.array([ring[1], ring[1], mid, ring[2], ring[1], [o, o + 4]])
    assert supports_hull(a, b, ring).tolist() == [True, True, True, False, False, True]
    assert supports_hull(a[:0], b[:0], ring).tolist() == []


def test_rim_bucket_adds_the_band_near_the_rectangle():
    """Hull [0, 100]^2, its rim the band 10 m wide along the edge, a tile's rectangle
    [40, 60] x [0, 20] grown by 20: the bucket gets the rim points in [20, 80] x [0, 40]
    outside the rectangle; the cloud's other points lie in the hull's inner square outside
    the rectangle or outside the grown rectangle."""
    from shapely.geometry import Point, box

    from toolbox.terrain.gridding.stream_tin import rim_bucket

    hull, inner = box(0, 0, 100, 100), box(10, 10, 90, 90)
    rim = np.array([[50.0, 5.0, 1.0], [30.0, 2.0, 2.0], [85.0, 5.0, 3.0], [5.0, 50.0, 4.0],
                    [25.0, 38.0, 5.0]])  # the last one not in the band: never given here
    xyz = np.array([[45.0, 15.0, 0.0]])
    rect = np.array([40.0, 0.0, 60.0, 20.0])
    bucket, outer = rim_bucket(xyz, rect, hull, inner, rim[:4], 20.0)
    assert bucket[:, 2].tolist() == [0.0, 2.0]  # (50, 5) is in the rectangle already
    for x, y, missing in [(30, 5, False), (30, 30, True), (50, 15, False), (85, 5, True),
                          (5, 50, True), (79, 9, False), (81, 9, True)]:
        assert outer.intersects(Point(x, y)) == missing, (x, y)
    # the rim is read for redone tiles only when one of them reaches its band (2 buckets of 5 m)
    from toolbox.terrain.gridding.stream_tin import RIM_REACH, _near_rim

    tiles = np.array([[45.0, 45.0, 55.0, 55.0]])
    gap = 45.0 - 10.0  # from the tile's box to the band
    assert not _near_rim(hull, 5.0, tiles, np.array([0.99 * gap / (1 + RIM_REACH)]))
    assert _near_rim(hull, 5.0, tiles, np.array([1.01 * gap / (1 + RIM_REACH)]))


@pytest.fixture(scope="module")
def pathological(tmp_path_factory):
    """A dense cluster (8,000 points within 10 m) in a ring of 400 sparse points 400 m around
    it: the triangles between the ring and the cluster have circumcircles some 400 m across,
    so the ring's tiles need buckets grown over the cluster."""
    rng = np.random.default_rng(11)
    cluster = rng.uniform(395, 405, (8000, 2))
    angle = np.linspace(0, 2 * np.pi, 400, endpoint=False) + 0.001
    ring = 400 + 400 * np.column_stack([np.cos(angle), np.sin(angle)])
    xy = np.vstack([cluster, ring])
    z = 50 + 0.01 * xy[:, 0] + rng.normal(0, 0.05, len(xy))
    return _write(tmp_path_factory.mktemp("tin") / "pathological.laz", xy[:, 0], xy[:, 1], z)


def test_pathological_cloud_bucket_growth_is_capped(pathological, tmp_path, monkeypatch):
    """With buckets capped at 2,000 points (TILE_POINTS), a ring tile whose bucket would have
    to grow over the 8,000-point cluster stops with one clear error naming
    TOOLBOX_STREAM_POINTS; nothing is written."""
    from toolbox.errors import InputDataError
    from toolbox.terrain.gridding import stream

    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    monkeypatch.setattr(stream, "TILE_POINTS", 2000)
    with pytest.raises(InputDataError, match=r"tin_linear: tile \d+.* over the [\d,]+ a tile's "
                                             r"bucket may hold.*TOOLBOX_STREAM_POINTS above 8,400"):
        _run(pathological, tmp_path / "x.tif", {"CELL_SIZE": 8.0, "TILE_SIZE": 16})
    assert not (tmp_path / "x.tif").exists()


def test_pathological_cloud_streams_under_the_default_cap(pathological, tmp_path, monkeypatch):
    """The same cloud under the default cap: the buckets grow (more passes) and the cells equal
    the in-memory TIN's and scipy's."""
    stats, grid, transform = _streamed(pathological, tmp_path, monkeypatch,
                                       {"CELL_SIZE": 8.0, "TILE_SIZE": 16})
    assert stats["streamed"]["tiles_retried"] > 0
    expected = _scipy(pathological, transform, grid.shape)
    inside = np.isfinite(expected) & np.isfinite(grid)
    assert inside.sum() > 0.95 * np.isfinite(expected).sum()
    np.testing.assert_allclose(grid[inside], expected[inside].astype(np.float32), rtol=1e-6)
