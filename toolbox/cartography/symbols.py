"""Map-sheet geometry of the code file's symbology (:mod:`toolbox.styles.symbology`, shared
with the QGIS styles): hatching lines clipped to an area, scarp ticks along a line."""

from __future__ import annotations

from toolbox.styles.symbology import (  # noqa: F401  (re-exported)
    DASHES,
    DEFAULT_WIDTH,
    LINETYPES,
    SCARP_TICK_MM,
    SYMBOLS,
    Symbol,
    parse_symbol,
)


def hatch_lines(polygon, angle_deg: float, spacing: float):
    """Parallel lines ``spacing`` apart (ground units) at ``angle_deg`` (from the x axis,
    counter-clockwise) clipped to ``polygon``: a (Multi)LineString, possibly empty."""
    import numpy as np
    import shapely

    if polygon.is_empty:
        return shapely.MultiLineString([])
    cx, cy = polygon.centroid.x, polygon.centroid.y
    xmin, ymin, xmax, ymax = polygon.bounds
    r = float(np.hypot(xmax - xmin, ymax - ymin)) / 2 + spacing
    a = np.radians(angle_deg)
    d = np.array([np.cos(a), np.sin(a)])  # along the lines
    n = np.array([-d[1], d[0]])  # across
    offsets = np.arange(-r, r + spacing / 2, spacing)
    starts = np.array([cx, cy]) + offsets[:, None] * n - r * d
    ends = np.array([cx, cy]) + offsets[:, None] * n + r * d
    lines = shapely.linestrings(np.stack([starts, ends], axis=1))
    return shapely.intersection(shapely.MultiLineString(list(lines)), polygon)


def scarp_ticks(line, spacing: float, length: float):
    """Ticks of a scarp: segments ``length`` long perpendicular to ``line``, on its left, every
    ``spacing`` along it (ground units), as an array (n, 2, 2)."""
    import numpy as np

    if line.length <= 0:
        return np.zeros((0, 2, 2))
    out = []
    for s in np.arange(spacing / 2, line.length, spacing):
        a = line.interpolate(max(s - spacing / 10, 0.0))
        b = line.interpolate(min(s + spacing / 10, line.length))
        t = np.array([b.x - a.x, b.y - a.y])
        norm = float(np.hypot(*t))
        if norm == 0:
            continue
        left = np.array([-t[1], t[0]]) / norm
        p = line.interpolate(s)
        base = np.array([p.x, p.y])
        out.append([base, base + length * left])
    return np.array(out).reshape(-1, 2, 2)
