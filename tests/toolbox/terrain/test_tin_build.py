"""Building a TIN: duplicates, crossing breaklines, boundary clip, concave hull, bad input."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from toolbox.terrain.tin.build import BOUNDARY, BREAKLINE, CROSSING, POINT, TinBuildError, build_tin
from toolbox.terrain.tin.kernels import interpolate_tin
from toolbox.terrain.tin.topology import edge_table

ORIGIN = np.array([1_688_000.0, 4_799_500.0, 0.0])


def grid_points(n: int = 11, size: float = 100.0, seed: int = 0) -> np.ndarray:
    """Jittered grid of points on the plane z = 0.1 x (local x)."""
    g = np.linspace(0, size, n)
    gx, gy = np.meshgrid(g, g)
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    xy[:, :2] += np.random.default_rng(seed).uniform(-1, 1, xy.shape) * (size / n / 4)
    xy = np.clip(xy, 0, size)
    return ORIGIN + np.column_stack([xy, 0.1 * xy[:, 0]])


def polygons(model):
    xy = model.xyz[:, :2]
    tri = model.triangles
    return shapely.polygons(np.concatenate([xy[tri], xy[tri][:, :1]], axis=1))


def test_duplicates_are_merged_by_the_rule_and_reported():
    pts = grid_points()
    dup = pts[[5, 5, 17]].copy()
    dup[:, 2] = [10.0, 20.0, 99.0]
    data = np.vstack([pts, dup])
    for rule, z5 in (("mean", (pts[5, 2] + 30.0) / 3), ("min", min(pts[5, 2], 10.0)),
                     ("max", 20.0), ("first", pts[5, 2])):
        model = build_tin(data, duplicate_rule=rule)
        assert model.report["duplicates"]["duplicates_removed"] == 3
        assert model.report["duplicates"]["duplicate_groups"] == 2
        assert len(model.xyz) == len(pts)
        node = np.flatnonzero((model.xyz[:, :2] == pts[5, :2]).all(axis=1))[0]
        assert model.xyz[node, 2] == pytest.approx(z5)
        assert model.merged[node] == 3
    with pytest.raises(TinBuildError, match="different Z"):
        build_tin(data, duplicate_rule="error")


def test_breakline_vertex_wins_over_a_mass_point_with_rule_first():
    pts = grid_points()
    line = np.array([pts[12], pts[13]])
    line[:, 2] = [50.0, 60.0]
    model = build_tin(pts, line, np.array([0, 0]), duplicate_rule="first")
    node = np.flatnonzero((model.xyz[:, :2] == pts[12, :2]).all(axis=1))[0]
    assert model.xyz[node, 2] == 50.0 and model.source[node] == BREAKLINE


def test_tolerance_merges_near_points():
    pts = grid_points()
    near = pts[[40]] + [0.001, 0.0, 1.0]
    model = build_tin(np.vstack([pts, near]), duplicate_tolerance=0.01)
    assert len(model.xyz) == len(pts)
    assert model.report["duplicates"]["max_z_spread"] == pytest.approx(1.0)


def test_crossing_breaklines_are_split_with_interpolated_z():
    pts = grid_points()
    # two breaklines crossing at local (50.5, 50.5) without a shared vertex
    lines = ORIGIN + np.array([[10.5, 10.5, 10.0], [90.5, 90.5, 20.0],   # z at crossing 15
                               [10.5, 90.5, 30.0], [90.5, 10.5, 40.0]])  # z at crossing 35
    model = build_tin(pts, lines, np.array([0, 0, 1, 1]))
    crossing = np.flatnonzero(model.source == CROSSING)
    assert len(crossing) == 1
    np.testing.assert_allclose(model.xyz[crossing[0]], ORIGIN + [50.5, 50.5, 25.0], atol=1e-9)
    assert model.report["crossings"] == {"count": 1, "max_z_disagreement": pytest.approx(20.0)}
    # all four halves are triangle edges flagged as breakline edges
    edges = {tuple(sorted(e)) for e in edge_table(model.triangles, model.neighbors).nodes.tolist()}
    ends = [np.flatnonzero((model.xyz[:, :2] == p[:2]).all(axis=1))[0] for p in lines]
    for end in ends:
        pair = tuple(sorted((end, crossing[0])))
        assert pair in edges
        assert pair in {tuple(e) for e in model.breakline_edges.tolist()}


def test_contours_with_constant_height_keep_the_surface_off_the_flat_triangles():
    # a cone of contour rings: every breakline segment must be an edge
    rings, index = [], []
    for k, (r, z) in enumerate(((10.0, 30.0), (20.0, 20.0), (30.0, 10.0))):
        a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
        ring = np.column_stack([50 + r * np.cos(a), 50 + r * np.sin(a), np.full(40, z)])
        ring = np.vstack([ring, ring[:1]])  # closed
        rings.append(ORIGIN + ring)
        index.append(np.full(41, k))
    model = build_tin(np.zeros((0, 3)), np.vstack(rings), np.concatenate(index))
    assert model.report["breakline_segments"] == 120
    assert model.report["breakline_repeated_vertices"] == 3  # the closing vertices
    assert model.report["duplicates"]["duplicates_removed"] == 0 and len(model.xyz) == 120
    edges = {tuple(sorted(e)) for e in edge_table(model.triangles, model.neighbors).nodes.tolist()}
    assert {tuple(e) for e in model.breakline_edges.tolist()} <= edges
    assert len(model.breakline_edges) == 120


def test_boundary_clips_hard_with_a_hole():
    pts = grid_points(n=21)
    boundary = shapely.Polygon(
        [(20, -10), (120, 30), (80, 80), (50, 40), (20, 80)],
        holes=[[(40, 20), (50, 20), (45, 30)]])
    boundary = shapely.transform(boundary, lambda c: c + ORIGIN[:2])
    model = build_tin(pts, boundary=boundary)
    hull = shapely.convex_hull(shapely.multipoints(pts[:, :2]))
    region = shapely.intersection(boundary, hull)
    covered = shapely.union_all(polygons(model))
    assert covered.area == pytest.approx(region.area, rel=1e-12)
    assert shapely.symmetric_difference(covered, region).area < 1e-6
    clip = model.report["boundary"]
    assert clip["boundary_area_outside_data_hull"] > 0  # (120, 30) and (20, -10) are outside
    assert clip["nodes_dropped_outside"] > 0
    # boundary nodes lie on the plane of the points (their Z comes from the unclipped TIN)
    b = model.source == BOUNDARY
    assert b.sum() >= 8
    np.testing.assert_allclose(model.xyz[b, 2], 0.1 * (model.xyz[b, 0] - ORIGIN[0]), atol=1e-9)


def test_concave_hull_keeps_every_node_and_removes_the_gap():
    # a C-shaped set: convex hull spans the gap, concave hull does not
    pts = grid_points(n=21)
    local = pts[:, :2] - ORIGIN[:2]
    keep = ~((local[:, 0] > 30) & (local[:, 1] > 30) & (local[:, 1] < 70))
    pts = pts[keep]
    convex = build_tin(pts)
    concave = build_tin(pts, concave=True, concave_max_edge=12.0)
    assert len(concave.xyz) == len(pts) == len(convex.xyz)
    assert concave.report["concave_hull"]["triangles_removed"] > 0
    a_convex = shapely.area(polygons(convex)).sum()
    a_concave = shapely.area(polygons(concave)).sum()
    assert a_concave < a_convex - 0.5 * 60 * 30  # most of the 70 x 40 gap is gone
    gap_centre = ORIGIN[:2] + [70.0, 50.0]
    assert np.isnan(interpolate_tin(concave.xyz, concave.triangles, gap_centre[:1],
                                    gap_centre[1:]))[0]
    # still one piece, neighbours consistent
    nb = concave.neighbors
    for t, j in zip(*np.nonzero(nb >= 0), strict=True):
        assert t in nb[nb[t, j]]


def test_default_concave_threshold_is_reported():
    model = build_tin(grid_points(), concave=True)
    assert model.report["concave_hull"]["max_edge"] > 0


@pytest.mark.parametrize("points, message", [
    (ORIGIN + np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]), "at least 3 points"),
    (ORIGIN + np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0], [2.0, 2.0, 1.0]]), "collinear"),
    (ORIGIN + np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0], [1.0, 1.0, 1.0]]), "3 distinct"),
])
def test_too_few_or_collinear_points_fail_clearly(points, message):
    with pytest.raises(TinBuildError, match=message):
        build_tin(points)


def test_boundary_outside_the_data_fails_clearly():
    far = shapely.box(0, 0, 10, 10)
    with pytest.raises(TinBuildError, match="does not overlap"):
        build_tin(grid_points(), boundary=far)


def test_sources_are_counted():
    model = build_tin(grid_points())
    assert (model.source == POINT).all() and (model.merged == 1).all()


def test_boundary_parts_touching_at_a_vertex_share_one_node():
    pts = grid_points(n=21)
    boxes = shapely.MultiPolygon([shapely.box(10, 10, 50, 50), shapely.box(50, 50, 90, 90)])
    boxes = shapely.transform(boxes, lambda c: c + ORIGIN[:2])
    model = build_tin(pts, boundary=boxes)
    assert model.report["boundary"]["boundary_nodes_added"] <= 7
    covered = shapely.union_all(polygons(model))
    assert shapely.symmetric_difference(covered, boxes).area < 1e-6
