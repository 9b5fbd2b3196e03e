"""The two constrained Delaunay triangulators behind toolbox.terrain.tin.kernels, run through the
same tests: pythoncdt (CDT, MPL-2.0, the default) and Triangle (the optional extra).

References are independent: scipy.spatial.Delaunay (Qhull) for the unconstrained triangulation,
and each library against the other for the constrained one (unique on general-position input).
"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest
from scipy.spatial import Delaunay

import toolbox
from toolbox.errors import ToolboxError
from toolbox.terrain.tin.kernels import (
    TRIANGULATOR_ENV,
    triangulate,
    triangulate_pslg,
    triangulator_name,
)

ORIGIN = np.array([1_688_000.0, 4_799_500.0])
HAS_TRIANGLE = importlib.util.find_spec("triangle") is not None
TRIANGULATORS = ["cdt", pytest.param("triangle", marks=pytest.mark.skipif(
    not HAS_TRIANGLE, reason="the [triangle] extra is not installed"))]


def random_points(n: int, seed: int, size: float = 100.0) -> np.ndarray:
    return ORIGIN + np.random.default_rng(seed).uniform(0, size, (n, 2))


def triangle_set(tri: np.ndarray) -> set[tuple[int, ...]]:
    return set(map(tuple, np.sort(tri, axis=1).tolist()))


def edge_set(tri: np.ndarray) -> set[tuple[int, int]]:
    pairs = np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return set(map(tuple, np.sort(pairs, axis=1).tolist()))


def zigzag_breaklines(n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Random points plus three non-crossing zig-zag lines; returns all XY and the segments."""
    xy = random_points(n_points, seed=11)
    lines, segments, start = [], [], len(xy)
    for k, y in enumerate((20.0, 50.0, 80.0)):
        xs = np.linspace(2.3, 97.1, 9)
        ys = y + np.where(np.arange(9) % 2 == 0, -6.0, 6.0) + 0.173 * k
        lines.append(ORIGIN + np.column_stack([xs, ys]))
        idx = np.arange(start, start + 9)
        segments.append(np.column_stack([idx[:-1], idx[1:]]))
        start += 9
    return np.vstack([xy, *lines]), np.vstack(segments)


@pytest.mark.parametrize("name", TRIANGULATORS)
def test_delaunay_equals_scipy_on_general_position_points(name):
    xy = random_points(2000, seed=4)
    ours = triangulate_pslg(xy, triangulator=name)
    reference = Delaunay(xy - ORIGIN).simplices
    assert triangle_set(ours.triangles) == triangle_set(reference)
    p = ours.vertices[ours.triangles] - ORIGIN
    area2 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) \
        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])
    assert (area2 > 0).all()  # counter-clockwise


@pytest.mark.parametrize("name", TRIANGULATORS)
def test_neighbours_face_the_corner(name):
    """neighbors[t, j] is the triangle across the edge opposite corner j; -1 on the hull."""
    tri = triangulate_pslg(random_points(300, seed=5), triangulator=name)
    t, nb = tri.triangles, tri.neighbors
    assert nb.shape == t.shape
    for j in range(3):
        edge = np.sort(t[:, [(j + 1) % 3, (j + 2) % 3]], axis=1)
        inner = nb[:, j] >= 0
        other = t[nb[inner, j]]
        shares = [set(e) <= set(o) for e, o in zip(edge[inner].tolist(), other.tolist(),
                                                    strict=True)]
        assert all(shares)
    # hull edges (no neighbour) are exactly the edges used by one triangle
    pairs = np.sort(np.vstack([t[:, [1, 2]], t[:, [2, 0]], t[:, [0, 1]]]), axis=1)
    _, counts = np.unique(pairs, axis=0, return_counts=True)
    assert (nb == -1).sum() == (counts == 1).sum()


@pytest.mark.parametrize("name", TRIANGULATORS)
def test_every_breakline_is_an_edge(name):
    xy, segments = zigzag_breaklines(400)
    result = triangulate_pslg(xy, segments, triangulator=name)
    wanted = set(map(tuple, np.sort(segments, axis=1).tolist()))
    assert result.steiner_count == 0
    assert wanted <= edge_set(result.triangles)
    assert not wanted <= edge_set(triangulate(xy, triangulator=name))  # the constraint mattered
    constrained = result.segments[result.segment_parents >= 0]
    np.testing.assert_array_equal(np.sort(np.sort(constrained, axis=1), axis=0),
                                  np.sort(np.sort(segments, axis=1), axis=0))


@pytest.mark.skipif(not HAS_TRIANGLE, reason="the [triangle] extra is not installed")
def test_both_give_the_identical_constrained_tin():
    xy, segments = zigzag_breaklines(1500)
    cdt = triangulate_pslg(xy, segments, triangulator="cdt")
    tri = triangulate_pslg(xy, segments, triangulator="triangle")
    assert triangle_set(cdt.triangles) == triangle_set(tri.triangles)
    assert triangle_set(triangulate(xy, triangulator="cdt")) == triangle_set(
        triangulate(xy, triangulator="triangle"))


