"""Set operations between two area layers (thesis S002 §2.4, Fig. 26-28: intersection, union,
subtraction, used to derive thematic maps), with GEOS doing the geometry.

Every output piece remembers the feature of each layer it comes from (index or -1), so both sides'
attributes can be kept. Overlays run with a ``grid_size`` (GEOS OverlayNG snap rounding), which
makes them robust and free of float-noise slivers.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import shapely

from toolbox.topology.issues import ERROR, FIXED, Issue

OPERATIONS = ("intersection", "union", "difference", "symmetric_difference")
_POINT_RE = re.compile(r"\[\s*([-+0-9.eE]+)\s+([-+0-9.eE]+)")


@dataclass
class OverlayResult:
    """Pieces (single Polygons) and, for each, the index of its A and B feature (-1: none)."""

    geoms: np.ndarray
    a_index: np.ndarray
    b_index: np.ndarray
    counts: dict[str, int] = field(default_factory=dict)


def polygonal_parts(geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Single Polygons inside each geometry (collections and multi-polygons opened), with the
    index of the geometry they come from; lines and points are dropped."""
    geoms = np.asarray(geoms, dtype=object)
    index = np.arange(len(geoms))
    for _ in range(4):
        types = shapely.get_type_id(geoms)
        multi = (types == 6) | (types == 7)
        if not multi.any():
            break
        parts, where = shapely.get_parts(geoms[multi], return_index=True)
        geoms = np.concatenate([geoms[~multi], parts])
        index = np.concatenate([index[~multi], index[multi][where]])
    keep = (shapely.get_type_id(geoms) == 3) & ~shapely.is_empty(geoms)
    geoms, index = geoms[keep], index[keep]
    order = np.argsort(index, kind="stable")
    return geoms[order], index[order]


def repaired_parts(geom) -> np.ndarray:
    """The polygonal parts of an invalid area ``geom`` repaired with GEOS ``make_valid``
    (structure method; collapsed pieces dropped)."""
    fixed = shapely.make_valid(geom, method="structure", keep_collapsed=False)
    return polygonal_parts(np.array([fixed], dtype=object))[0]


def clean_polygons(geoms: np.ndarray, layer: str) -> tuple[np.ndarray, list[Issue], dict]:
    """Repair input areas for overlay.

    Null, empty and non-polygonal features become None (``invalid_geometry``). Invalid polygons
    (self-intersections, bow-ties...) are repaired with GEOS ``make_valid`` (structure method);
    the repair is reported as ``self_intersection`` ``fixed`` at the point GEOS names, or as
    ``error`` when nothing polygonal is left (the feature is then skipped).

    Returns the cleaned geometries (Polygon/MultiPolygon or None), issues and counts.
    """
    geoms = np.asarray(geoms, dtype=object).copy()
    issues: list[Issue] = []
    counts = {"features": len(geoms), "skipped": 0, "repaired": 0}
    for i, g in enumerate(geoms):
        if g is None or shapely.is_empty(g):
            issues.append(Issue("invalid_geometry", ERROR, None, f"{layer}: null or empty "
                                "geometry", (i,)))
            geoms[i] = None
            continue
        g = shapely.force_2d(g)
        if shapely.get_type_id(g) not in (3, 6, 7):
            issues.append(Issue("invalid_geometry", ERROR, shapely.point_on_surface(g),
                                f"{layer}: {g.geom_type} is not an area", (i,)))
            geoms[i] = None
            continue
        if not shapely.is_valid(g):
            reason = shapely.is_valid_reason(g)
            match = _POINT_RE.search(reason)
            where = (shapely.Point(float(match.group(1)), float(match.group(2))) if match
                     else shapely.Point(shapely.get_coordinates(g)[0]))
            parts = repaired_parts(g)
            if len(parts) == 0:
                issues.append(Issue("self_intersection", ERROR, where, f"{layer}: {reason}; "
                                    "could not be repaired, feature skipped", (i,)))
                geoms[i] = None
                continue
            issues.append(Issue("self_intersection", FIXED, where, f"{layer}: {reason}; "
                                "repaired", (i,)))
            counts["repaired"] += 1
            g = shapely.multipolygons(parts) if len(parts) > 1 else parts[0]
        parts, _ = polygonal_parts(np.array([g], dtype=object))
        if len(parts) == 0:
            issues.append(Issue("invalid_geometry", ERROR, shapely.point_on_surface(g),
                                f"{layer}: no area in this geometry", (i,)))
            geoms[i] = None
            continue
        if shapely.get_type_id(g) == 7:  # a collection: its areas (united: they may overlap)
            others = [p for p in shapely.get_parts(g) if shapely.get_type_id(p) not in (3, 6)]
            if others:
                issues.append(Issue("invalid_geometry", FIXED, shapely.point_on_surface(others[0]),
                                    f"{layer}: {len(others)} point or line part(s) of a "
                                    "GeometryCollection dropped, its areas kept", (i,)))
            g = shapely.union_all(parts)
        geoms[i] = g
    counts["skipped"] = int(sum(1 for g in geoms if g is None))
    return geoms, issues, counts


