"""The rewritten TIN build kernels against independent oracles: CDT's neighbours (renumbered
through one lookup table), the Euler-count shortcut of the every-vertex-used check, the
x-first duplicate test and the flat-index edge table. They give the arrays of the code they
replaced (a refactor for speed): these tests pin them to brute force, scipy and set logic."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.terrain.tin import kernels
from toolbox.terrain.tin.build import _has_duplicate_xy
from toolbox.terrain.tin.kernels import _uses_every_vertex, triangulate_pslg
from toolbox.terrain.tin.topology import edge_table

ORIGIN = np.array([1_688_000.0, 4_799_500.0])
TRIANGULATORS = ["cdt"]
try:
    import triangle  # noqa: F401

    TRIANGULATORS.append("triangle")
except ImportError:
    pass


def brute_neighbours(tri: np.ndarray) -> np.ndarray:
    """Neighbour across the edge facing each corner, by a dictionary of undirected edges."""
    owners: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for t, row in enumerate(tri.tolist()):
        for j in range(3):
            key = tuple(sorted((row[(j + 1) % 3], row[(j + 2) % 3])))
            owners.setdefault(key, []).append((t, j))
    out = np.full(tri.shape, -1, dtype=np.int64)
    for pair in owners.values():
        if len(pair) == 2:
            (t, j), (u, k) = pair
            out[t, j], out[u, k] = u, t
    return out


@pytest.mark.parametrize("z_order", [False, True])
def test_cdt_neighbours_equal_a_brute_force_edge_match(monkeypatch, z_order):
    """With and without the Z-order run (its renumbering), with constrained segments."""
    if z_order:
        monkeypatch.setattr(kernels, "MEMORY_ORDER_MIN_POINTS", 100)
    rng = np.random.default_rng(21)
    xy = ORIGIN + rng.uniform(0, 100, (1500, 2))
    seg = np.array([[0, 1], [2, 3], [4, 5]])
    result = triangulate_pslg(xy, seg, triangulator="cdt")
    assert result.neighbors.dtype == np.int32
    np.testing.assert_array_equal(result.neighbors, brute_neighbours(result.triangles))


@pytest.mark.parametrize("name", TRIANGULATORS)
def test_a_duplicate_point_is_found_with_neighbours_asked(name):
    """Triangle leaves a duplicate out silently: the Euler count (T + h + 2) / 2 = V misses one
    vertex and the scan names it; CDT refuses it itself."""
    xy = ORIGIN + np.random.default_rng(3).uniform(0, 50, (300, 2))
    xy = np.vstack([xy, xy[17]])
    with pytest.raises(ValueError, match="duplicated in XY"):
        triangulate_pslg(xy, triangulator=name)


def test_euler_count_against_the_vertices_really_used():
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(8)
    for n in (3, 4, 10, 200):
        d = Delaunay(rng.uniform(0, 1, (n, 2)))
        tri, nb = d.simplices, d.neighbors
        used = len(np.unique(tri))
        assert _uses_every_vertex(tri, nb, n) == (used == n)
        assert not _uses_every_vertex(tri, nb, n + 1)  # one more vertex than the triangles use
        assert not _uses_every_vertex(tri, np.zeros((0, 3)), n)  # no neighbours: no verdict
    # a grid: collinear hull points and four points on every circle
    g = np.stack(np.meshgrid(np.arange(12.0), np.arange(9.0)), -1).reshape(-1, 2)
    result = triangulate_pslg(ORIGIN + g)
    assert _uses_every_vertex(result.triangles, result.neighbors, len(g))
    assert len(np.unique(result.triangles)) == len(g)


def test_duplicate_xy_test_equals_a_set_of_pairs():
    rng = np.random.default_rng(4)
    base = np.column_stack([rng.integers(0, 6, 40).astype(float),
                            rng.integers(0, 6, 40).astype(float), rng.uniform(0, 1, 40)])
    cases = [
        base,  # many shared x, some exact duplicates
        np.unique(base[:, :2], axis=0),  # shared x and y, no duplicate
        np.array([[0.0, 1.0, 0.0], [-0.0, 1.0, 5.0], [2.0, 3.0, 0.0]]),  # -0.0 == 0.0
        np.array([[1.0, 1.0, 0.0], [1.0, 2.0, 0.0], [2.0, 1.0, 0.0]]),  # shared x, shared y
        np.column_stack([rng.uniform(0, 1, (1000, 2)), np.zeros(1000)]),  # nothing shared
        np.array([[np.nan, 1.0, 0.0], [np.nan, 1.0, 0.0], [2.0, 3.0, 0.0]]),  # NaN != NaN
    ]
    for xyz in cases:
        pairs = [(float(x), float(y)) for x, y in xyz[:, :2] if x == x and y == y]
        assert _has_duplicate_xy(xyz) == (len(set(pairs)) < len(pairs)), xyz[:5]


def brute_edge_table(tri: np.ndarray, nb: np.ndarray):
    """Each edge once from its lower-index triangle, ordered by triangle then corner."""
    nodes, left, right = [], [], []
    ids = np.full(tri.shape, -1, dtype=np.int64)
    for t in range(len(tri)):
        for j in range(3):
            u = int(nb[t, j])
            if u < 0 or t < u:
                ids[t, j] = len(nodes)
                nodes.append((int(tri[t, (j + 1) % 3]), int(tri[t, (j + 2) % 3])))
                left.append(t)
                right.append(u)
    for t in range(len(tri)):
        for j in range(3):
            u = int(nb[t, j])
            if 0 <= u < t:
                k = list(nb[u]).index(t)
                ids[t, j] = ids[u, k]
    return np.array(nodes).reshape(-1, 2), np.array(left), np.array(right), ids


@pytest.mark.parametrize("dtype", [np.int32, np.int64])
def test_edge_table_equals_a_brute_force_on_scipy_delaunay(dtype):
    from scipy.spatial import Delaunay

    d = Delaunay(np.random.default_rng(6).uniform(0, 1, (300, 2)))
    tri, nb = d.simplices.astype(dtype), d.neighbors.astype(dtype)  # neighbour j faces corner j
    edges = edge_table(tri, nb)
    nodes, left, right, ids = brute_edge_table(tri, nb)
    for got, want in ((edges.nodes, nodes), (edges.left, left), (edges.right, right),
                      (edges.triangle_edges, ids)):
        assert got.dtype == np.int32
        np.testing.assert_array_equal(got, want)


def test_edge_table_of_no_triangle_and_of_one():
    empty = edge_table(np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64))
    assert empty.nodes.shape == (0, 2) and empty.triangle_edges.shape == (0, 3)
    one = edge_table(np.array([[4, 5, 6]]), np.array([[-1, -1, -1]]))
    np.testing.assert_array_equal(one.nodes, [[5, 6], [6, 4], [4, 5]])
    np.testing.assert_array_equal(one.right, [-1, -1, -1])
    np.testing.assert_array_equal(one.triangle_edges, [[0, 1, 2]])
