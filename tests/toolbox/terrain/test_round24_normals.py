"""Round 24: the TIN's plane normals and areas, computed component by component
(topology.corner_normals, _areas), are numpy's ``np.cross`` and ``np.linalg.norm`` bit for bit,
on Siena-sized coordinates, tiny and huge ones, degenerate triangles, NaN and infinities."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from toolbox.terrain.tin.topology import _areas, corner_normals, triangle_measures

FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                   st.floats(1_688_000.0, 1_698_000.0), st.floats(-1e-300, 1e-300))


@settings(max_examples=200, deadline=None)
@given(corners=arrays(np.float64, st.tuples(st.integers(0, 40), st.just(3), st.just(3)),
                      elements=FLOATS))
def test_normals_and_areas_are_numpys_bits(corners):
    p1 = corners[:, 0]
    with np.errstate(all="ignore"):
        want = np.cross(corners[:, 1] - p1, corners[:, 2] - p1)
        got = corner_normals(corners)
        flat, space = _areas(got)
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(flat, np.abs(want[:, 2]) / 2.0)
        np.testing.assert_array_equal(space, np.linalg.norm(want, axis=1) / 2.0)


def test_a_tilted_triangle_has_its_analytic_areas():
    xyz = np.array([[1_688_000.0, 4_799_500.0, 100.0], [1_688_004.0, 4_799_500.0, 103.0],
                    [1_688_000.0, 4_799_502.0, 100.0]])
    m = triangle_measures(xyz, np.array([[0, 1, 2]]))
    assert m.area_2d[0] == 4.0  # 4 x 2 / 2
    assert m.area_3d[0] == 5.0  # 5 (the slanted side) x 2 / 2


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(3, 200),
       scale=st.sampled_from([1e-6, 1.0, 1e3, 1e8]))
def test_the_compiled_areas_are_the_numpy_bits(seed, n, scale):
    """edge_kernel.triangle_areas (JIT and, where built, compiled) against the numpy steps."""
    from toolbox.aot import compiled_kernel
    from toolbox.terrain.tin import edge_kernel, topology

    rng = np.random.default_rng(seed)
    xyz = np.c_[rng.uniform(0, 100, (n, 2)) * scale + [1_688_000.0, 4_799_500.0],
                rng.normal(300, 5, n)]
    triangles = rng.integers(0, n, (2 * n, 3)).astype(np.int32)
    want = topology._areas(topology.plane_normals(xyz, triangles))
    built = compiled_kernel("triangle_areas")
    kernels = [edge_kernel.triangle_areas] + ([built] if built is not None else [])
    for kernel in kernels:
        got = kernel(xyz, triangles)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
    got = topology.triangle_areas(xyz, triangles)  # the dispatch
    np.testing.assert_array_equal(got[1], want[1])