@pytest.mark.parametrize("name", TRIANGULATORS)
def test_crossing_breaklines_are_split_at_the_intersection(name):
    xy = ORIGIN + np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [3.0, 6.0],
                            [8.0, 2.0]])
    segments = np.array([[0, 2], [1, 3], [4, 5]])
    result = triangulate_pslg(xy, segments, triangulator=name)
    # the diagonals cross at (5, 5); (3, 6)-(8, 2) crosses the first diagonal at (14/3, 14/3)
    # and ends ON the second one (8 + 2 = 10): that vertex splits it, no new vertex there
    assert result.steiner_count == 2
    np.testing.assert_array_equal(result.vertices[:6], xy)
    added = result.vertices[6:] - ORIGIN
    expected = np.array([[5.0, 5.0], [14 / 3, 14 / 3]])
    assert sorted(map(tuple, added.round(9).tolist())) == sorted(
        map(tuple, expected.round(9).tolist()))
    # every piece lies on its parent segment and is an edge of the triangulation
    pieces = result.segments[result.segment_parents >= 0]
    parents = result.segment_parents[result.segment_parents >= 0]
    for (a, b), parent in zip(pieces.tolist(), parents.tolist(), strict=True):
        p, q = xy[segments[parent]] - ORIGIN
        for v in (result.vertices[a] - ORIGIN, result.vertices[b] - ORIGIN):
            cross = (q[0] - p[0]) * (v[1] - p[1]) - (q[1] - p[1]) * (v[0] - p[0])
            assert abs(cross) < 1e-8
    assert set(map(tuple, np.sort(pieces, axis=1).tolist())) <= edge_set(result.triangles)
    for parent in range(3):  # each input segment is covered end to end by its pieces
        mine = pieces[parents == parent]
        length = np.linalg.norm(result.vertices[mine[:, 0]] - result.vertices[mine[:, 1]], axis=1)
        full = np.linalg.norm(xy[segments[parent, 0]] - xy[segments[parent, 1]])
        assert length.sum() == pytest.approx(full)


@pytest.mark.parametrize("name", TRIANGULATORS)
@pytest.mark.parametrize("xy, message", [
    (np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]), "collinear"),
    (np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0]]), "duplicated"),
])
def test_bad_points_give_the_same_errors(name, xy, message):
    with pytest.raises(ValueError, match=message):
        triangulate(xy, triangulator=name)


def test_choice_by_environment(monkeypatch):
    monkeypatch.delenv(TRIANGULATOR_ENV, raising=False)
    assert triangulator_name() == "cdt"  # the redistributable one is the default
    monkeypatch.setenv(TRIANGULATOR_ENV, "Triangle")  # case-insensitive
    if HAS_TRIANGLE:
        assert triangulator_name() == "triangle"
        assert triangulator_name("cdt") == "cdt"  # the argument wins over the variable
    monkeypatch.setenv(TRIANGULATOR_ENV, "delaunator")
    with pytest.raises(ToolboxError, match="TOOLBOX_TRIANGULATOR must be one of cdt, triangle, "
                                           "auto, got 'delaunator'"):
        triangulator_name()
    # without the extra: 'triangle' names the extra to install, 'auto' falls back to CDT
    monkeypatch.setitem(sys.modules, "triangle", None)
    with pytest.raises(ToolboxError, match=r"pip install 'photogrammetry-toolbox\[triangle\]'"):
        triangulator_name("triangle")
    assert triangulator_name("auto") == "cdt"
    monkeypatch.setenv(TRIANGULATOR_ENV, "auto")
    assert len(triangulate(random_points(20, seed=1))) > 0


@pytest.mark.skipif(not HAS_TRIANGLE, reason="the [triangle] extra is not installed")
def test_tin_delaunay_end_to_end_is_the_same_with_both(tmp_path, monkeypatch):
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(3)
    xy = random_points(300, seed=3)
    z = 300 + 0.05 * (xy[:, 0] - ORIGIN[0]) + rng.normal(0, 0.1, len(xy))
    points = gpd.GeoDataFrame(geometry=shapely.points(np.column_stack([xy, z])), crs=3003)
    lines = gpd.GeoDataFrame(geometry=[
        shapely.LineString([ORIGIN + (10, 10), ORIGIN + (90, 90)]),
        shapely.LineString([ORIGIN + (10, 90), ORIGIN + (90, 10)])], crs=3003)
    lines["z"] = [305.0, 305.0]
    results = {}
    for name in ("cdt", "triangle"):
        monkeypatch.setenv(TRIANGULATOR_ENV, name)
        out = tmp_path / f"{name}.gpkg"
        results[name] = toolbox.run("tin:delaunay", {"INPUT": points, "BREAKLINES": lines,
                                                      "BREAKLINES_Z_FIELD": "z",
                                                      "OUTPUT": out})["STATISTICS"]
        results[name] = {k: results[name][k] for k in ("nodes", "triangles", "crossings")}
        frame = gpd.read_file(out, layer="triangles")
        results[name]["area"] = round(float(frame.area.sum()), 6)
    assert results["cdt"] == results["triangle"]
    assert results["cdt"]["crossings"]["count"] == 1


