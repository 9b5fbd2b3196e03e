"""Round 16 (cdt): the CDT triangulation with many crossing breaklines (pieces and their parent
segments from array lookups) and the spatially ordered insertion of plain points.

Truth: crossings computed here by brute force from the segment pairs (orientation tests and
the line-line intersection), the Delaunay empty-circle property, and Triangle on random points
(a Delaunay triangulation of points in general position is unique)."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.terrain.tin import kernels
from toolbox.terrain.tin.kernels import (
    MEMORY_ORDER_MIN_POINTS,
    _memory_order,
    triangulate_pslg,
)


def _crossing_points(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Proper intersections of every pair of segments a[i]-b[i], brute force (m^2 pairs)."""
    points = []
    for i in range(len(a)):
        for j in range(i + 1, len(a)):
            p, r, q, s = a[i], b[i] - a[i], a[j], b[j] - a[j]
            den = r[0] * s[1] - r[1] * s[0]
            if den == 0:
                continue
            t = ((q - p)[0] * s[1] - (q - p)[1] * s[0]) / den
            u = ((q - p)[0] * r[1] - (q - p)[1] * r[0]) / den
            if 0 < t < 1 and 0 < u < 1:
                points.append(p + t * r)
    return np.array(points).reshape(-1, 2)


def _triangle_codes(triangles: np.ndarray, n: int) -> np.ndarray:
    """Sorted codes of the triangles as vertex sets (order of rows and corners ignored)."""
    t = np.sort(np.asarray(triangles, dtype=np.int64), axis=1)
    return np.sort((t[:, 0] * n + t[:, 1]) * n + t[:, 2])


def _edges(triangles: np.ndarray) -> set[tuple[int, int]]:
    e = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                                triangles[:, [2, 0]]]), axis=1)
    return set(map(tuple, e.tolist()))


def test_crossing_breaklines_split_at_every_crossing_into_triangle_edges():
    rng = np.random.default_rng(16)
    m = 60
    ends = rng.uniform(0.0, 100.0, (2 * m, 2))
    xy = np.vstack([ends, rng.uniform(0.0, 100.0, (300, 2))])
    seg = np.arange(2 * m).reshape(-1, 2)
    tri = triangulate_pslg(xy, seg)
    truth = _crossing_points(ends[0::2], ends[1::2])
    assert len(truth) > 300  # random long segments: many crossings
    assert tri.steiner_count == len(truth)
    added = tri.vertices[tri.n_input:]
    # each added vertex is one of the true crossings (and each crossing is matched once)
    d = np.hypot(*(added[:, None, :] - truth[None, :, :]).transpose(2, 0, 1))
    assert d.min(axis=1).max() < 1e-9
    assert len(np.unique(d.argmin(axis=1))) == len(truth)
    edges = _edges(tri.triangles)
    pieces = np.sort(tri.segments, axis=1)
    assert set(map(tuple, pieces.tolist())) <= edges  # every piece is a triangle edge
    for k in range(m):
        mine = pieces[tri.segment_parents == k]
        a, b = ends[2 * k], ends[2 * k + 1]
        on = np.unique(mine)
        # the pieces of segment k: its two ends and its crossings, a chain from end to end
        direction = (b - a) / np.hypot(*(b - a))
        along = (tri.vertices[on] - a) @ direction
        off = (tri.vertices[on] - a) @ np.array([-direction[1], direction[0]])
        assert np.abs(off).max() < 1e-9
        chain = on[np.argsort(along)]
        assert chain[0] == 2 * k and chain[-1] == 2 * k + 1
        assert set(map(tuple, np.sort(np.column_stack([chain[:-1], chain[1:]]), axis=1)
                       .tolist())) == set(map(tuple, mine.tolist()))
    # every crossing vertex lies on exactly two input segments (4 piece ends)
    ends_of = np.bincount(pieces.ravel(), minlength=len(tri.vertices))
    assert (ends_of[tri.n_input:] == 4).all()


def test_pieces_of_overlapping_and_touching_segments_keep_every_parent():
    # a 5 x 5 grid; segments along grid lines overlap, pass through vertices, repeat
    g = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), -1).reshape(-1, 2)
    seg = np.array([[0, 4], [0, 2], [1, 3], [4, 0], [0, 24], [6, 18]])
    tri = triangulate_pslg(g, seg)
    assert tri.steiner_count == 0
    rows = set(zip(map(tuple, np.sort(tri.segments, axis=1).tolist()),
                   tri.segment_parents.tolist()))
    # hand count: 0-4 is split at 1, 2, 3; 0-2 lies on it (0-1, 1-2); 1-3 too; 4-0 repeats 0-4
    # (its pieces are the first one's); the diagonal 0-24 passes 6, 12, 18; 6-18 lies on it
    expected = {((0, 1), 0), ((1, 2), 0), ((2, 3), 0), ((3, 4), 0),
                ((0, 1), 1), ((1, 2), 1), ((1, 2), 2), ((2, 3), 2),
                ((0, 6), 4), ((6, 12), 4), ((12, 18), 4), ((18, 24), 4),
                ((6, 12), 5), ((12, 18), 5)}
    assert rows == expected
    assert _edges(tri.triangles) >= {p for p, _ in rows}


