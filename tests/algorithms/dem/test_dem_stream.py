"""Streamed gridding of a point cloud (toolbox/terrain/gridding/stream.py): the same cells as the
in-memory path (the oracle), nearest also against scipy's k-d tree, never more than one chunk
of the cloud held, and the runs that cannot stream refused with one line."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest
import rasterio
from conftest import run_cli
from scipy.spatial import cKDTree

import toolbox
import toolbox.io.pointcloud as pointcloud
from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.io.pointcloud import PointFilter, open_point_cloud, write_point_cloud
from toolbox.raster.grid_request import GridRequest
from toolbox.terrain.gridding.methods import METHODS
from toolbox.terrain.gridding.request import Execution, GriddingRequest, PointSources
from toolbox.terrain.gridding.run import grid_dem
from toolbox.terrain.gridding.stream import grid_dem_streamed, plan_boxes, scan_cloud, spill

X0, Y0, N = 1_688_000.0, 4_799_500.0, 20_000


@pytest.fixture(scope="module")
def cloud(tmp_path_factory):
    """20,000 points over 200 x 150 m (classes 2 and 5) with 200 exact XY duplicates of other
    heights, as LAZ."""
    rng = np.random.default_rng(29)
    x, y = X0 + rng.uniform(0, 200, N), Y0 + rng.uniform(0, 150, N)
    x, y = np.round(x, 3), np.round(y, 3)  # on the LAZ's 1 mm lattice: duplicates stay exact
    z = 300 + 10 * np.sin(x / 40) * np.cos(y / 30) + rng.normal(0, 0.2, N)
    dup = rng.choice(N - 200, 200, replace=False)
    x[-200:], y[-200:] = x[dup], y[dup]
    cls = np.where(rng.random(N) < 0.8, 2, 5)
    cls[-200:] = 2
    cls[dup] = 2
    path = tmp_path_factory.mktemp("stream") / "cloud.laz"
    write_point_cloud(path, np.column_stack([x, y, z]), "EPSG:3003", classification=cls)
    return path


def _grid(path):
    with rasterio.open(path) as ds:
        return ds.read(1, masked=True).filled(np.nan), ds.transform


def _run(method, cloud, out, extra=None):
    params = {"INPUT": str(cloud), "CLASSES": "2", "CELL_SIZE": 2.0, "TILE_SIZE": 32,
              "OUTPUT": str(out), "OVERVIEWS": False, **(extra or {})}
    return toolbox.run(f"dem:{method}", params)["STATISTICS"]


@pytest.mark.parametrize("method, extra", [
    ("nearest", {}), ("idw", {"NEIGHBOURS": 8}), ("plane", {}),
    ("idw", {"NEIGHBOURS": 6, "SECTORS": 4, "RADIUS": 6.0}),
    ("nearest", {"MAX_DISTANCE": 1.0, "DUPLICATES": "first"}),
    ("idw", {"EXTRAPOLATE": True, "EXTENT": f"{X0 - 40},{Y0 - 30},{X0 + 230},{Y0 + 170}"})])
def test_streamed_equals_in_memory(cloud, tmp_path, monkeypatch, method, extra):
    memory = _run(method, cloud, tmp_path / "memory.tif", extra)
    assert "streamed" not in memory
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    streamed = _run(method, cloud, tmp_path / "stream.tif", extra)
    info = streamed["streamed"]
    assert info["tiles"] >= 8 and info["chunk_points"] == 1000
    assert info["bucket_points_max"] < N / 3
    a, ta = _grid(tmp_path / "memory.tif")
    b, tb = _grid(tmp_path / "stream.tif")
    assert ta == tb and a.shape == b.shape
    assert np.isfinite(a).sum() > 0.5 * a.size
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_array_equal(a, b)  # the same points, the same kernel: the same cells
    assert streamed["duplicates"] == memory["duplicates"]
    assert streamed["duplicates"]["duplicate_groups"] >= 100
    assert streamed["points_used"] == memory["points_used"]
    assert streamed["cells"]["cells_with_value"] == memory["cells"]["cells_with_value"]


def test_streamed_nearest_against_a_kd_tree(cloud, tmp_path, monkeypatch):
    """Independent reference: scipy's cKDTree over the class-2 points (duplicates merged by
    their mean, as DUPLICATES=mean), at the cell centres that have a value."""
    import laspy

    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    _run("nearest", cloud, tmp_path / "s.tif")
    grid, t = _grid(tmp_path / "s.tif")
    las = laspy.read(cloud)
    keep = np.asarray(las.classification) == 2
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])[keep]
    xy, inverse = np.unique(xyz[:, :2], axis=0, return_inverse=True)
    z = np.bincount(inverse.ravel(), xyz[:, 2]) / np.bincount(inverse.ravel())
    rows, cols = np.nonzero(np.isfinite(grid))
    cx, cy = t.c + (cols + 0.5) * t.a, t.f + (rows + 0.5) * t.e
    _, idx = cKDTree(xy - (X0, Y0)).query(np.column_stack([cx - X0, cy - Y0]))
    np.testing.assert_array_equal(grid[rows, cols], z[idx].astype(np.float32))


def test_streaming_holds_one_chunk_not_the_cloud(cloud, tmp_path):
    """Chunks of 500 of 20,000 points: the Python heap's peak (numpy arrays included) of both
    passes stays below a third of the 480 kB of all the points' coordinates (a chunk costs
    about 250 bytes a record while it is decoded and binned); the whole streamed run's, below
    a third of the in-memory run's."""
    ref = open_point_cloud(cloud)
    flt = PointFilter((2,))
    request = GriddingRequest(PointSources(points=ref, classes="2"), tmp_path / "o.tif",
                              GridRequest(cell_size=2.0), execution=Execution(tile_size=32,
                                                                              overviews=False))
    all_points = N * 3 * 8
    # imports and numba kernels first (their allocations are not the streaming's)
    grid_dem_streamed(METHODS["nearest"], request, Feedback(), chunk_points=500)
    request.output.unlink()
    tracemalloc.start()
    try:
        scan = scan_cloud(ref, flt, None, 500)
        _, scan_peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        grid = request.grid.grid(scan.bounds, ref.crs)
        boxes = plan_boxes(grid, 32, scan, 1, np.inf)
        folder = tmp_path / "buckets"
        folder.mkdir()
        tracemalloc.reset_peak()
        written = spill(ref, flt, None, 500, boxes, folder)
        _, spill_peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        stats = grid_dem_streamed(METHODS["nearest"], request, Feedback(), chunk_points=500)
        _, run_peak = tracemalloc.get_traced_memory()
        request.output.unlink()
        tracemalloc.reset_peak()
        grid_dem(METHODS["nearest"], request, Feedback())  # in memory: the same cells
        _, memory_peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert written.sum() >= scan.kept
    assert stats["streamed"]["tiles"] >= 8
    assert scan_peak < all_points / 3
    assert spill_peak < all_points / 3
    # the tiles: a few buckets in flight (the engine's prefetch), not the cloud
    assert run_peak < memory_peak / 3


