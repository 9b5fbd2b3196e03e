"""TIN topology (neighbours, edges with left/right triangles) and per-triangle measures."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.terrain.tin.kernels import triangulate, triangulate_pslg
from toolbox.terrain.tin.topology import (
    edge_table,
    hull_edges,
    neighbors_from_triangles,
    plane_normals,
    triangle_measures,
)

ORIGIN = np.array([1_688_000.0, 4_799_500.0])


@pytest.fixture(scope="module")
def tin():
    xy = ORIGIN + np.random.default_rng(21).uniform(0, 50, (200, 2))
    return xy, triangulate_pslg(xy)


def test_neighbour_ids_are_symmetric_and_share_the_edge(tin):
    _, result = tin
    tri, nb = result.triangles, result.neighbors
    for t, j in zip(*np.nonzero(nb >= 0), strict=True):
        other = nb[t, j]
        assert t in nb[other]
        back = int(np.flatnonzero(nb[other] == t)[0])
        edge = {tri[t, (j + 1) % 3], tri[t, (j + 2) % 3]}
        assert edge == {tri[other, (back + 1) % 3], tri[other, (back + 2) % 3]}


def test_neighbours_rebuilt_from_triangles_equal_triangles_own(tin):
    _, result = tin
    np.testing.assert_array_equal(neighbors_from_triangles(result.triangles), result.neighbors)


def test_edge_table_lists_each_edge_once_with_left_and_right(tin):
    xy, result = tin
    tri, nb = result.triangles, result.neighbors
    edges = edge_table(tri, nb)
    n, hull = len(xy), len(hull_edges(tri, nb))
    assert len(edges.nodes) == 3 * n - 3 - hull  # Euler: E = 3n - 3 - h
    assert len({tuple(sorted(e)) for e in edges.nodes.tolist()}) == len(edges.nodes)
    assert (edges.right == -1).sum() == hull
    for e, (a, b) in enumerate(edges.nodes):
        left = list(tri[edges.left[e]])
        i = left.index(a)
        assert left[(i + 1) % 3] == b  # a -> b runs counter-clockwise around the left triangle
        if edges.right[e] >= 0:
            right = list(tri[edges.right[e]])
            i = right.index(b)
            assert right[(i + 1) % 3] == a  # and clockwise around the right one
    # each triangle's edge ids point to edges made of its other two nodes
    for t in range(len(tri)):
        for j in range(3):
            assert set(edges.nodes[edges.triangle_edges[t, j]]) == \
                {tri[t, (j + 1) % 3], tri[t, (j + 2) % 3]}


def test_edge_table_is_compact_and_equals_scipy_delaunay_edges():
    """Indices are stored as int32 (half the memory of a 10 M-point TIN's table); the edges are
    those of scipy's (Qhull) Delaunay triangulation of the same points."""
    from scipy.spatial import Delaunay

    xy = ORIGIN + np.random.default_rng(5).uniform(0, 50, (500, 2))
    tri = triangulate(xy)
    edges = edge_table(tri, neighbors_from_triangles(tri))
    assert all(a.dtype == np.int32 for a in (edges.nodes, edges.left, edges.right,
                                             edges.triangle_edges))
    simplices = Delaunay(xy - ORIGIN).simplices
    oracle = {tuple(sorted(e)) for s in simplices.tolist()
              for e in ((s[0], s[1]), (s[1], s[2]), (s[2], s[0]))}
    assert {tuple(sorted(e)) for e in edges.nodes.tolist()} == oracle


def test_edges_of_a_square():
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    tri = triangulate(xy)
    edges = edge_table(tri, neighbors_from_triangles(tri))
    assert len(edges.nodes) == 5 and (edges.right >= 0).sum() == 1


def test_neighbours_refuse_an_edge_shared_by_three_triangles():
    tri = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(ValueError, match="more than two"):
        neighbors_from_triangles(tri)


def test_measures_of_known_planes():
    # z = x: slope 45 deg (100 %), facing west (aspect 270); z = -y: facing north (0);
    # flat: aspect -1
    xy = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]) + ORIGIN
    tri = np.array([[0, 1, 2]])
    cases = [(xy[:, 0] - ORIGIN[0], 45.0, 100.0, 270.0),
             (-(xy[:, 1] - ORIGIN[1]), 45.0, 100.0, 0.0),
             (2.0 * (xy[:, 1] - ORIGIN[1]), np.degrees(np.arctan(2.0)), 200.0, 180.0),
             (np.full(3, 5.0), 0.0, 0.0, -1.0)]
    for z, slope, pct, aspect in cases:
        m = triangle_measures(np.column_stack([xy, z]), tri)
        assert m.area_2d[0] == pytest.approx(2.0)
        assert m.slope_deg[0] == pytest.approx(slope)
        assert m.slope_pct[0] == pytest.approx(pct)
        assert m.aspect_deg[0] == pytest.approx(aspect)
        assert m.area_3d[0] == pytest.approx(2.0 / np.cos(np.radians(slope)))


def test_plane_normals_match_eq_43():
    p = np.array([[1.0, 2.0, 3.0], [4.0, 1.0, 5.0], [2.0, 6.0, 4.0]])
    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = p
    a = y1 * (z2 - z3) + y2 * (z3 - z1) + y3 * (z1 - z2)
    b = z1 * (x2 - x3) + z2 * (x3 - x1) + z3 * (x1 - x2)
    c = x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2)
    np.testing.assert_allclose(plane_normals(p, np.array([[0, 1, 2]]))[0], [a, b, c])