def test_cdt_super_triangle_dropped_as_cdt_does():
    """Our removal of CDT's super-triangle (a numpy filter instead of erase_super_triangle's
    hash sets) gives CDT's own triangles, neighbours and constrained edges, in its order."""
    import pythoncdt as cdt

    from toolbox.terrain.tin.kernels import _cdt

    rng = np.random.default_rng(3)
    for _ in range(5):
        xy = rng.uniform(0, 100, (400, 2))
        seg = rng.integers(0, 400, (8, 2)).astype(np.int32)  # some cross: new vertices
        seg = seg[seg[:, 0] != seg[:, 1]]
        ref = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                                cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
        ref.insert_vertices(xy)
        ref.insert_edges(np.ascontiguousarray(seg, dtype=np.uintc))
        ref.erase_super_triangle()
        tris = ref.triangles_array()
        ref_nb = tris["neighbors"][:, [1, 2, 0]].astype(np.int64)
        ref_nb[ref_nb == cdt.NO_NEIGHBOR] = -1
        vertices = ref.vertices_array()
        added, triangles, nb, pieces, _ = _cdt(xy, seg, True, True)
        np.testing.assert_array_equal(triangles, tris["vertices"])
        np.testing.assert_array_equal(nb, ref_nb)
        np.testing.assert_array_equal(added, np.column_stack([vertices["x"][400:],
                                                              vertices["y"][400:]]))
        assert set(map(tuple, pieces.tolist())) == {(e.v1, e.v2) for e in ref.fixed_edges}


def _points_and_crossing_breaklines(tmp_path):
    import geopandas as gpd
    import shapely

    xy = random_points(1500, seed=8)
    z = 300 + 0.05 * (xy[:, 0] - ORIGIN[0]) + 3 * np.sin((xy[:, 1] - ORIGIN[1]) / 9)
    points = gpd.GeoDataFrame(geometry=shapely.points(np.column_stack([xy, z])), crs=3003)
    points.to_file(tmp_path / "points.gpkg")
    lines = gpd.GeoDataFrame({"z": [305.0, 305.0]}, geometry=[
        shapely.LineString([ORIGIN + (10.3, 10.1), ORIGIN + (89.7, 90.2)]),
        shapely.LineString([ORIGIN + (10.2, 90.4), ORIGIN + (90.1, 10.6)])], crs=3003)
    lines.to_file(tmp_path / "lines.gpkg")
    return xy, z


def _dem(path):
    import rasterio

    with rasterio.open(path) as src:
        return src.read(1, masked=True).astype("float64").filled(np.nan), src.transform


@pytest.mark.parametrize("name", TRIANGULATORS)
def test_dem_tin_linear_equals_scipy_linear_interpolation(name, tmp_path, monkeypatch):
    """dem:tin_linear (points triangulated in bin order, tiles of 64 cells) is the linear
    interpolation on the Delaunay TIN: scipy's griddata (Qhull) is the oracle."""
    from scipy.interpolate import griddata

    monkeypatch.setenv(TRIANGULATOR_ENV, name)
    xy, z = _points_and_crossing_breaklines(tmp_path)
    toolbox.run("dem:tin_linear", {"INPUT": tmp_path / "points.gpkg", "CELL_SIZE": 0.5,
                                   "TILE_SIZE": 64, "OUTPUT": tmp_path / "dem.tif"})
    dem, t = _dem(tmp_path / "dem.tif")
    cx = t.c + (np.arange(dem.shape[1]) + 0.5) * t.a
    cy = t.f + (np.arange(dem.shape[0]) + 0.5) * t.e
    gx, gy = np.meshgrid(cx - ORIGIN[0], cy - ORIGIN[1])
    ref = griddata(xy - ORIGIN, z, (gx, gy), method="linear")
    inside = ~np.isnan(ref) & ~np.isnan(dem)
    assert inside.sum() > 0.95 * np.isfinite(ref).sum()
    np.testing.assert_allclose(dem[inside], ref[inside], atol=1e-4)  # Float32 GeoTIFF


@pytest.mark.skipif(not HAS_TRIANGLE, reason="the [triangle] extra is not installed")
def test_dem_tin_linear_is_the_same_with_both(tmp_path, monkeypatch):
    _points_and_crossing_breaklines(tmp_path)
    dems = {}
    for name in ("cdt", "triangle"):
        monkeypatch.setenv(TRIANGULATOR_ENV, name)
        out = tmp_path / f"{name}.tif"
        toolbox.run("dem:tin_linear", {"INPUT": tmp_path / "points.gpkg",
                                       "BREAKLINES": tmp_path / "lines.gpkg",
                                       "BREAKLINES_Z_FIELD": "z", "CELL_SIZE": 0.5,
                                       "TILE_SIZE": 64, "OUTPUT": out})
        dems[name] = _dem(out)[0]
    np.testing.assert_array_equal(np.isnan(dems["cdt"]), np.isnan(dems["triangle"]))
    ok = ~np.isnan(dems["cdt"])
    np.testing.assert_allclose(dems["cdt"][ok], dems["triangle"][ok], atol=1e-4)
