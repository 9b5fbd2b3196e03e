"""Round 24: the compiled edge table (toolbox.terrain.tin.edge_kernel) against its numpy twin
(topology.edge_table's steps, themselves checked against Qhull's edges and Euler's formula in
test_tin_topology.py): triangulations of random, gridded (cocircular) and breakline-constrained
points, and malformed neighbour tables, give the same four arrays; what the kernel does not take
(int64 ids, a neighbour beyond the triangles) goes to numpy as before. Also: a small TIN, whose
edge table is made once, is written as a big one's, made twice."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolbox.terrain.tin import edge_kernel, store, topology
from toolbox.terrain.tin.build import build_tin
from toolbox.terrain.tin.kernels import triangulate_pslg

FIELDS = ("nodes", "left", "right", "triangle_edges")
ORIGIN = np.array([1_688_000.0, 4_799_500.0])


def numpy_table(tri, nb, monkeypatch) -> topology.EdgeTable:
    with monkeypatch.context() as m:
        m.setattr(topology, "_compiled_edge_arrays", lambda *_: None)
        return topology.edge_table(tri, nb)


def assert_same(kernel_arrays, table: topology.EdgeTable) -> None:
    for name, got in zip(FIELDS, kernel_arrays, strict=True):
        want = getattr(table, name)
        assert got.dtype == want.dtype == np.int32, name
        np.testing.assert_array_equal(got, want, err_msg=name)


def points(kind: str, n: int, rng) -> tuple[np.ndarray, np.ndarray | None]:
    if kind == "grid":  # every cell's four corners on one circle
        side = max(2, int(np.sqrt(n)))
        gx, gy = np.meshgrid(np.arange(side), np.arange(side))
        return ORIGIN + np.c_[gx.ravel(), gy.ravel()] * 2.0, None
    xy = ORIGIN + rng.uniform(0, 100, (max(n, 3), 2))
    if kind == "breaklines":
        m = len(xy) // 4 * 2
        return xy, np.arange(m).reshape(-1, 2)  # disjoint segments, some crossing
    return xy, None


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 400),
       kind=st.sampled_from(["random", "grid", "breaklines"]))
def test_the_kernel_gives_numpys_arrays_on_triangulations(seed, n, kind):
    rng = np.random.default_rng(seed)
    xy, segments = points(kind, n, rng)
    result = triangulate_pslg(xy, segments)
    tri, nb = result.triangles, result.neighbors
    assert tri.dtype == nb.dtype == np.int32  # the triangulation's own arrays
    with pytest.MonkeyPatch.context() as m:
        assert_same(edge_kernel.edge_arrays(tri, nb), numpy_table(tri, nb, m))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), t=st.integers(1, 60))
def test_the_kernel_gives_numpys_arrays_on_malformed_neighbours(seed, t):
    """Neighbours that do not face back (or face back twice): the same arrays all the same,
    the kernel assigning in numpy's order."""
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, 3 * t, (t, 3)).astype(np.int32)
    nb = rng.integers(-2, t, (t, 3)).astype(np.int32)
    with pytest.MonkeyPatch.context() as m:
        assert_same(edge_kernel.edge_arrays(tri, nb), numpy_table(tri, nb, m))


def test_edge_table_takes_the_kernel_only_for_what_it_handles(monkeypatch):
    """int32 C-contiguous arrays with every neighbour a triangle go to the compiled kernel
    when it is built; int64 ids, a strided view or a neighbour beyond the triangles, never
    (numpy's take refuses that neighbour: IndexError, as before)."""
    result = triangulate_pslg(ORIGIN + np.random.default_rng(3).uniform(0, 50, (300, 2)))
    tri, nb = result.triangles, result.neighbors
    calls = []

    def kernel(*arrays):
        calls.append("edge_arrays")
        return edge_kernel.edge_arrays(*arrays)

    monkeypatch.setattr("toolbox.aot.compiled_kernel",
                        lambda name: kernel if name == "edge_arrays" else None)
    table = topology.edge_table(tri, nb)
    assert_same(tuple(getattr(table, f) for f in FIELDS), numpy_table(tri, nb, monkeypatch))
    assert calls == ["edge_arrays"]
    topology.edge_table(tri.astype(np.int64), nb.astype(np.int64))
    topology.edge_table(np.asfortranarray(tri), nb)
    assert calls == ["edge_arrays"]
    bad = nb.copy()
    bad[0, 0] = len(tri)
    with pytest.raises(IndexError):
        topology.edge_table(tri, bad)
    assert calls == ["edge_arrays"]


def test_a_small_tin_made_once_is_written_as_a_big_one_made_twice(tmp_path, monkeypatch):
    """SMALL_TIN_TRIANGLES: the edge table kept from the triangles layer for the edges
    layer gives the very rows of the table made again (every table of the GeoPackage but the
    styles, whose timestamps differ)."""
    rng = np.random.default_rng(8)
    xy = ORIGIN + rng.uniform(0, 300, (2000, 2))
    model = build_tin(np.c_[xy, 250 + rng.normal(0, 2, len(xy))],
                      np.array([[ORIGIN[0] + 10, ORIGIN[1] + 10, 251.0],
                                [ORIGIN[0] + 290, ORIGIN[1] + 280, 255.0]]), np.array([0, 0]))
    kept = tmp_path / "kept.gpkg"
    store.write_tin(kept, model)
    monkeypatch.setattr(store, "SMALL_TIN_TRIANGLES", 0)
    again = tmp_path / "again.gpkg"
    store.write_tin(again, model)

    def tables(path):
        with sqlite3.connect(path) as db:
            names = [r[0] for r in db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table' AND name NOT IN "
                "('layer_styles', 'gpkg_contents') ORDER BY name")]
            return {name: db.execute(f'SELECT * FROM "{name}"').fetchall() for name in names}

    mine, theirs = tables(kept), tables(again)
    assert mine == theirs
    # the nodes' source, written from a numpy str array (the ASCII text path)
    assert {row[3] for row in mine["nodes"]} == {"point", "breakline"}
    assert [row[3] for row in mine["nodes"]] == [store.SOURCES[k] for k in model.source]
    assert len(mine["edges"]) == len(topology.edge_table(model.triangles, model.neighbors).nodes)
