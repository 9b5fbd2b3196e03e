"""Round 24: CDT's triangles and neighbours without its super-triangle, in one compiled pass
(unique_kernel.cdt_tables), against the numpy steps kernels._drop_super_triangle and
_kept_neighbours (whose triangulations are checked against Triangle's and Qhull's in
test_round21_tinbuild_kernels.py and test_tin_topology.py): random, gridded and constrained
point sets, with and without a renumbering, give the same int32 arrays through numba's JIT and,
where built, the compiled module; a build gives the same TIN either way."""

from __future__ import annotations

import numpy as np
import pytest
import pythoncdt as cdt
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolbox.aot import compiled_kernel
from toolbox.terrain.tin import kernels
from toolbox.terrain.tin.unique_kernel import cdt_tables


def cdt_rows(xy: np.ndarray, segments: np.ndarray | None):
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                          cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
    t.insert_vertices(np.ascontiguousarray(xy))
    if segments is not None:
        t.insert_edges(np.ascontiguousarray(segments, dtype=np.uintc))
    return t, t.triangles_array(copy=False)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 300), grid=st.booleans(),
       constrained=st.booleans(), renumbered=st.booleans())
def test_the_kernel_gives_the_numpy_tables(seed, n, grid, constrained, renumbered):
    rng = np.random.default_rng(seed)
    if grid:
        side = max(2, int(np.sqrt(n)))
        xy = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2) * 1.0
    else:
        xy = rng.uniform(-50, 50, (n, 2))
    segments = np.arange(len(xy) // 4 * 2).reshape(-1, 2) if constrained and len(xy) > 3 \
        else None
    t, tris = cdt_rows(xy, segments)
    count = t.vertices_count()
    renumber = np.concatenate([np.zeros(kernels.SUPER, np.int32),
                               rng.permutation(count - kernels.SUPER).astype(np.int32)]) \
        if renumbered else None
    want_tri, kept = kernels._drop_super_triangle(tris["vertices"], renumber)
    want_nb = kernels._kept_neighbours(tris["neighbors"], kept, cdt.NO_NEIGHBOR)
    rows = tris.view(np.uint32).reshape(-1, 6)
    given_renumber = np.zeros(0, np.int32) if renumber is None else renumber
    built = compiled_kernel("cdt_tables")
    for kernel in (cdt_tables, built) if built is not None else (cdt_tables,):
        got_tri, got_nb = kernel(rows, given_renumber, kernels.SUPER)
        assert got_tri.dtype == got_nb.dtype == np.int32
        np.testing.assert_array_equal(got_tri, want_tri)
        np.testing.assert_array_equal(got_nb, want_nb)


def test_a_triangulation_is_the_same_either_way(monkeypatch):
    xy = np.random.default_rng(2).uniform(0, 1000, (20000, 2)) + [1_688_000.0, 4_799_500.0]
    segments = np.arange(40).reshape(-1, 2)
    if compiled_kernel("cdt_tables") is None:
        pytest.skip("no compiled module in this environment: the numpy steps ran both times")
    with_kernel = kernels.triangulate_pslg(xy, segments)
    monkeypatch.setattr("toolbox.aot.compiled_kernel",
                        lambda name, folder=None: None)
    without = kernels.triangulate_pslg(xy, segments)
    for name in ("vertices", "triangles", "neighbors", "segments", "segment_parents"):
        np.testing.assert_array_equal(getattr(with_kernel, name), getattr(without, name))