def test_random_points_same_triangles_as_triangle():
    triangle = pytest.importorskip("triangle")
    rng = np.random.default_rng(1616)
    xy = rng.uniform(0.0, 1000.0, (MEMORY_ORDER_MIN_POINTS + 10, 2)) + [1_685_000.0, 4_795_000.0]
    assert _memory_order(xy)[0] is not None  # the points go to CDT in Z-order
    ours = triangulate_pslg(xy, neighbors=False, parents=False, triangulator="cdt").triangles
    ref = triangle.triangulate({"vertices": xy - xy.min(axis=0)}, "")["triangles"]
    assert np.array_equal(_triangle_codes(ours, len(xy)), _triangle_codes(ref, len(xy)))


def test_memory_order_gives_the_same_arrays_even_on_cocircular_points(monkeypatch):
    # 3000 copies of six points exactly on one circle (integer points of x^2 + y^2 = 5^6,
    # scaled and shifted by powers of two: exact), all x distinct and all y distinct, among
    # random points: where such a circle is empty, the Delaunay triangulation is not unique
    # and depends on the insertion order (checked below), yet the Z-ordered array must give
    # CDT's very triangles, in the same order, with the same neighbours
    import pythoncdt as cdt

    rng = np.random.default_rng(5)
    ring = np.array([[35, 120], [44, 117], [75, 100], [100, 75], [117, 44], [120, 35]]) / 64.0
    assert ((ring * 64) ** 2).sum(axis=1).tolist() == [5 ** 6] * 6
    offsets = np.round(rng.uniform(0, 1e5, (3000, 2)) * 1024) / 1024
    xy = np.vstack([(ring[None] + offsets[:, None]).reshape(-1, 2),
                    rng.uniform(0, 1e5, (MEMORY_ORDER_MIN_POINTS - 17_000, 2))])
    assert len(np.unique(xy[:, 0])) == len(xy) and len(np.unique(xy[:, 1])) == len(xy)
    fast = triangulate_pslg(xy, triangulator="cdt")
    monkeypatch.setattr(kernels, "MEMORY_ORDER_MIN_POINTS", 10 ** 12)
    plain = triangulate_pslg(xy, triangulator="cdt")
    assert np.array_equal(fast.triangles, plain.triangles)
    assert np.array_equal(fast.neighbors, plain.neighbors)
    # another insertion order breaks the cocircular ties otherwise: the check above has teeth
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AS_PROVIDED,
                          cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
    flip = np.ascontiguousarray(xy[::-1] - xy.min(axis=0))
    t.insert_vertices(flip)
    other = t.triangles_array()["vertices"].astype(np.int64)
    other = len(xy) - 1 - (other[(other >= 3).all(axis=1)] - 3)
    assert not np.array_equal(_triangle_codes(other, len(xy)),
                              _triangle_codes(plain.triangles, len(xy)))


def test_memory_order_not_taken_on_shared_coordinates():
    grid = np.stack(np.meshgrid(np.arange(600.0), np.arange(600.0)), -1).reshape(-1, 2)
    assert _memory_order(grid) == (None, True)
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 100, (MEMORY_ORDER_MIN_POINTS, 2))
    assert _memory_order(xy)[0] is not None and _memory_order(xy)[1]
    xy[5000, 1] = xy[200_000, 1]  # one shared y, far apart: meets no median split
    assert _memory_order(xy)[0] is not None and _memory_order(xy)[1]
    xy[4100:4120, 0] = xy[4120, 0]  # 21 points on one x: not worth following
    order, exact = _memory_order(xy)
    assert order is not None and not exact  # kept only if the triangulation is unique
    xy[:20, 0] = xy[20, 0]  # among the first points: likely a grid, as given
    assert _memory_order(xy) == (None, True)
    assert _memory_order(xy[:1000]) == (None, True)  # small: as given


def _cdt_triangles(xy: np.ndarray, perm: np.ndarray | None = None) -> np.ndarray:
    """CDT's triangles of ``xy`` given to it in the order ``perm``, numbered as in ``xy``."""
    import pythoncdt as cdt

    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                          cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
    t.insert_vertices(np.ascontiguousarray(xy if perm is None else xy[perm]))
    v = t.triangles_array()["vertices"].astype(np.int64)
    v = v[(v >= 3).all(axis=1)] - 3
    return v if perm is None else perm[v]


def _tied_neighbour(seed: int) -> np.ndarray:
    """Random points where point 0's nearest neighbour gets point 0's x."""
    b = np.random.default_rng(seed).uniform(0, 1000, (MEMORY_ORDER_MIN_POINTS, 2))
    d = np.hypot(*(b - b[0]).T)
    d[0] = np.inf
    b[int(np.argmin(d)), 0] = b[0, 0]
    return b


def test_memory_order_refused_where_a_shared_x_makes_a_split_ambiguous():
    xy = _tied_neighbour(0)
    order, exact = _memory_order(xy)
    assert order is not None and not exact
    # and rightly: another array order gives CDT other triangle arrays there
    perm = np.argsort(np.random.default_rng(99).random(len(xy)))
    assert not np.array_equal(_cdt_triangles(xy), _cdt_triangles(xy, perm))


def test_memory_order_taken_with_a_harmless_shared_x_gives_the_same_arrays(monkeypatch):
    xy = _tied_neighbour(1)
    assert len(np.unique(xy[:, 0])) == len(xy) - 1
    assert _memory_order(xy)[1]
    fast = triangulate_pslg(xy, triangulator="cdt")
    monkeypatch.setattr(kernels, "MEMORY_ORDER_MIN_POINTS", 10 ** 12)
    plain = triangulate_pslg(xy, triangulator="cdt")
    assert np.array_equal(fast.triangles, plain.triangles)
    assert np.array_equal(fast.neighbors, plain.neighbors)