def _difference(a: np.ndarray, b: np.ndarray, pairs_a: np.ndarray, pairs_b: np.ndarray,
                grid: float) -> np.ndarray:
    """a[i] minus the union of the b's it intersects (a[i] itself where none)."""
    out = shapely.set_precision(a, grid)
    order = np.argsort(pairs_a, kind="stable")
    pa, pb = pairs_a[order], pairs_b[order]
    bounds = np.searchsorted(pa, np.arange(len(a) + 1))
    for i in np.unique(pa):
        cutter = shapely.union_all(b[pb[bounds[i]:bounds[i + 1]]], grid_size=grid)
        out[i] = shapely.difference(a[i], cutter, grid_size=grid)
    return out


def overlay_polygons(a: np.ndarray, b: np.ndarray, operation: str, grid: float
                     ) -> OverlayResult:
    """Intersection, union, difference (A - B) or symmetric difference of two area sets.

    Parameters
    ----------
    a, b : arrays of Polygon/MultiPolygon or None (None features take no part).
    operation : one of :data:`OPERATIONS`.
    grid : coordinate grid of the result (GEOS OverlayNG ``grid_size``), CRS units.

    Returns
    -------
    OverlayResult
        ``intersection``: pieces of A ∩ B with both indices; ``difference``: A - B with
        ``b_index`` -1; ``symmetric_difference``: A - B and B - A; ``union``: all three kinds.
        Pieces are single polygons, in the order intersection, A - B, B - A.
    """
    if operation not in OPERATIONS:
        raise ValueError(f"operation must be one of {', '.join(OPERATIONS)}; got {operation!r}")
    a = np.asarray(a, dtype=object)
    b = np.asarray(b, dtype=object)
    a_ok, b_ok = np.flatnonzero([g is not None for g in a]), np.flatnonzero(
        [g is not None for g in b])
    A, B = a[a_ok], b[b_ok]  # noqa: N806 - the two sets, as in the set algebra
    if len(A) and len(B):
        ia, ib = shapely.STRtree(B).query(A, predicate="intersects")
    else:
        ia = ib = np.zeros(0, dtype=np.int64)
    pieces, a_idx, b_idx = [], [], []

    def add(geoms: np.ndarray, ai: np.ndarray, bi: np.ndarray) -> None:
        parts, where = polygonal_parts(geoms)
        keep = shapely.area(parts) > grid * grid
        pieces.append(parts[keep])
        a_idx.append(ai[where][keep])
        b_idx.append(bi[where][keep])

    if operation in ("intersection", "union"):
        add(shapely.intersection(A[ia], B[ib], grid_size=grid), a_ok[ia], b_ok[ib])
    if operation in ("difference", "symmetric_difference", "union"):
        add(_difference(A, B, ia, ib, grid), a_ok, np.full(len(A), -1))
    if operation in ("symmetric_difference", "union"):
        add(_difference(B, A, ib, ia, grid), np.full(len(B), -1), b_ok)
    geoms = np.concatenate(pieces) if pieces else np.zeros(0, dtype=object)
    a_index = np.concatenate(a_idx).astype(np.int64) if a_idx else np.zeros(0, np.int64)
    b_index = np.concatenate(b_idx).astype(np.int64) if b_idx else np.zeros(0, np.int64)
    geoms = shapely.orient_polygons(shapely.normalize(geoms), exterior_cw=False)
    counts = {"pieces": len(geoms), "pairs_intersecting": len(ia),
              "a_only": int(np.sum(b_index < 0)), "b_only": int(np.sum(a_index < 0)),
              "both": int(np.sum((a_index >= 0) & (b_index >= 0)))}
    return OverlayResult(geoms, a_index, b_index, counts)
