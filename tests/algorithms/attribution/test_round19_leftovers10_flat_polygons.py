"""A closed line of a polygon code whose vertices lie on one line (it goes out and doubles back)
is ``degenerate`` wherever it lies. The check was the convex hull's area against exactly 0:
rounding of the coordinates left 173 of 200 such lines near the origin and all 200 at Siena's
Gauss-Boaga coordinates accepted as polygons (27 and 0 called ``degenerate``). A real thin
polygon (1 mm across 100 m) is still a polygon at both places."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from toolbox.attribution.resolve import resolve_geometries

SIENA = (1688000.0, 4799500.0)


def _doubling_back(rng, offset, n=200):
    """Lines out along a sloping line and back: vertices o + t d (t = 0, t2, t1, 0), on one
    line by construction (up to the rounding of each coordinate)."""
    lines = []
    for _ in range(n):
        o, d = rng.uniform(-50, 50, 2), rng.normal(size=2)
        t = np.sort(rng.uniform(0, 100, 3))
        p = o + t[:, None] * d
        lines.append(shapely.LineString(np.array([p[0], p[2], p[1], p[0]]) + offset))
    return np.array(lines, dtype=object)


@pytest.mark.parametrize("offset", [(0.0, 0.0), SIENA])
def test_a_closed_line_doubling_back_is_degenerate_at_any_translation(offset):
    geoms = _doubling_back(np.random.default_rng(0), offset)
    kind, _, reason, detail = resolve_geometries(geoms, np.full(len(geoms), "polygon", object),
                                                 0.5)
    assert list(reason) == ["degenerate"] * len(geoms)
    assert set(detail) == {"polygon of zero area"} and set(kind) == {None}


@pytest.mark.parametrize("offset", [(0.0, 0.0), SIENA])
def test_a_thin_polygon_is_still_a_polygon(offset):
    ring = np.array([(0, 0), (100, 50), (100.0004472, 49.9991056), (0, 0)]) + offset  # 1 mm
    geoms = np.array([shapely.Polygon(ring), shapely.LineString(ring)], dtype=object)
    kind, out, reason, _ = resolve_geometries(geoms, np.full(2, "polygon", object), 0.5)
    assert list(reason) == [None, None] and list(kind) == ["polygon", "polygon"]
    assert shapely.area(out[0]) == pytest.approx(0.5 * 111.8034 * 0.001, rel=1e-3)
