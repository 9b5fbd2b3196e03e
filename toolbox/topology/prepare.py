"""Input linework to clean 2D LineStrings: explode parts, use polygon rings, refuse the unusable.

Area topology is planimetric: heights are dropped here (an area's height comes from its label
point, the thesis' spot height, S002 §2.2.2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from toolbox.topology.issues import ERROR, Issue

_POINTS = (0, 4)  # Point, MultiPoint
_LINES = (1, 2)  # LineString, LinearRing
_MULTILINE = 5
_POLYGONS = (3, 6)
_COLLECTION = 7
_TYPE_NAMES = {0: "Point", 4: "MultiPoint", 7: "GeometryCollection"}


@dataclass
class PreparedLines:
    """Usable lines and where they came from.

    Attributes
    ----------
    lines : (M,) object array of 2D LineStrings, at least two distinct vertices each, no repeated
        consecutive vertices.
    source : (M,) int array
        Input row (0-based) of each line.
    issues : list of Issue
        ``invalid_geometry`` records (skipped rows or parts).
    counts : dict
        ``features``, ``lines``, ``invalid``, ``parts_exploded`` (extra lines from multi-part
        features), ``polygon_rings`` (lines taken from polygon boundaries).
    """

    lines: np.ndarray
    source: np.ndarray
    issues: list[Issue] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)


def _where(geom) -> shapely.Geometry:
    """A point locating a (possibly broken) geometry for the errors layer, or None."""
    if geom is None or shapely.is_empty(geom):
        return None
    coords = shapely.get_coordinates(geom)
    coords = coords[np.isfinite(coords).all(axis=1)]
    return shapely.Point(coords[0]) if len(coords) else None


def prepare_lines(geometries: np.ndarray) -> PreparedLines:
    """Turn input geometries into clean 2D lines.

    Parameters
    ----------
    geometries : (N,) array of shapely geometries or None
        LineString/LinearRing are used as they are; MultiLineString and GeometryCollection are
        split into parts; Polygon/MultiPolygon contribute their rings. Points, empty or null
        geometries, lines with NaN/inf coordinates and lines with fewer than two distinct
        vertices are skipped and reported as ``invalid_geometry``.

    Returns
    -------
    PreparedLines
    """
    geoms = np.asarray(geometries, dtype=object)
    n = len(geoms)
    issues: list[Issue] = []
    counts = {"features": n, "lines": 0, "invalid": 0, "parts_exploded": 0, "polygon_rings": 0}
    rows = np.arange(n)
    null = np.array([g is None for g in geoms], dtype=bool)
    empty = ~null & shapely.is_empty(np.where(null, shapely.Point(), geoms))
    for row in np.flatnonzero(null | empty):
        issues.append(Issue("invalid_geometry", ERROR, None,
                            "null geometry" if null[row] else "empty geometry", (int(row),)))
    keep = ~(null | empty)
    geoms, rows = geoms[keep], rows[keep]
    # collections and multi-parts -> parts (one level per round; collections may nest)
    for _ in range(4):
        types = shapely.get_type_id(geoms)
        multi = (types == _MULTILINE) | (types == _COLLECTION) | (types == 6)
        if not multi.any():
            break
        parts, index = shapely.get_parts(geoms[multi], return_index=True)
        counts["parts_exploded"] += int(len(parts) - np.count_nonzero(multi))
        geoms = np.concatenate([geoms[~multi], parts])
        rows = np.concatenate([rows[~multi], rows[multi][index]])
        order = np.argsort(rows, kind="stable")
        geoms, rows = geoms[order], rows[order]
    types = shapely.get_type_id(geoms)
    polygon = types == 3
    if polygon.any():
        rings, index = shapely.get_rings(geoms[polygon], return_index=True)
        counts["polygon_rings"] += len(rings)
        geoms = np.concatenate([geoms[~polygon], rings])
        rows = np.concatenate([rows[~polygon], rows[polygon][index]])
        order = np.argsort(rows, kind="stable")
        geoms, rows = geoms[order], rows[order]
        types = shapely.get_type_id(geoms)
    bad_type = ~np.isin(types, _LINES)
    for geom, row, type_id in zip(geoms[bad_type], rows[bad_type], types[bad_type], strict=True):
        name = _TYPE_NAMES.get(int(type_id), f"geometry type {int(type_id)}")
        issues.append(Issue("invalid_geometry", ERROR, _where(geom),
                            f"{name} in a line layer", (int(row),)))
    geoms, rows = geoms[~bad_type], rows[~bad_type]
    coords, index = shapely.get_coordinates(geoms, return_index=True)
    finite = np.ones(len(geoms), dtype=bool)
    bad_coord = ~np.isfinite(coords).all(axis=1)
    finite[np.unique(index[bad_coord])] = False
    for geom, row in zip(geoms[~finite], rows[~finite], strict=True):
        issues.append(Issue("invalid_geometry", ERROR, _where(geom),
                            "NaN or infinite coordinates", (int(row),)))
    geoms, rows = geoms[finite], rows[finite]
    geoms = shapely.remove_repeated_points(shapely.force_2d(geoms), 0.0)
    if len(geoms):
        # LinearRings become LineStrings (one kind of line downstream)
        coords, index = shapely.get_coordinates(geoms, return_index=True)
        nverts = np.bincount(index, minlength=len(geoms))
        short = nverts < 2
        degenerate = short.copy()
        degenerate[~short] = shapely.length(geoms[~short]) == 0
        for geom, row in zip(geoms[degenerate], rows[degenerate], strict=True):
            issues.append(Issue("invalid_geometry", ERROR, _where(geom),
                                "fewer than two distinct vertices", (int(row),)))
        ok = ~degenerate
        keep_coords = ok[index]
        new_index = np.cumsum(ok) - 1
        geoms = shapely.linestrings(coords[keep_coords], indices=new_index[index[keep_coords]])
        rows = rows[ok]
    geoms = np.asarray(geoms, dtype=object).reshape(-1)
    counts["lines"] = len(geoms)
    counts["invalid"] = len(issues)
    return PreparedLines(geoms, rows.astype(np.int64), issues, counts)