@pytest.mark.parametrize("cell, tile, k", [(2.0, 32, 8), (0.5, 16, 40)])
def test_bucket_files_hold_every_point_near_their_tile(cloud, tmp_path, cell, tile, k):
    """Every kept point is in the bucket of every tile whose grown box holds it (numpy check of
    the spill's neighbour-tile shortcut), in file order; also with reaches over a tile's side."""
    ref = open_point_cloud(cloud)
    flt = PointFilter((2,))
    scan = scan_cloud(ref, flt, None, 777)
    grid = GridRequest(cell_size=cell).grid(scan.bounds, ref.crs)
    boxes = plan_boxes(grid, tile, scan, k, np.inf)
    if tile == 16:
        assert boxes.reach.max() > 16 * cell  # neighbours two tiles away are searched
    spill(ref, flt, None, 777, boxes, tmp_path)
    xyz, _ = pointcloud.read_xyz(ref, flt)
    for t, rect in enumerate(boxes.rects):
        inside = (xyz[:, 0] >= rect[0]) & (xyz[:, 0] <= rect[2]) & (xyz[:, 1] >= rect[1]) \
            & (xyz[:, 1] <= rect[3])
        path = tmp_path / f"{t}.xyz"
        got = np.fromfile(path).reshape(-1, 3) if path.exists() else np.zeros((0, 3))
        np.testing.assert_array_equal(got, xyz[inside])


