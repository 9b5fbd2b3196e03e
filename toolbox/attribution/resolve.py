"""Geometry checks of the coding step, for all entities at once (arrays in, arrays out).

:func:`resolve_geometries` decides, for each entity whose code is known, whether its geometry
fits the code's type (and closes the outlines of polygon codes); :func:`z_statistics` gives the
Z minimum, maximum and mean of each geometry. Both work on the coordinates of every geometry in
one array (``shapely.get_coordinates(..., return_index=True)``), grouped by geometry, instead of
one NumPy call per entity.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import shapely


def _starts(index: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(first row, number of rows) of each of ``n`` geometries in a coordinate array whose
    geometry ``index`` is non-decreasing (as ``shapely.get_coordinates`` returns it)."""
    counts = np.bincount(index, minlength=n)
    return np.cumsum(counts) - counts, counts


def distinct_xy(xy: np.ndarray, index: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (x, y) vertices of each of ``n`` geometries (coordinates rounded to 1e-9 CRS
    units; a vertex with a NaN coordinate counts as distinct), and whether each geometry's last
    vertex occurs only once in it (False for a geometry without vertices).

    ``xy``: (N, 2) coordinates, ``index``: (N,) non-decreasing geometry of each row.
    """
    r = np.round(xy[:, :2], 9)
    order = np.lexsort((r[:, 1], r[:, 0], index))
    s, si = r[order], index[order]
    new = np.ones(len(order), bool)
    new[1:] = (si[1:] != si[:-1]) | (s[1:, 0] != s[:-1, 0]) | (s[1:, 1] != s[:-1, 1])
    distinct = np.bincount(si[new], minlength=n)
    group = np.cumsum(new) - 1  # run of equal vertices of each sorted row
    size = np.bincount(group)
    rank = np.empty(len(order), np.intp)
    rank[order] = np.arange(len(order))
    starts, counts = _starts(index, n)
    last_unique = np.zeros(n, bool)
    has = counts > 0
    last_unique[has] = size[group[rank[starts[has] + counts[has] - 1]]] == 1
    return distinct, last_unique


def _polygons_from_lines(geoms: np.ndarray, drop_last: np.ndarray, close: np.ndarray,
                         with_z: bool) -> np.ndarray:
    """Polygons whose shell is each line's vertices (Z kept when ``with_z``): the last vertex
    left out where ``drop_last``, the first appended where ``close`` (as ``shapely.Polygon``
    builds them: a ring whose last vertex differs from its first in any ordinate is closed)."""
    coords, index = shapely.get_coordinates(geoms, include_z=with_z, return_index=True)
    starts, counts = _starts(index, len(geoms))
    keep = np.ones(len(coords), bool)
    keep[(starts + counts - 1)[drop_last]] = False
    first = starts[close]
    index = np.concatenate([index[keep], np.flatnonzero(close)])
    coords = np.concatenate([coords[keep], coords[first]])
    order = np.argsort(index, kind="stable")  # appended vertices last in their ring
    rings = shapely.linearrings(coords[order], indices=index[order])
    return shapely.polygons(rings)


FLAT_TOLERANCE = 1e-12
"""A polygon whose convex hull's area is at most ``FLAT_TOLERANCE x d x (d + m)`` (``d`` its
bounding box's diagonal, ``m`` its largest absolute coordinate) has all its vertices on one line
but for rounding: a width below ``1e-12`` of its extent plus its distance from the origin (5 um
at Siena's Gauss-Boaga coordinates, where a coordinate's rounding step is 1 nm). Exactly zero
area told such lines apart by where they lay: near the origin some, far from it none."""


def _collinear(shapes: np.ndarray) -> np.ndarray:
    """Whether each polygon's vertices lie on one line (:data:`FLAT_TOLERANCE`)."""
    area = shapely.area(shapely.convex_hull(shapes))
    box = shapely.bounds(shapes)
    diagonal = np.hypot(box[:, 2] - box[:, 0], box[:, 3] - box[:, 1])
    reach = np.abs(box).max(axis=1) if len(box) else np.zeros(0)
    return area <= FLAT_TOLERANCE * diagonal * (diagonal + reach)


def resolve_geometries(geoms: np.ndarray, declared: np.ndarray, closure: float
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(kind, geometry, reason, detail) of each entity: reason None when usable.

    ``geoms``: object array of geometries (None allowed); ``declared``: the code's type of each
    ("point", "line", "polygon" or None: taken from the geometry). A line of a polygon code is
    closed when its ends miss by at most ``closure`` (planimetric distance, CRS units) and
    becomes a Polygon (detail ``closed: ends ... apart``).
    """
    geoms = np.asarray(geoms, dtype=object)
    n = len(geoms)
    kind = np.full(n, None, dtype=object)
    out = np.full(n, None, dtype=object)
    reason = np.full(n, None, dtype=object)
    detail = np.full(n, "", dtype=object)
    missing = shapely.is_missing(geoms)
    missing[~missing] = shapely.is_empty(geoms[~missing])
    reason[missing], detail[missing] = "no_vertices", "no coordinates"
    gtype = shapely.get_type_id(geoms)
    nv = shapely.get_num_coordinates(geoms)
    is_point, is_polygon = gtype == 0, gtype == 3
    want = np.asarray(declared, dtype=object).copy()
    free = np.array([w is None for w in want], dtype=bool)
    want[free] = np.where(is_point[free], "point", np.where(is_polygon[free], "polygon", "line"))
    live = ~missing

    def fail(mask: np.ndarray, why: str, texts: Any) -> None:
        reason[mask] = why
        detail[mask] = texts if isinstance(texts, str) else list(texts)

    def accept(mask: np.ndarray, what: str, shapes: np.ndarray, notes: Any = "") -> None:
        kind[mask], out[mask] = what, shapes
        detail[mask] = notes if isinstance(notes, str) else list(notes)

    # point codes
    pts = live & (want == "point")
    bad = pts & ~is_point
    fail(bad, "type_mismatch", ["the code is a point type, the entity a " + (
        "polygon" if p else f"line with {k} vertices") for p, k in
        zip(is_polygon[bad], nv[bad], strict=True)])
    accept(pts & is_point, "point", geoms[pts & is_point])
    # line codes
    lns = live & (want == "line")
    fail(lns & is_polygon, "type_mismatch", "the code is a line type, the entity a polygon")
    lns &= ~is_polygon
    coords, index = shapely.get_coordinates(geoms[lns], return_index=True)
    nd, _ = distinct_xy(coords, index, int(lns.sum()))
    deg = np.zeros(n, bool)
    deg[lns] = is_point[lns] | (nd < 2)
    fail(deg, "degenerate", ["line with " + ("one vertex" if k == 1 else "zero length")
                             for k in nv[deg]])
    accept(lns & ~deg, "line", geoms[lns & ~deg])
    # polygon codes: the outline (a polygon's exterior ring, else every vertex)
    pol = np.flatnonzero(live & (want == "polygon"))
    src = geoms[pol].copy()
    src[is_polygon[pol]] = shapely.get_exterior_ring(src[is_polygon[pol]])
    coords, index = shapely.get_coordinates(src, return_index=True)
    nd, last_unique = distinct_xy(coords, index, len(pol))
    starts, counts = _starts(index, len(pol))
    bad = is_point[pol] | (nd < 3)
    fail(pol[bad], "degenerate", [f"polygon with {k} distinct vertices" for k in nd[bad]])
    pol, nd, last_unique = pol[~bad], nd[~bad], last_unique[~bad]
    first, last = coords[starts[~bad]], coords[(starts + counts - 1)[~bad]]
    gap = np.hypot(last[:, 0] - first[:, 0], last[:, 1] - first[:, 1])
    line = ~is_polygon[pol]
    open_ = line & (gap > closure)
    fail(pol[open_], "unclosed_polygon", [f"ends {g:.3f} apart (closure tolerance {closure:g})"
                                          for g in gap[open_]])
    shapes = geoms[pol].copy()
    notes = np.full(len(pol), "", dtype=object)
    close = line & ~open_ & (gap > 0)
    notes[close] = [f"closed: ends {g:.3f} apart" for g in gap[close]]
    hz = shapely.has_z(shapes)
    for with_z in (False, True):  # the last vertex was meant to be the first: snapped onto it
        sel = line & ~open_ & (hz == with_z)  # (the first appended if too few would be left)
        if sel.any():
            drop = close[sel] & (nd[sel] - last_unique[sel] >= 3)
            shapes[sel] = _polygons_from_lines(shapes[sel], drop, close[sel], with_z)
    ok = ~open_
    flat = np.zeros(len(pol), bool)
    flat[ok] = _collinear(shapes[ok])  # all vertices on one line
    fail(pol[flat], "degenerate", "polygon of zero area")
    ok &= ~flat
    invalid = np.zeros(len(pol), bool)
    invalid[ok] = ~shapely.is_valid(shapes[ok])
    fail(pol[invalid], "invalid_polygon", shapely.is_valid_reason(shapes[invalid]))
    ok &= ~invalid
    accept(pol[ok], "polygon", shapes[ok], notes[ok])
    return kind, out, reason, detail


def z_statistics(geoms: Any) -> dict[str, np.ndarray]:
    """z_min, z_max, z_mean of each geometry's vertices, NaN vertices left out (NaN for a 2D
    geometry, None, or one without a finite Z)."""
    geoms = np.asarray(geoms, dtype=object)
    out = {k: np.full(len(geoms), np.nan) for k in ("z_min", "z_max", "z_mean")}
    sel = np.flatnonzero(shapely.has_z(geoms))
    coords, index = shapely.get_coordinates(geoms[sel], include_z=True, return_index=True)
    starts, counts = _starts(index, len(sel))
    z = coords[:, 2]
    known = ~np.isnan(z)
    at, sel = starts[counts > 0], sel[counts > 0]  # segments of reduceat: every vertex once
    if len(sel):
        finite = np.logical_or.reduceat(np.isfinite(z), at)
        # the sums as np.nanmean adds them (0.0 + a pairwise sum of the vertices: a 0.0 put
        # before each segment, else reduceat would start from its first vertex, 1 ulp apart)
        padded = np.insert(np.where(known, z, 0.0), at, 0.0)
        with np.errstate(invalid="ignore"):  # 0 / 0 where no Z is known: not kept
            stats = (np.fmin.reduceat(z, at), np.fmax.reduceat(z, at),
                     np.add.reduceat(padded, at + np.arange(len(at)))
                     / np.add.reduceat(known.astype(np.intp), at))
        for key, values in zip(("z_min", "z_max", "z_mean"), stats, strict=True):
            out[key][sel[finite]] = values[finite]
    return out
