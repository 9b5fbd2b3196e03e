"""Round 18: where shared coordinates may change CDT's insertion sequence (breakline vertices on
common x values, as in the benchmark), the points still go to CDT in Z-order, and the result is
kept only if it is the unique constrained Delaunay triangulation (no edge with four cocircular
points, no crossing vertex); else the run is redone with the points as given. Truth: the run
without the ordering (the same triangle set), Shewchuk's Triangle (an independent
implementation), exact integer in-circle determinants."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from tests.toolbox.terrain.test_round17_cdtspeed import SMALL, _codes, _runs
from toolbox.terrain.tin import kernels
from toolbox.terrain.tin.kernels import _memory_order, cocircular_edge_count
from toolbox.terrain.tin.unique_kernel import cocircular_edges


def _zigzag_breaklines(seed: int, lines: int = 20, vertices: int = 30):
    """Random points, then zig-zag breaklines whose vertices share 30 x values and 2 y values
    per line (the benchmark's layout, smaller)."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(0, 1e4, (SMALL + 5000, 2))
    lx = np.linspace(10.0, 9990.0, vertices)
    gap = 1e4 / (lines + 1)
    rows, segments = [], []
    for k in range(lines):
        ly = (k + 1) * gap + np.where(np.arange(vertices) % 2 == 0, -gap / 4, gap / 4)
        start = len(points) + k * vertices
        rows.append(np.column_stack([lx, ly]))
        idx = np.arange(start, start + vertices)
        segments.append(np.column_stack([idx[:-1], idx[1:]]))
    return np.vstack([points, *rows]), np.vstack(segments)


def _same_neighbours(tri) -> bool:
    """Each neighbour shares the edge opposite its corner (the arrays stay consistent)."""
    t, nb = tri.triangles, tri.neighbors
    for j in range(3):
        has = nb[:, j] >= 0
        edge = np.sort(np.column_stack([t[has, (j + 1) % 3], t[has, (j + 2) % 3]]), axis=1)
        other = t[nb[has, j]]
        shares = ((other == edge[:, :1]).any(axis=1) & (other == edge[:, 1:]).any(axis=1))
        if not shares.all():
            return False
    return True


def test_breaklines_on_shared_coordinates_go_in_z_order_and_give_the_same_triangles(
        monkeypatch):
    xy, seg = _zigzag_breaklines(7)
    monkeypatch.setattr(kernels, "MEMORY_ORDER_MIN_POINTS", SMALL)
    order, exact = _memory_order(xy - xy.min(axis=0), seg.ravel())
    assert order is not None and not exact  # before: None (the points as given)
    fast, plain, kept = _runs(monkeypatch, xy, seg)
    assert kept == [True]  # the ordered run was used
    assert np.array_equal(_codes(fast.triangles), _codes(plain.triangles))
    assert np.array_equal(fast.vertices, plain.vertices)
    pieces = [set(map(tuple, np.sort(r.segments, axis=1).tolist())) for r in (fast, plain)]
    assert pieces[0] == pieces[1] and len(pieces[0]) == len(seg)
    assert _same_neighbours(fast)
    triangle = pytest.importorskip("triangle")
    ref = triangle.triangulate({"vertices": xy, "segments": seg}, "pc")["triangles"]
    assert np.array_equal(_codes(fast.triangles), _codes(ref))


def test_cocircular_points_on_shared_coordinates_fall_back_to_the_points_as_given(
        monkeypatch):
    # random points with an empty square holding a 12 x 12 lattice (squares of four cocircular
    # points, Delaunay-empty), the lattice after the first 4096 points
    rng = np.random.default_rng(8)
    points = rng.uniform(0, 1e4, (SMALL + 5000, 2))
    points = points[~((points > 4000) & (points < 6000)).all(axis=1)]
    lattice = np.stack(np.meshgrid(np.arange(12.0), np.arange(12.0)), -1).reshape(-1, 2)
    xy = np.vstack([points, 4500.0 + 80.0 * lattice])
    fast, plain, kept = _runs(monkeypatch, xy, None)
    assert kept == [False]  # maybe not the only triangulation: redone as given
    for name in ("triangles", "neighbors", "vertices"):
        assert np.array_equal(getattr(fast, name), getattr(plain, name)), name


def _exact_cocircular(xy: np.ndarray, rows: np.ndarray) -> int:
    """The edges of ``rows`` (CDT's (T, 6) layout) whose four points lie exactly on one circle,
    in rational arithmetic."""
    q = [(Fraction(x), Fraction(y)) for x, y in xy.tolist()]
    count = 0
    for t, row in enumerate(rows.tolist()):
        for i in range(3):
            o = row[3 + i]
            if o >= len(rows) or o <= t:
                continue
            a, b, c = row[i], row[(i + 1) % 3], row[(i + 2) % 3]
            d = sum(rows[o, :3].tolist()) - a - b
            (ax, ay), (bx, by), (cx, cy), (dx, dy) = q[a], q[b], q[c], q[d]
            ax, ay, bx, by, cx, cy = ax - dx, ay - dy, bx - dx, by - dy, cx - dx, cy - dy
            det = ((ax * ax + ay * ay) * (bx * cy - cx * by)
                   + (bx * bx + by * by) * (cx * ay - ax * cy)
                   + (cx * cx + cy * cy) * (ax * by - bx * ay))
            count += det == 0
    return count


def test_cocircular_edge_count_equals_exact_arithmetic():
    import pythoncdt as cdt

    rng = np.random.default_rng(9)
    lattice = np.stack(np.meshgrid(np.arange(0.0, 40.0, 4.0), np.arange(0.0, 40.0, 4.0)),
                       -1).reshape(-1, 2)
    scattered = rng.integers(41, 90, (300, 2)).astype(float)
    xy = np.unique(np.vstack([lattice, scattered]), axis=0)
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                          cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
    t.insert_vertices(xy)
    coords = t.vertices_array().view(np.float64).reshape(-1, 2)
    rows = t.triangles_array().view(np.uint32).reshape(-1, 6)
    exact = _exact_cocircular(coords, rows)
    assert exact >= 81  # one diagonal in each of the lattice's 9 x 9 squares
    assert cocircular_edges(coords, rows) == exact  # the JIT
    assert cocircular_edge_count(coords, rows) == exact  # the compiled build where there is one
    jitter = coords + rng.uniform(-1e-3, 1e-3, coords.shape) * (np.arange(len(coords)) >= 3)[:, None]
    assert cocircular_edges(jitter, rows) == _exact_cocircular(jitter, rows) == 0