@pytest.mark.parametrize("method, extra, name", [
    ("tin_linear", {"DUPLICATE_TOLERANCE": 0.5}, "DUPLICATE_TOLERANCE"),
    ("nearest", {"DUPLICATE_TOLERANCE": 0.5}, "DUPLICATE_TOLERANCE")])
def test_runs_that_cannot_stream_are_refused(cloud, tmp_path, monkeypatch, method, extra, name):
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    with pytest.raises(ParameterError, match=f"^{name} .*TOOLBOX_STREAM_POINTS"):
        _run(method, cloud, tmp_path / "x.tif", extra)
    assert not (tmp_path / "x.tif").exists()


def test_cli_refusal_is_one_line(cloud, tmp_path, monkeypatch):
    """A run that cannot stream (DUPLICATE_TOLERANCE > 0 with a cloud over the limit) is
    refused with its reason, one line, nothing written."""
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    out = tmp_path / "q.tif"
    res = run_cli("run", "dem:tin_linear", "--INPUT", cloud, "--CELL_SIZE", 2, "--OUTPUT", out,
                  "--DUPLICATE_TOLERANCE", 0.5, "--QUALITY", tmp_path / "q.json")
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr
    assert lines[0].count("DUPLICATE_TOLERANCE") and "got 0.5" in lines[0]
    assert not out.exists() and not (tmp_path / "q.json").exists()
    json.dumps(lines)


def _quality(method, cloud, tmp_path, monkeypatch, extra):
    """(in-memory report, streamed report, streamed STATISTICS) of QUALITY, the streamed run
    on tiles of 8 x 8 buckets (several tiles) and chunks of 1,000 points."""
    import toolbox.terrain.gridding.stream_quality as stream_quality

    _run(method, cloud, tmp_path / "m.tif", {**extra, "QUALITY": str(tmp_path / "m.json")})
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    monkeypatch.setattr(stream_quality, "FIRST_BLOCK", 8)
    stats = _run(method, cloud, tmp_path / "s.tif", {**extra, "QUALITY": str(tmp_path / "s.json")})
    memory = json.loads((tmp_path / "m.json").read_text())
    streamed = json.loads((tmp_path / "s.json").read_text())
    return memory, streamed, stats


@pytest.mark.parametrize("method, extra", [
    ("nearest", {}), ("idw", {"NEIGHBOURS": 8}), ("plane", {}), ("cubic", {}),
    ("idw", {"NEIGHBOURS": 6, "SECTORS": 4, "RADIUS": 6.0}),
    ("idw", {"NEIGHBOURS": 8, "RADIUS": 3.0, "MIN_NEIGHBOURS": 3}),
    ("nearest", {"MAX_DISTANCE": 1.0, "DUPLICATES": "first"}),
    ("idw", {"EXTRAPOLATE": True, "POWER": 1.0}),
    ("tin_linear", {}), ("tin_linear", {"MAX_DISTANCE": 1.5, "DUPLICATES": "first"}),
    ("tin_linear", {"EXTRAPOLATE": True})])
def test_streamed_quality_equals_in_memory(cloud, tmp_path, monkeypatch, method, extra):
    """The in-memory QUALITY is the oracle: the same counts, the same worst point (its index,
    its prediction), the same maximum error; the sums (RMSE, mean, ...) to the rounding of
    their order of summation."""
    memory, streamed, stats = _quality(method, cloud, tmp_path, monkeypatch, extra)
    a, b = memory["methods"][method], streamed["methods"][method]
    info = b.pop("streamed")
    assert info["tiles"] >= 9 and info["bucket_points_max"] < N / 3
    assert stats["cross_validation"]["rmse"] == b["rmse"]
    assert a["predicted"] > 0.5 * a["points"]
    assert streamed["points"] == memory["points"] and streamed["crs"] == memory["crs"]
    assert streamed["duplicates"] == memory["duplicates"]
    assert streamed["duplicates"]["duplicate_groups"] >= 100
    sums = ("rmse", "mean_error", "mean_abs_error", "std_error")
    assert {k: v for k, v in b.items() if k not in sums} == \
        {k: v for k, v in a.items() if k not in sums}
    for key in sums:
        assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-15), key


