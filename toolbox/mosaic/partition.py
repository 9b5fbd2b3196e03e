"""Cut polygons: the Voronoi ("LPV", locus of nearest points) partition of the mosaic area and
the seamlines between cut polygons.

Each ground point goes to the ortho whose centre (nadir point or footprint centre) is nearest
*among the orthos that have valid data there*, so the cells are an exact partition of the union
of the footprints: ``cell_i = F_i − ∪_j (F_j ∩ H_ij)``, with ``F`` the footprints and ``H_ij`` the
half plane closer to centre ``j`` than to centre ``i``. The boundary between two cells lies on
the perpendicular bisector of their centres (inside the overlap) or on a footprint edge.
"""

from __future__ import annotations

import numpy as np


def half_plane_closer_to(p: tuple[float, float], q: tuple[float, float], bounds) -> object:
    """The part of the box ``bounds`` closer to ``q`` than to ``p`` (a shapely polygon): the box
    cut by the perpendicular bisector of ``p`` and ``q``."""
    import shapely

    p, q = np.asarray(p, float), np.asarray(q, float)
    xmin, ymin, xmax, ymax = bounds
    size = 4.0 * max(xmax - xmin, ymax - ymin, float(np.hypot(*(q - p))), 1.0)
    mid, d = (p + q) / 2.0, q - p
    norm = float(np.hypot(*d))
    if norm == 0:
        return shapely.Polygon()
    d /= norm
    n = np.array([-d[1], d[0]])  # along the bisector
    corners = [mid + n * size, mid + n * size + d * size, mid - n * size + d * size, mid - n * size]
    return shapely.Polygon(corners).intersection(shapely.box(*bounds))


