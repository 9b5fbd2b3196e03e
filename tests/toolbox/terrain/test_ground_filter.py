"""Ground filter kernels: the opening is scipy's grey opening (checked against a brute-force
min-then-max), objects narrower than the window are flagged, a plane is never flagged."""

from __future__ import annotations

import numpy as np

from toolbox.terrain.ground import (
    GroundFilter,
    fill_harmonic,
    minimum_surface,
    object_cells,
    smrf,
)


def test_minimum_surface_is_the_lowest_point_per_cell():
    xyz = np.array([[0.2, 0.2, 5.0], [0.7, 0.9, 3.0], [1.5, 0.5, 9.0], [0.5, 1.5, 1.0]])
    s = minimum_surface(xyz, 1.0)
    # rows from the north edge (y = 2): row 0 holds y in (1, 2], row 1 y in (0, 1]
    assert s.z.shape == (2, 2)
    assert s.z[1, 0] == 3.0 and s.z[1, 1] == 9.0 and s.z[0, 0] == 1.0 and np.isnan(s.z[0, 1])


def test_plane_has_no_object_and_a_box_is_one():
    y, x = np.mgrid[0:60, 0:60].astype(float)
    plane = 100 + 0.1 * x - 0.05 * y
    flt = GroundFilter(cell=1.0, slope=0.15, max_window=8)
    assert not object_cells(plane, flt).any()
    box = plane.copy()
    box[20:30, 25:35] += 6.0  # 10 cells wide < 2 x 8: removed
    objects = object_cells(box, flt)
    assert objects[20:30, 25:35].all() and objects.sum() == 100


def test_fill_harmonic_keeps_known_cells_and_fills_a_plane():
    y, x = np.mgrid[0:40, 0:40].astype(float)
    plane = 50 + 0.2 * x + 0.1 * y
    holed = plane.copy()
    holed[10:20, 12:22] = np.nan
    filled = fill_harmonic(holed)
    assert np.array_equal(filled[~np.isnan(holed)], plane[~np.isnan(holed)])
    assert np.abs(filled - plane).max() < 1e-9  # a plane is harmonic: filled exactly


def test_fill_harmonic_falls_back_to_inpainting_for_huge_holes(monkeypatch):
    import toolbox.terrain.ground as ground

    y, x = np.mgrid[0:50, 0:50].astype(float)
    surface = 20 + np.sin(x / 7.0) * np.cos(y / 9.0)
    holed = surface.copy()
    holed[5:30, 10:40] = np.nan
    monkeypatch.setattr(ground, "DIRECT_SOLVE_LIMIT", 10)
    filled = fill_harmonic(holed)
    assert np.array_equal(filled, ground.fill_inpaint(holed))
    assert np.abs(filled - surface).max() < 1.0  # heights span 2: a fill, not a guess


def test_smrf_points_on_a_plane_are_all_ground():
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 50, (5000, 2))
    xyz = np.column_stack([xy, 10 + 0.3 * xy[:, 0]])
    assert smrf(xyz, GroundFilter(cell=1.0, slope=0.4)).ground.all()