def test_streamed_quality_nearest_against_a_kd_tree(cloud, tmp_path, monkeypatch):
    """Independent reference: scipy's cKDTree over the distinct class-2 positions (duplicates
    merged by their mean): each point predicted by its nearest other point, the convex hull's
    vertices (scipy's ConvexHull) left out."""
    import laspy
    from scipy.spatial import ConvexHull

    _, streamed, _ = _quality("nearest", cloud, tmp_path, monkeypatch, {})
    cv = streamed["methods"]["nearest"]
    las = laspy.read(cloud)
    keep = np.asarray(las.classification) == 2
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])[keep]
    xy, inverse = np.unique(xyz[:, :2], axis=0, return_inverse=True)
    z = np.bincount(inverse.ravel(), xyz[:, 2]) / np.bincount(inverse.ravel())
    _, idx = cKDTree(xy - (X0, Y0)).query(xy - (X0, Y0), k=2)
    err = z[idx[:, 1]] - z
    hull = ConvexHull(xy - (X0, Y0)).vertices
    err[hull] = np.nan
    err = err[np.isfinite(err)]
    assert cv["points"] == len(xy) and cv["hull_vertices_not_predicted"] == len(hull)
    assert cv["predicted"] == len(err)
    assert cv["rmse"] == pytest.approx(np.sqrt(np.mean(err ** 2)), rel=1e-12)
    assert cv["mean_error"] == pytest.approx(err.mean(), rel=1e-9)
    assert cv["max_abs_error"] == np.abs(err).max()


def test_streamed_quality_of_a_plane_is_exact(tmp_path, monkeypatch):
    """Analytic: points of a plane (heights exact on the LAZ's 1 mm lattice): dem:plane's
    leave-one-out predicts every inner point exactly, the 4 corners of the square (its hull
    vertices) are not predicted."""
    rng = np.random.default_rng(5)
    x, y = rng.integers(1, 300, 6000).astype(float), rng.integers(1, 300, 6000).astype(float)
    xy = np.unique(np.column_stack([x, y]), axis=0)
    xy = np.vstack([xy, [[0, 0], [300, 0], [0, 300], [300, 300]]])
    z = 120.0 + 0.25 * xy[:, 0] - 0.5 * xy[:, 1]
    path = tmp_path / "plane.laz"
    write_point_cloud(path, np.column_stack([X0 + xy[:, 0], Y0 + xy[:, 1], z]), "EPSG:3003")
    import toolbox.terrain.gridding.stream_quality as stream_quality

    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    monkeypatch.setattr(stream_quality, "FIRST_BLOCK", 4)
    toolbox.run("dem:plane", {"INPUT": str(path), "CELL_SIZE": 10.0, "TILE_SIZE": 16,
                              "OUTPUT": str(tmp_path / "p.tif"),
                              "QUALITY": str(tmp_path / "p.json")})
    cv = json.loads((tmp_path / "p.json").read_text())["methods"]["plane"]
    assert cv["streamed"]["tiles"] >= 9
    assert cv["points"] == len(xy) and cv["hull_vertices_not_predicted"] == 4
    assert cv["predicted"] == len(xy) - 4 and cv["max_abs_error"] < 1e-9


@pytest.mark.parametrize("rim", [2, 10_000])
def test_streamed_tin_quality_grows_its_tiles(cloud, tmp_path, monkeypatch, rim):
    """tin_linear with first reaches a tenth of the planned ones: tiles whose stars reach past
    their bucket are spilled again with the reach doubled, with the rim along the hull held
    (2 buckets) or not (10,000: the hull shrunk by it is empty); the report is still the
    in-memory one."""
    from dataclasses import replace

    import toolbox.terrain.gridding.stream_quality as stream_quality

    plan = stream_quality.plan_quality

    def short(*args):
        tiles, boxes = plan(*args)
        return tiles, replace(boxes, reach=boxes.reach / 10)

    monkeypatch.setattr(stream_quality, "plan_quality", short)
    monkeypatch.setattr(stream_quality, "RIM_BUCKETS", rim)
    memory, streamed, _ = _quality("tin_linear", cloud, tmp_path, monkeypatch, {})
    a, b = memory["methods"]["tin_linear"], streamed["methods"]["tin_linear"]
    info = b.pop("streamed")
    assert info["passes"] >= 2 and info["tiles_retried"] > 0
    assert (info["rim_points"] is None) == (rim > 2)
    sums = ("rmse", "mean_error", "mean_abs_error", "std_error")
    assert {k: v for k, v in b.items() if k not in sums} == \
        {k: v for k, v in a.items() if k not in sums}
    for key in sums:
        assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-15), key


