"""Round 17 (cdtspeed): CDT gets its points in Z-order also with breaklines (the segments'
vertices keep their index), and the result is the very arrays of a run with the points as given:
triangles, neighbours, crossing vertices, constrained pieces and their parents. Truth: the run
without the ordering (MEMORY_ORDER_MIN_POINTS out of reach), on inputs where another insertion
order would change the triangles (exactly cocircular points), with crossing segments, and with
a point exactly on a segment (the ordered run is redone as given)."""

from __future__ import annotations

import numpy as np

from toolbox.terrain.tin import kernels
from toolbox.terrain.tin.kernels import MEMORY_ORDER_MIN_POINTS, _memory_order, triangulate_pslg

FIELDS = ("vertices", "triangles", "neighbors", "segments", "segment_parents")
SMALL = 20_000  # MEMORY_ORDER_MIN_POINTS lowered to this, so the inputs stay small and fast


def _runs(monkeypatch, xy, seg, **options):
    """(ordered run, run as given, whether the ordered run was kept)."""
    kept = []
    run = kernels._cdt_run

    def spy(*args, **kwargs):
        result = run(*args, **kwargs)
        if len(args) > 5:
            kept.append(result is not None)
        return result

    monkeypatch.setattr(kernels, "_cdt_run", spy)
    monkeypatch.setattr(kernels, "MEMORY_ORDER_MIN_POINTS", SMALL)
    fast = triangulate_pslg(xy, seg, triangulator="cdt", **options)
    monkeypatch.setattr(kernels, "MEMORY_ORDER_MIN_POINTS", 10 ** 12)
    plain = triangulate_pslg(xy, seg, triangulator="cdt", **options)
    return fast, plain, kept


def _cocircular_with_breaklines(seed: int):
    # 1000 copies of six points exactly on one circle (as in test_round16_cdt) among random
    # points; 200 segments join points of different rings (long, crossing each other)
    rng = np.random.default_rng(seed)
    ring = np.array([[35, 120], [44, 117], [75, 100], [100, 75], [117, 44], [120, 35]]) / 64.0
    offsets = np.round(rng.uniform(0, 2e4, (1000, 2)) * 1024) / 1024
    xy = np.vstack([(ring[None] + offsets[:, None]).reshape(-1, 2),
                    rng.uniform(0, 2e4, (SMALL, 2))])
    ends = rng.choice(6000, 400, replace=False)
    seg = ends.reshape(-1, 2)
    assert len(np.unique(xy[:, 0])) == len(xy) and len(np.unique(xy[:, 1])) == len(xy)
    return xy, seg


def _codes(triangles: np.ndarray) -> np.ndarray:
    t = np.sort(triangles.astype(np.int64), axis=1)
    return np.sort((t[:, 0] * 2 ** 21 + t[:, 1]) * 2 ** 21 + t[:, 2])


def test_breaklines_in_z_order_give_the_same_arrays_with_cocircular_points_and_crossings(
        monkeypatch):
    xy, seg = _cocircular_with_breaklines(12)
    fast, plain, kept = _runs(monkeypatch, xy, seg)
    assert kept == [True]  # the ordered run was used
    assert plain.steiner_count > 1000  # crossings added vertices
    # the check has teeth: numbered the other way round (CDT then walks each segment from its
    # other end), the points get other triangles where they are cocircular
    other = triangulate_pslg(xy[::-1], len(xy) - 1 - seg, triangulator="cdt")
    assert not np.array_equal(_codes(len(xy) - 1 - other.triangles), _codes(plain.triangles))
    for name in FIELDS:
        assert np.array_equal(getattr(fast, name), getattr(plain, name)), name
    fast, plain, kept = _runs(monkeypatch, xy, seg, neighbors=False, parents=False)
    assert kept == [True]
    assert np.array_equal(fast.triangles, plain.triangles)
    assert np.array_equal(fast.vertices, plain.vertices)


def test_a_point_exactly_on_a_segment_redoes_the_run_as_given(monkeypatch):
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 1e3, (SMALL, 2))
    xy[0], xy[1] = [100.0, 200.0], [164.0, 200.5]
    xy[5000] = [132.0, 200.25]  # exactly halfway: on the segment 0-1
    seg = np.array([[0, 1], [2, 3]])
    for options in ({}, {"neighbors": False, "parents": False}):
        fast, plain, kept = _runs(monkeypatch, xy, seg, **options)
        assert kept == [False]  # point 5000 was moved and ends a constrained edge
        for name in FIELDS:
            assert np.array_equal(getattr(fast, name), getattr(plain, name)), name
        if options == {}:
            pieces = set(map(tuple, np.sort(plain.segments, axis=1).tolist()))
            assert {(0, 5000), (1, 5000)} <= pieces


def test_segment_vertices_sharing_a_coordinate_are_not_an_exact_order():
    # (round 18: the ordered run is then kept only if its triangulation is the unique one)
    rng = np.random.default_rng(4)
    xy = rng.uniform(0, 1e4, (MEMORY_ORDER_MIN_POINTS, 2))
    probe = np.array([5010, 5020, 5030, 5040])
    assert _memory_order(xy, probe)[1]
    xy[5030, 0] = xy[5010, 0]
    assert not _memory_order(xy, probe)[1]
