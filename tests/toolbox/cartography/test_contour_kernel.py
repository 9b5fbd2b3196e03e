"""The one-pass marching-squares kernel against contourpy (the oracle, and the tracer it replaced):
per level the same lines, the same ends, the same closed rings, the same lengths and the
orientation (contourpy keeps higher ground on the left, the kernel on the right) on saddles,
flat areas, heights exactly on the levels and no-data holes (corner-masked squares)."""

from __future__ import annotations

import contourpy
import numpy as np
import pytest
import shapely
from scipy.ndimage import gaussian_filter

from toolbox.cartography.contour_kernel import grid_lines


def oracle_lines(z: np.ndarray, level: float) -> list[np.ndarray]:
    """contourpy's lines (serial, corner mask) in grid coordinates, higher ground on the right."""
    rows, cols = z.shape
    data = np.ma.masked_invalid(z) if np.isnan(z).any() else z
    gen = contourpy.contour_generator(np.arange(cols, dtype=float), np.arange(rows, dtype=float),
                                      data, name="serial", corner_mask=True)
    return [line[::-1] for line in gen.lines(level)]


def summary(lines: list[np.ndarray]) -> tuple[list, float]:
    """Ends (rounded) and closedness of every line, sorted, and the total length."""
    ends = sorted((tuple(np.round(line[0], 9)), tuple(np.round(line[-1], 9)),
                   bool(np.array_equal(line[0], line[-1]))) for line in lines)
    opened = [e for e in ends if not e[2]]  # a ring's start is arbitrary: compare its count
    length = float(sum(shapely.length(shapely.linestrings(line)) for line in lines))
    return opened + [sum(e[2] for e in ends)], length


def assert_like_contourpy(z: np.ndarray, levels: np.ndarray) -> int:
    points, offsets, level_of = grid_lines(z, levels)
    for k, level in enumerate(levels):
        ours = [points[offsets[i]:offsets[i + 1]] for i in np.flatnonzero(level_of == k)]
        ref = oracle_lines(z, level)
        assert len(ours) == len(ref), level
        (our_ends, our_len), (ref_ends, ref_len) = summary(ours), summary(ref)
        assert our_ends == ref_ends, level
        assert our_len == pytest.approx(ref_len, rel=1e-12, abs=1e-12), level
    return len(level_of)


def test_saddles_and_heights_on_the_levels():
    # small integers: many saddles, flat squares, and levels just below node heights
    rng = np.random.default_rng(1)
    z = rng.integers(0, 6, size=(23, 31)).astype(float)
    levels = np.arange(6.0) - 1024 * np.spacing(np.arange(6.0) + 1.0)
    assert assert_like_contourpy(z, levels) > 100
    saddle = np.array([[1.0, 0.0], [0.0, 1.0]])
    for level in (0.4, 0.6):  # middle (0.5) above, then below the level
        assert_like_contourpy(saddle, np.array([level]))


def test_levels_between_heights_and_flat_plateaus():
    rng = np.random.default_rng(2)
    z = gaussian_filter(rng.normal(size=(60, 80)), 4) * 100
    z[20:30, 10:40] = np.round(z[20:30, 10:40].mean())  # a plateau at a level
    levels = np.arange(np.floor(z.min()), np.ceil(z.max()), 1.0)
    assert assert_like_contourpy(z, levels) > 20


def test_nodata_holes_are_corner_masked():
    rng = np.random.default_rng(3)
    z = gaussian_filter(rng.normal(size=(50, 70)), 3) * 50
    z[rng.random(z.shape) < 0.08] = np.nan  # lone holes: squares traced as triangles
    z[10:14, 5:60] = np.nan  # a strip
    levels = np.linspace(np.nanmin(z), np.nanmax(z), 15)[1:-1]
    assert assert_like_contourpy(z, levels) > 50


def test_closed_rings_repeat_their_start():
    y, x = np.mgrid[0:40, 0:40]
    z = 100.0 - np.hypot(x - 19.5, y - 20.2)
    points, offsets, level_of = grid_lines(z, np.array([90.0, 95.0]))
    assert len(level_of) == 2
    for i in range(2):
        line = points[offsets[i]:offsets[i + 1]]
        assert np.array_equal(line[0], line[-1])
        # higher ground (the apex) on the right: clockwise in the (column, row) frame
        assert not shapely.is_ccw(shapely.linearrings(line))


def test_degenerate_grids():
    for z in (np.zeros((1, 5)), np.zeros((5, 1)), np.full((4, 4), np.nan)):
        points, offsets, level_of = grid_lines(z, np.array([0.5]))
        assert len(points) == 0 and len(level_of) == 0 and list(offsets) == [0]


def line_set(points: np.ndarray, offsets: np.ndarray, level_of: np.ndarray) -> set:
    """Every line as (level, its vertices rounded to 1e-9 cells), rings rotated to start at
    their smallest vertex (a ring's start is arbitrary), in the direction traced."""
    out = set()
    for i, k in enumerate(level_of.tolist()):
        line = np.round(points[offsets[i]:offsets[i + 1]], 9) + 0.0  # (no -0.0)
        if len(line) > 2 and np.array_equal(line[0], line[-1]):
            ring = line[:-1]
            s = min(range(len(ring)), key=lambda j: tuple(ring[j]))
            line = np.vstack([ring[s:], ring[:s], ring[s:s + 1]])
        out.add((k, tuple(map(tuple, line.tolist()))))
    return out


@pytest.mark.parametrize("case", ["saddles", "plateau", "nodata"])
def test_contourpy_tracer_gives_the_kernels_lines(case):
    """The tracer of small grids (contourpy, no numba in the process) and the kernel give the
    same lines, vertex for vertex (to 1e-9 cells: the two interpolate in different
    arithmetic order) and in the same direction (higher ground on the right)."""
    from toolbox.cartography.contours import contourpy_lines

    rng = np.random.default_rng(11)
    if case == "saddles":
        z = rng.integers(0, 6, size=(23, 31)).astype(float)
        levels = np.arange(6.0) - 1024 * np.spacing(np.arange(6.0) + 1.0)
    else:
        z = gaussian_filter(rng.normal(size=(60, 80)), 3) * 100
        if case == "plateau":
            z[20:30, 10:40] = np.round(z[20:30, 10:40].mean())
        else:
            z[rng.random(z.shape) < 0.08] = np.nan
            z[10:14, 5:60] = np.nan
        levels = np.arange(np.floor(np.nanmin(z)) - 2, np.ceil(np.nanmax(z)) + 2, 1.0)
    kernel = grid_lines(z, levels)
    ours = contourpy_lines(z, levels)
    assert len(kernel[2]) > 20
    assert line_set(*ours) == line_set(*kernel)
    assert len(ours[2]) == len(kernel[2])
    for z in (np.zeros((1, 5)), np.full((4, 4), np.nan), np.zeros((3, 3))):
        points, offsets, level_of = contourpy_lines(z, np.array([0.5]))
        assert len(points) == 0 and len(level_of) == 0 and list(offsets) == [0]