@pytest.mark.parametrize("jitter", [False, True])
def test_streamed_tin_quality_settles_points_on_straight_hull_edges(tmp_path, monkeypatch, jitter):
    """A 90 x 60 grid of points 1 m apart (a survey grid): the points along its four straight
    edges are on the convex hull's boundary but not its vertices, their stars open in the TIN
    of the whole cloud. Streamed with buckets capped at 2,000 points they settle (they never
    did: the run ended with an error) and the report is the in-memory one. Plain grid on a
    plane: every point but the 4 corners predicted exactly (analytic). Inner points moved
    (general position) with a 3 m spike on the edge at (45, 0): the spike is the worst point,
    its prediction the plane of its triangle in scipy's Delaunay TIN of the other points."""
    from scipy.spatial import Delaunay

    import toolbox.terrain.gridding.stream as stream
    import toolbox.terrain.gridding.stream_quality as stream_quality

    gx, gy = np.meshgrid(np.arange(90.0), np.arange(60.0))
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    if jitter:
        rng = np.random.default_rng(3)
        inner = (xy[:, 0] > 0) & (xy[:, 0] < 89) & (xy[:, 1] > 0) & (xy[:, 1] < 59)
        xy[inner] += np.round(rng.uniform(-0.3, 0.3, (int(inner.sum()), 2)), 3)
        z = np.round(300 + 10 * np.sin(xy[:, 0] / 20) * np.cos(xy[:, 1] / 15)
                     + rng.normal(0, 0.2, len(xy)), 3)
        spike = int(np.flatnonzero((xy[:, 0] == 45) & (xy[:, 1] == 0))[0])
        z[spike] += 3.0
    else:
        z = 120.0 + 0.25 * xy[:, 0] - 0.5 * xy[:, 1]
    path = tmp_path / "grid.laz"
    write_point_cloud(path, np.column_stack([X0 + xy[:, 0], Y0 + xy[:, 1], z]), "EPSG:3003")
    params = {"INPUT": str(path), "CELL_SIZE": 2.0, "TILE_SIZE": 16, "OVERVIEWS": False}
    toolbox.run("dem:tin_linear", {**params, "OUTPUT": str(tmp_path / "m.tif"),
                                   "QUALITY": str(tmp_path / "m.json")})
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "1000")
    monkeypatch.setattr(pointcloud, "CHUNK_POINTS", 1000)
    monkeypatch.setattr(stream_quality, "FIRST_BLOCK", 4)
    monkeypatch.setattr(stream, "TILE_POINTS", 2000)
    toolbox.run("dem:tin_linear", {**params, "OUTPUT": str(tmp_path / "s.tif"),
                                   "QUALITY": str(tmp_path / "s.json")})
    a = json.loads((tmp_path / "m.json").read_text())["methods"]["tin_linear"]
    b = json.loads((tmp_path / "s.json").read_text())["methods"]["tin_linear"]
    info = b.pop("streamed")
    assert info["tiles"] >= 9 and info["bucket_points_max"] <= 2000
    assert b["hull_vertices_not_predicted"] == 4 and b["predicted"] == len(xy) - 4
    sums = ("rmse", "mean_error", "mean_abs_error", "std_error")
    assert {k: v for k, v in b.items() if k not in sums} == \
        {k: v for k, v in a.items() if k not in sums}
    for key in sums:
        assert b[key] == pytest.approx(a[key], rel=1e-12, abs=1e-15), key
    if not jitter:
        assert b["max_abs_error"] < 1e-9
        return
    others = np.delete(np.column_stack([xy, z]), spike, axis=0)
    tin = Delaunay(others[:, :2])
    s = int(tin.find_simplex(xy[spike]))
    assert s >= 0
    weights = tin.transform[s, :2] @ (xy[spike] - tin.transform[s, 2])
    expected = others[tin.simplices[s], 2] @ np.r_[weights, 1 - weights.sum()]
    worst = b["worst_point"]
    assert (worst["x"], worst["y"]) == (X0 + 45, Y0)
    assert worst["predicted"] == pytest.approx(expected, rel=1e-12)
