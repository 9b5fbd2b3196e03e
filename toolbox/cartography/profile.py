"""Elevation profiles and cross sections ("sezioni e profili") along polylines.

Kernels are arrays in, arrays out: a polyline is ``(n, 2)`` x, y in map units; chainage is the
distance along it from its first vertex. A DEM is sampled bilinearly between cell centres
(cell values at centres, as everywhere in the toolbox); a TIN by the plane of its triangles.
"""

from __future__ import annotations

import numpy as np


def chainage_of_vertices(xy: np.ndarray) -> np.ndarray:
    """Cumulative distance along a polyline at each vertex (0 at the first)."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def points_at(xy: np.ndarray, chainage: np.ndarray) -> np.ndarray:
    """Points at the given chainages along a polyline (linear along each segment)."""
    s = chainage_of_vertices(xy)
    return np.column_stack([np.interp(chainage, s, xy[:, 0]), np.interp(chainage, s, xy[:, 1])])


def sample_stations(xy: np.ndarray, step: float) -> np.ndarray:
    """Chainages every ``step`` from 0, plus the polyline's end (the thesis' constant step)."""
    length = chainage_of_vertices(xy)[-1]
    stations = np.arange(0.0, length, step)
    return np.append(stations, length) if length - stations[-1] > 1e-9 * max(length, 1) \
        else stations


def contour_crossings(xy: np.ndarray, contour_geoms, levels: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crossings of a polyline with contour lines: (chainage, points (k, 2), heights), sorted by
    chainage. As the thesis' sections from contours: the polyline's ends, which have no height,
    are not included; the first and last crossings become the profile's ends."""
    import shapely

    line = shapely.linestrings(xy)
    tree = shapely.STRtree(contour_geoms)
    hits = tree.query(line, predicate="intersects")
    ch, pts, hs = [], [], []
    for i in hits:
        inter = shapely.intersection(line, shapely.force_2d(contour_geoms[i]))
        for p in shapely.get_parts(inter):
            for c in shapely.get_coordinates(p):  # points (or a shared stretch's vertices)
                ch.append(float(shapely.line_locate_point(line, shapely.points(c))))
                pts.append(c)
                hs.append(float(levels[i]))
    if not ch:
        return np.empty(0), np.empty((0, 2)), np.empty(0)
    order = np.argsort(ch, kind="stable")
    return np.asarray(ch)[order], np.asarray(pts)[order], np.asarray(hs)[order]


def section_axes(axis_xy: np.ndarray, spacing: float, half_width: float
                 ) -> list[tuple[float, np.ndarray]]:
    """Cross-section lines perpendicular to an axis: at chainages 0, spacing, 2·spacing, ...
    (and the axis' end), each ``2·half_width`` long, running from left to right of the axis
    direction. Returns ``(chainage, (2, 2) end points)`` per section."""
    s = chainage_of_vertices(axis_xy)
    stations = sample_stations(axis_xy, spacing)
    out = []
    for ch in stations:
        seg = min(int(np.searchsorted(s, ch, side="right")) - 1, len(axis_xy) - 2)
        d = axis_xy[seg + 1] - axis_xy[seg]
        d = d / np.hypot(*d)
        right = np.array([d[1], -d[0]])
        centre = points_at(axis_xy, np.array([ch]))[0]
        out.append((float(ch), np.vstack([centre - half_width * right,
                                          centre + half_width * right])))
    return out
