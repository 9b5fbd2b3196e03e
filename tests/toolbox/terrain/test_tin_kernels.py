"""TIN kernels: Delaunay properties, constrained edges, plane interpolation, rasterisation."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.terrain.tin.kernels import (
    interpolate_tin,
    rasterize_tin,
    triangles_by_tile,
    triangulate,
    triangulate_pslg,
)

ORIGIN = np.array([1_688_000.0, 4_799_500.0])  # Siena, Monte Mario / Italy zone 1


def random_points(n: int, seed: int = 0, size: float = 100.0) -> np.ndarray:
    return ORIGIN + np.random.default_rng(seed).uniform(0, size, (n, 2))


def plane(x, y):
    """Known truth: z = 300 + 0.05 (x - x0) - 0.02 (y - y0)."""
    return 300.0 + 0.05 * (x - ORIGIN[0]) - 0.02 * (y - ORIGIN[1])


def edge_set(triangles: np.ndarray) -> set[tuple[int, int]]:
    t = triangles
    pairs = np.vstack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return set(map(tuple, np.sort(pairs, axis=1).tolist()))


def signed_area2(xy, tri):
    p = xy[tri] - xy[tri[:, :1]]
    return p[:, 1, 0] * p[:, 2, 1] - p[:, 2, 0] * p[:, 1, 1]


# -- triangulation ---------------------------------------------------------------------------------
def test_delaunay_empty_circumcircle_and_triangle_count():
    import shapely

    xy = random_points(400, seed=1)
    tri = triangulate(xy)
    assert tri.dtype == np.int32 and tri.shape[1] == 3
    local = xy - ORIGIN
    assert (signed_area2(local, tri) > 0).all()  # counter-clockwise
    # 2n - 2 - h triangles, h = points on the convex hull
    hull = shapely.convex_hull(shapely.multipoints(local))
    h = len(hull.exterior.coords) - 1
    assert len(tri) == 2 * len(xy) - 2 - h
    # no point strictly inside any triangle's circumcircle (in-circle determinant)
    a, b, c = local[tri[:, 0]], local[tri[:, 1]], local[tri[:, 2]]
    for p in local:
        ad, bd, cd = a - p, b - p, c - p
        det = ((ad[:, 0] ** 2 + ad[:, 1] ** 2) * (bd[:, 0] * cd[:, 1] - cd[:, 0] * bd[:, 1])
               - (bd[:, 0] ** 2 + bd[:, 1] ** 2) * (ad[:, 0] * cd[:, 1] - cd[:, 0] * ad[:, 1])
               + (cd[:, 0] ** 2 + cd[:, 1] ** 2) * (ad[:, 0] * bd[:, 1] - bd[:, 0] * ad[:, 1]))
        assert det.max() <= 1e-6, "a point lies inside a circumcircle"
    assert set(np.unique(tri)) == set(range(len(xy)))  # every point is a node


def test_large_coordinates_give_the_same_triangles_as_local_ones():
    xy = random_points(300, seed=2, size=1.0)  # 1 m patch at 1.7e6 / 4.8e6 m
    far = {tuple(sorted(t)) for t in triangulate(xy).tolist()}
    near = {tuple(sorted(t)) for t in triangulate(xy - ORIGIN).tolist()}
    assert far == near


def test_every_breakline_segment_is_an_edge():
    xy = random_points(300, seed=3)
    # three zig-zag breaklines through extra vertices; they do not cross each other
    lines = []
    for k, y in enumerate((20.0, 50.0, 80.0)):
        xs = np.linspace(2, 98, 9)
        ys = y + np.where(np.arange(9) % 2 == 0, -6.0, 6.0)
        lines.append(ORIGIN + np.column_stack([xs, ys + k * 0.1]))
    start = len(xy)
    segments = []
    for line in lines:
        idx = np.arange(start, start + len(line))
        segments.append(np.column_stack([idx[:-1], idx[1:]]))
        start += len(line)
    all_xy = np.vstack([xy, *lines])
    segments = np.vstack(segments)
    constrained = edge_set(triangulate(all_xy, segments))
    unconstrained = edge_set(triangulate(all_xy))
    wanted = set(map(tuple, np.sort(segments, axis=1).tolist()))
    assert wanted <= constrained
    assert not wanted <= unconstrained  # the constraint did change the triangulation


def test_crossing_segments_are_refused_or_split_at_the_intersection():
    xy = ORIGIN + np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [3.0, 6.0]])
    crossing = np.array([[0, 2], [1, 3]])
    with pytest.raises(ValueError, match="cross"):
        triangulate(xy, crossing)
    result = triangulate_pslg(xy, crossing)
    assert result.steiner_count == 1
    np.testing.assert_allclose(result.vertices[5], ORIGIN + [5.0, 5.0], atol=1e-9)
    np.testing.assert_array_equal(result.vertices[:5], xy)  # inputs unchanged
    # the four halves are constrained edges, each traced back to its input segment
    pieces = {tuple(sorted(s)): p for s, p in zip(result.segments.tolist(),
                                                  result.segment_parents.tolist(), strict=True)}
    assert pieces[(0, 5)] == 0 and pieces[(2, 5)] == 0
    assert pieces[(1, 5)] == 1 and pieces[(3, 5)] == 1
    assert {(0, 5), (2, 5), (1, 5), (3, 5)} <= edge_set(result.triangles)


@pytest.mark.parametrize("xy, message", [
    (np.array([[0.0, 0.0], [1.0, 1.0]]), "at least 3"),
    (np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]), "collinear"),
    (np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0]]), "duplicated"),
    (np.array([[0.0, 0.0], [np.nan, 0.0], [0.0, 1.0]]), "NaN"),
])
def test_bad_points_raise_clear_errors(xy, message):
    with pytest.raises(ValueError, match=message):
        triangulate(xy)


def test_bad_segments_raise():
    xy = random_points(10)
    with pytest.raises(ValueError, match="index the 10 points"):
        triangulate(xy, np.array([[0, 10]]))
    with pytest.raises(ValueError, match=r"\(M, 2\) integer"):
        triangulate(xy, np.array([[0.0, 1.0]]))


# -- interpolation ---------------------------------------------------------------------------------
def test_interpolation_reproduces_a_plane_and_is_nan_outside():
    xy = random_points(500, seed=4)
    xyz = np.column_stack([xy, plane(xy[:, 0], xy[:, 1])])
    # the four corners are nodes, so the TIN covers the whole square
    xy[:4] = ORIGIN + np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])
    xyz = np.column_stack([xy, plane(xy[:, 0], xy[:, 1])])
    tri = triangulate(xy)
    q = ORIGIN + np.random.default_rng(5).uniform(0, 100, (2000, 2))
    z = interpolate_tin(xyz, tri, q[:, 0], q[:, 1])
    np.testing.assert_allclose(z, plane(q[:, 0], q[:, 1]), rtol=0, atol=1e-9)
    # the nodes themselves, and points far outside
    np.testing.assert_allclose(interpolate_tin(xyz, tri, xy[:, 0], xy[:, 1]), xyz[:, 2], atol=1e-9)
    out = interpolate_tin(xyz, tri, ORIGIN[0] + np.array([-5.0, 150.0, np.nan]),
                          ORIGIN[1] + np.array([50.0, 50.0, 50.0]))
    assert np.isnan(out).all()


def test_interpolation_matches_scipy_linear_interpolator():
    from scipy.interpolate import LinearNDInterpolator

    xy = random_points(800, seed=6)
    z = np.random.default_rng(7).normal(300, 10, len(xy))
    xyz = np.column_stack([xy, z])
    q = ORIGIN + np.random.default_rng(8).uniform(-10, 110, (400, 2))
    ours = interpolate_tin(xyz, triangulate(xy), q[:, 0], q[:, 1])
    theirs = LinearNDInterpolator(xy - ORIGIN, z)(q - ORIGIN)
    np.testing.assert_array_equal(np.isnan(ours), np.isnan(theirs))
    np.testing.assert_allclose(ours[~np.isnan(ours)], theirs[~np.isnan(theirs)], atol=1e-9)


def test_interpolation_tolerance_snaps_points_just_outside_the_border():
    xy = ORIGIN + np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    xyz = np.column_stack([xy, [0.0, 10.0, 20.0, 10.0]])  # z = x + y
    tri = triangulate(xy)
    qx, qy = ORIGIN[0] + np.array([5.0, 5.0]), ORIGIN[1] + np.array([-1e-6, -0.5])
    assert np.isnan(interpolate_tin(xyz, tri, qx, qy)).all()
    z = interpolate_tin(xyz, tri, qx, qy, tolerance=1e-3)
    assert z[0] == pytest.approx(5.0, abs=1e-9) and np.isnan(z[1])


# -- rasterisation ---------------------------------------------------------------------------------
def grid_centres(x0, y0, cell, width, height):
    x = x0 + (np.arange(width) + 0.5) * cell
    y = y0 - (np.arange(height) + 0.5) * cell
    return np.meshgrid(x, y)


def test_rasterize_gives_the_plane_at_cell_centres_and_nan_outside():
    from scipy.spatial import Delaunay

    xy = random_points(300, seed=9)
    xyz = np.column_stack([xy, plane(xy[:, 0], xy[:, 1])])
    tri = triangulate(xy)
    x0, y0, cell, w, h = ORIGIN[0] - 3, ORIGIN[1] + 104, 0.7, 160, 155
    z = rasterize_tin(xyz, tri, x0, y0, cell, cell, w, h)
    gx, gy = grid_centres(x0, y0, cell, w, h)
    inside = Delaunay(xy - ORIGIN).find_simplex(np.column_stack([gx.ravel(), gy.ravel()])
                                                 - ORIGIN).reshape(h, w) >= 0
    np.testing.assert_array_equal(~np.isnan(z), inside)
    np.testing.assert_allclose(z[inside], plane(gx, gy)[inside], rtol=0, atol=1e-9)


def test_rasterize_leaves_no_crack_on_shared_edges():
    # a regular lattice: many cell centres fall exactly on triangle edges and nodes
    gx, gy = np.meshgrid(np.arange(0.0, 11.0), np.arange(0.0, 11.0))
    xy = ORIGIN + np.column_stack([gx.ravel(), gy.ravel()])
    xyz = np.column_stack([xy, np.sin(gx.ravel()) + gy.ravel()])
    tri = triangulate(xy)
    z = rasterize_tin(xyz, tri, ORIGIN[0] - 0.5, ORIGIN[1] + 10.5, 1.0, 1.0, 11, 11)
    assert not np.isnan(z).any()  # every centre is on the lattice, inside the TIN
    np.testing.assert_allclose(z[::-1].ravel(), xyz[:, 2], atol=1e-12)


def test_rasterize_by_tiles_equals_one_pass():
    xy = random_points(400, seed=10)
    xyz = np.column_stack([xy, np.random.default_rng(11).normal(300, 5, len(xy))])
    tri = triangulate(xy)
    x0, y0, cell, w, h, tile = ORIGIN[0], ORIGIN[1] + 100, 0.5, 200, 200, 64
    full = rasterize_tin(xyz, tri, x0, y0, cell, cell, w, h)
    order, start, ntx = triangles_by_tile(xy, tri, x0, y0, cell, cell, w, h, tile)
    tiled = np.full((h, w), np.nan)
    for k in range(len(start) - 1):
        r0, c0 = (k // ntx) * tile, (k % ntx) * tile
        ww, hh = min(tile, w - c0), min(tile, h - r0)
        tiled[r0:r0 + hh, c0:c0 + ww] = rasterize_tin(
            xyz, tri[order[start[k]:start[k + 1]]], x0 + c0 * cell, y0 - r0 * cell, cell, cell,
            ww, hh)
    np.testing.assert_array_equal(tiled, full)


def test_rasterize_rectangular_cells_and_errors():
    xy = ORIGIN + np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    xyz = np.column_stack([xy, [0.0, 10.0, 20.0, 10.0]])
    z = rasterize_tin(xyz, triangulate(xy), ORIGIN[0], ORIGIN[1] + 10, 2.0, 5.0, 5, 2)
    gx, gy = grid_centres(0.0, 10.0, 1.0, 5, 2)
    expected = (np.arange(5) + 0.5) * 2.0 + np.array([[7.5], [2.5]])
    np.testing.assert_allclose(z, expected, atol=1e-12)
    with pytest.raises(ValueError, match="cell_x and cell_y must be > 0"):
        rasterize_tin(xyz, triangulate(xy), 0, 0, 0.0, 1.0, 2, 2)