def same_point(p, q) -> bool:
    """True when ground points ``p`` and ``q`` coincide to rounding (1e-9 of the coordinates'
    magnitude: 5 mm at 5,000,000). Not ``np.allclose``: its relative tolerance (1e-5) took
    centres 40 m apart in UTM northings (~5e6) for one point."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    scale = max(1.0, float(np.abs(p).max()), float(np.abs(q).max()))
    return float(np.hypot(*(p - q))) <= 1e-9 * scale


def voronoi_cells(footprints: list, centres: list[tuple[float, float]]) -> list:
    """Cut polygons, one per ortho (possibly empty), partitioning the union of ``footprints``.

    ``centres[i]`` is ortho i's nadir point or footprint centre. Two orthos with the same centre
    (:func:`same_point`) split their overlap in favour of the lower index (callers pass the
    orthos in file-name order: :func:`toolbox.mosaic.block.name_order`).
    """
    import shapely

    bounds = shapely.union_all(footprints).bounds
    cells = []
    for i, (fi, ci) in enumerate(zip(footprints, centres, strict=True)):
        taken = []
        for j, (fj, cj) in enumerate(zip(footprints, centres, strict=True)):
            if j == i or not fi.intersects(fj):
                continue
            if same_point(ci, cj):
                if j < i:
                    taken.append(fj)
                continue
            taken.append(fj.intersection(half_plane_closer_to(ci, cj, bounds)))
        cell = fi.difference(shapely.union_all(taken)) if taken else fi
        cells.append(_polygonal(cell))
    return exact_coverage(cells)


#: vertices closer than this (relative to the coordinates' magnitude: 4.8e-6 m at 4,800,000)
#: are one, gaps narrower are closed: the cells' shared edges, computed once per cell, differ
#: by ~1e-9 m there
COVERAGE_TOLERANCE = 1e-12


def exact_coverage(cells: list) -> list:
    """``cells`` (computed one by one: two neighbours' common boundary computed twice, the
    copies differing by rounding, ~1e-9 m at 4,800,000: hairline gaps and overlaps) made an
    exact partition: shared edges with identical vertices, no overlap, no gap narrower than
    :data:`COVERAGE_TOLERANCE` x the coordinates' magnitude (GEOS's coverage cleaner,
    ``shapely.coverage_clean``: shapely >= 2.2 with GEOS >= 3.14; else the cells as they are).
    A result that moves any cell's boundary by more than that tolerance (the cleaner merged a
    real part away) is not used either."""
    import shapely

    polys = [c for c in cells if not c.is_empty]
    if len(polys) < 2 or not hasattr(shapely, "coverage_clean"):
        return cells
    magnitude = max(1.0, float(np.abs(shapely.bounds(polys)).max()))
    tolerance = COVERAGE_TOLERANCE * magnitude
    try:
        clean = shapely.coverage_clean(cells, gap_width=tolerance, snapping_distance=tolerance)
    except shapely.errors.GEOSException:
        return cells
    for before, after in zip(cells, clean, strict=True):
        if before.is_empty != after.is_empty or (
                not before.is_empty and before.hausdorff_distance(after) > 2 * tolerance):
            return cells
    return [_polygonal(c) for c in clean]


def _polygonal(geom):
    """Keep only the polygonal parts of a GEOS result (drop slivers' lines and points)."""
    import shapely

    if geom.is_empty or geom.geom_type in ("Polygon", "MultiPolygon"):
        return geom
    parts = [g for g in getattr(geom, "geoms", []) if g.geom_type in ("Polygon", "MultiPolygon")]
    return shapely.union_all(parts) if parts else shapely.Polygon()


def merge_lines(lines: list):
    """One (Multi)LineString from line parts, joined end to end where they touch."""
    import shapely
    from shapely.ops import linemerge

    union = shapely.union_all(lines)
    return union if union.geom_type == "LineString" else linemerge(union)


def seamlines(cells: list) -> list[tuple[int, int, object]]:
    """``(i, j, line)`` for every pair of cut polygons sharing a boundary of non-zero length
    (``line`` a merged (Multi)LineString, i < j)."""
    out = []
    for i in range(len(cells)):
        for j in range(i + 1, len(cells)):
            a, b = cells[i], cells[j]
            if a.is_empty or b.is_empty or not a.buffer(1e-9).intersects(b):
                continue
            lines = shared_lines(a, b)
            if not lines:
                continue
            merged = merge_lines(lines)
            if merged.length > 0:
                out.append((i, j, merged))
    return out


SHARED_TOLERANCE = 1e-9  # relative to the coordinates' magnitude (4.8 mm at 4,800,000)


def shared_lines(a, b) -> list:
    """The line parts of ``a``'s boundary that ``b``'s boundary runs along (within
    :data:`SHARED_TOLERANCE` of the coordinates' magnitude, parts longer than 10 x that).

    Cut polygons computed one by one (:func:`voronoi_cells`) meet along edges that coincide
    only to rounding: an exact ``a.boundary ∩ b.boundary`` then finds points instead of the
    shared line, and the pair's seam is missed."""
    import shapely

    def lines_of(shared, shortest):
        return [g for g in getattr(shared, "geoms", [shared])
                if g.geom_type in ("LineString", "MultiLineString") and g.length > shortest]

    exact = lines_of(shapely.intersection(a.boundary, b.boundary), 0.0)
    x0, y0, x1, y1 = a.bounds
    tol = SHARED_TOLERANCE * max(1.0, abs(x0), abs(y0), abs(x1), abs(y1))
    near = lines_of(shapely.intersection(a.boundary, b.boundary.buffer(tol, quad_segs=2)),
                    10 * tol)
    # exact where the edges coincide exactly (the tolerant lines overshoot by tol at the ends)
    if sum(g.length for g in near) > sum(g.length for g in exact) + 20 * tol:
        return near
    return exact


def partition_errors(cells: list, area) -> tuple[float, float]:
    """``(gap_or_excess_area, max_pairwise_overlap_area)`` of ``cells`` against ``area``: both
    are 0 for an exact partition."""
    import shapely

    union = shapely.union_all([c for c in cells if not c.is_empty])
    mismatch = union.symmetric_difference(area).area
    overlap = 0.0
    for i in range(len(cells)):
        for j in range(i + 1, len(cells)):
            overlap = max(overlap, cells[i].intersection(cells[j]).area)
    return mismatch, overlap
