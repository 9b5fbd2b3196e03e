"""Build a TIN model from mass points, breaklines and a boundary (the kernel of tin:delaunay).

Arrays and shapely geometries in, a :class:`TinModel` out; no files. Steps:

1. breakline vertices and mass points are pooled (breakline vertices first) and points with the
   same XY (within a tolerance) are merged by a stated rule
   (:func:`toolbox.terrain.points.merge_duplicate_xy`);
2. the constrained Delaunay triangulation (CDT, or Triangle ``-pc``:
   :mod:`toolbox.terrain.tin.kernels`) makes every breakline segment a
   triangle edge; where breaklines cross without a shared vertex, it splits them at the
   crossing, and the new node gets the Z interpolated linearly along each crossing segment (the
   mean when the breaklines disagree there; the largest disagreement is reported);
3. a boundary polygon clips hard: its vertices become nodes (Z from the unclipped TIN), its edges
   constrained edges, and triangles outside are removed (no triangle crosses it);
4. a concave hull, optionally, erodes border triangles whose outer edge is longer than a length
   (the chi-shape rule: a triangle is removed only if its third node is not already on the
   border, so every node stays in the TIN and the TIN stays one piece without pinches).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolbox.io.grid import coordinate_rounding
from toolbox.terrain.points import check_not_collinear, merge_duplicate_xy
from toolbox.terrain.tin.kernels import (
    Triangulation,
    crossing_heights,
    interpolate_tin,
    triangulate_pslg,
)
from toolbox.terrain.tin.topology import erode_concave, median_edge_length

SOURCES = ("point", "breakline", "crossing", "boundary")
POINT, BREAKLINE, CROSSING, BOUNDARY = range(4)
CONCAVE_DEFAULT_FACTOR = 3.0


@dataclass
class TinModel:
    """A TIN: nodes, triangles, topology and the constrained (breakline) edges.

    Attributes
    ----------
    xyz : (V, 3) float64
        Node coordinates.
    source : (V,) int8
        Index into :data:`SOURCES`: mass point, breakline vertex, breakline crossing, boundary.
    merged : (V,) int64
        Number of input vertices merged into each node (1 = no duplicate; 0 for added nodes).
    triangles : (T, 3) int32 or int64
        Node indices, counter-clockwise (the triangulation's int32 when no triangle was
        dropped: a 10 M-point TIN's triangles and neighbours take 0.48 GB less than in int64).
    neighbors : (T, 3) int32 or int64
        Triangle across the edge facing each corner, -1 on the border.
    breakline_edges : (K, 2) int64
        Node pairs (lower index first) of the breakline pieces between consecutive nodes: the
        triangle edges among them are the breakline edges (a piece whose two sides were
        clipped away is no edge).
    report : dict
        What was merged, split, clipped and eroded (JSON-serialisable).
    """

    xyz: np.ndarray
    source: np.ndarray
    merged: np.ndarray
    triangles: np.ndarray
    neighbors: np.ndarray
    breakline_edges: np.ndarray
    report: dict = field(default_factory=dict)


class TinBuildError(ValueError):
    """The inputs cannot make a TIN (too few points, collinear, boundary outside the data...)."""


def breakline_segments(line_index: np.ndarray) -> np.ndarray:
    """Segments ``(S, 2)`` joining consecutive vertices of the same line part.

    ``line_index`` gives, for each vertex (in order), the part it belongs to.
    """
    line_index = np.asarray(line_index)
    same = line_index[1:] == line_index[:-1]
    start = np.flatnonzero(same)
    return np.column_stack([start, start + 1]).astype(np.int64)


def _dedupe_within_lines(xyz: np.ndarray, line_index: np.ndarray, segments: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, int]:
    """Drop vertices repeating an earlier vertex of the same line (same XY), e.g. the closing
    vertex of a ring; segments are renumbered. Returns vertices, segments, vertices dropped."""
    n = len(xyz)
    order = np.lexsort((xyz[:, 1], xyz[:, 0], line_index))
    s = np.column_stack([line_index[order], xyz[order, 0], xyz[order, 1]])
    starts = np.ones(n, dtype=bool)
    starts[1:] = np.any(s[1:] != s[:-1], axis=1)
    group = np.empty(n, dtype=np.int64)
    group[order] = np.cumsum(starts) - 1
    first = np.full(int(group.max()) + 1, n, dtype=np.int64)
    np.minimum.at(first, group, np.arange(n))
    kept = first[group] == np.arange(n)
    new_index = np.cumsum(kept) - 1
    remap = new_index[first[group]]
    return xyz[kept], remap[segments], int(n - kept.sum())


def _has_duplicate_xy(xyz: np.ndarray) -> bool:
    """True when two points have exactly the same XY: only points sharing an x with another
    can, so x alone is sorted (half the time of sorting x + iy), then the points of the shared
    x values, if any (complex numbers sort by x, then y)."""
    x = np.sort(xyz[:, 0])
    shared = x[1:][x[1:] == x[:-1]]
    if len(shared) == 0:
        return False
    sub = xyz[np.isin(xyz[:, 0], shared)] if len(shared) < len(x) // 4 else xyz
    key = np.sort(sub[:, 0] + 1j * sub[:, 1])
    return bool(np.any(key[1:] == key[:-1]))


def _group_labels(xyz: np.ndarray, merged: np.ndarray, keep: np.ndarray,
                  tolerance: float) -> np.ndarray:
    """Merged-node index of every input point (``merge_duplicate_xy`` returns the merged points
    and each group's first input index; this recovers the full input -> node map)."""
    n = len(xyz)
    if tolerance > 0:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        from toolbox.terrain.points import local_origin

        pairs = cKDTree(xyz[:, :2] - local_origin(xyz)).query_pairs(tolerance,
                                                                     output_type="ndarray")
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        _, comp = connected_components(graph, directed=False)
        first = np.full(comp.max() + 1, n, dtype=np.int64)
        np.minimum.at(first, comp, np.arange(n))
        order = np.argsort(keep)
        return order[np.searchsorted(keep[order], first[comp])]
    # tolerance 0: every merged point keeps its group's exact XY; complex numbers sort by (x, y)
    node_key = merged[:, 0] + 1j * merged[:, 1]
    order = np.argsort(node_key)
    pos = np.searchsorted(node_key[order], xyz[:, 0] + 1j * xyz[:, 1])
    return order[np.minimum(pos, len(order) - 1)]


def _triangulate(xyz: np.ndarray, segments: np.ndarray, priority: np.ndarray
                 ) -> tuple[Triangulation, np.ndarray, np.ndarray]:
    """Constrained triangulation; returns it, all node heights (inputs + crossings) and, per
    node, the Z disagreement of the crossing breaklines (0 for input nodes)."""
    try:
        tri = triangulate_pslg(xyz[:, :2], segments if len(segments) else None)
    except ValueError as exc:
        raise TinBuildError(str(exc)) from None
    z = xyz[:, 2]
    spread = np.zeros(len(tri.vertices))
    if tri.steiner_count:
        extra, spread[tri.n_input:] = crossing_heights(tri, xyz, segments, priority)
        z = np.concatenate([z, extra])
    return tri, z, spread


def _renumber(tri_keep: np.ndarray, triangles: np.ndarray, neighbors: np.ndarray,
              n_nodes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keep some triangles: compact triangles, neighbours and nodes. Returns the new triangles,
    neighbours and the old index of each kept node."""
    new_index = np.full(len(triangles) + 1, -1, dtype=np.int64)  # last slot: "none" (-1)
    new_index[np.flatnonzero(tri_keep)] = np.arange(int(tri_keep.sum()))
    tris = triangles[tri_keep]
    nbs = new_index[neighbors[tri_keep]]
    used = np.zeros(n_nodes, dtype=bool)
    used[tris.ravel()] = True
    node_old = np.flatnonzero(used)
    node_new = np.full(n_nodes, -1, dtype=np.int64)
    node_new[node_old] = np.arange(len(node_old))
    return node_new[tris], nbs, node_old


def build_tin(points: np.ndarray, line_xyz: np.ndarray | None = None,
              line_index: np.ndarray | None = None, boundary=None, concave: bool = False,
              concave_max_edge: float | None = None, duplicate_rule: str = "mean",
              duplicate_tolerance: float = 0.0, nodes_ready=None) -> TinModel:
    """Constrained Delaunay TIN of mass points and breaklines, clipped to a boundary.

    Parameters
    ----------
    points : (P, 3) float array
        Mass points (may be empty if breaklines are given).
    line_xyz : (L, 3) float array, optional
        Breakline vertices, line after line, in order along each line.
    line_index : (L,) int array, optional
        Line (part) of each vertex; consecutive vertices of the same line make a segment.
    boundary : shapely Polygon or MultiPolygon, optional
        Hard clip: nothing of the TIN lies outside it (holes included). Parts outside the
        data's convex hull are dropped (reported).
    concave : bool
        Erode the border into a concave hull (see :func:`erode_concave`).
    concave_max_edge : float, optional
        With ``concave``: border triangles whose border edge is longer than this (map units)
        are removed; default :data:`CONCAVE_DEFAULT_FACTOR` x the median edge length.
    duplicate_rule : {"mean", "first", "min", "max", "error"}
        Z of points sharing an XY position; breakline vertices come first for "first".
    duplicate_tolerance : float
        Planimetric distance under which points are the same position (0: equal XY).
    nodes_ready : callable, optional
        Called as ``nodes_ready(xyz, source, merged)`` with the model's nodes before the
        triangulation when they are known then (no breaklines, boundary or concave hull: every
        node is a merged input point, and the triangulation uses every one): the caller may
        write them while the triangulation runs (:class:`toolbox.terrain.tin.store.NodesAhead`).

    Returns
    -------
    TinModel

    Raises
    ------
    TinBuildError
        Fewer than 3 distinct points, all collinear, boundary missing the data, duplicates with
        different Z under the "error" rule.
    """
    points = np.asarray(points, dtype="float64").reshape(-1, 3)
    line_xyz = np.zeros((0, 3)) if line_xyz is None else np.asarray(line_xyz, "float64")
    line_index = np.zeros(0, dtype=np.int64) if line_index is None else np.asarray(line_index)
    report: dict = {"input_points": len(points), "breakline_vertices": len(line_xyz)}
    line_segments = breakline_segments(line_index) if len(line_xyz) else np.zeros((0, 2), int)
    if len(line_xyz):
        # a closed line's last vertex and repeated vertices are the same node, not duplicates
        line_xyz, line_segments, repeated = _dedupe_within_lines(line_xyz, line_index,
                                                                 line_segments)
        report["breakline_repeated_vertices"] = repeated
    pooled = np.vstack([line_xyz, points]) if len(line_xyz) else points  # never written to
    is_line = np.concatenate([np.ones(len(line_xyz), bool), np.zeros(len(points), bool)])
    if len(pooled) < 3:
        raise TinBuildError(f"a TIN needs at least 3 points, got {len(pooled)}")
    if duplicate_tolerance > 0 or _has_duplicate_xy(pooled):
        try:
            nodes, dup, keep = merge_duplicate_xy(pooled, duplicate_tolerance, duplicate_rule)
        except ValueError as exc:
            raise TinBuildError(f"duplicate XY positions: {exc}") from None
        report["duplicates"] = dup.as_dict()
        group = _group_labels(pooled, nodes, keep, duplicate_tolerance) if dup.removed else \
            np.arange(len(pooled))
    else:  # the common case, checked in a fraction of merge_duplicate_xy's time
        nodes, group = pooled, np.arange(len(pooled))
        report["duplicates"] = {"duplicate_groups": 0, "duplicates_removed": 0,
                                "max_z_spread": 0.0, "rule": duplicate_rule}
    if len(nodes) == len(pooled):  # no merge: group is the identity
        merged = np.ones(len(nodes), dtype=np.int64)
        source = np.where(is_line, BREAKLINE, POINT).astype(np.int8)
    else:
        merged = np.bincount(group, minlength=len(nodes)).astype(np.int64)
        source = np.where(np.bincount(group, weights=is_line, minlength=len(nodes)) > 0,
                          BREAKLINE, POINT).astype(np.int8)
    segments = group[line_segments]
    segments = segments[segments[:, 0] != segments[:, 1]]
    segments = np.unique(np.sort(segments, axis=1), axis=0) if len(segments) else segments
    report["breakline_segments"] = len(segments)
    if len(nodes) < 3:
        raise TinBuildError(f"a TIN needs at least 3 distinct XY positions, got {len(nodes)} "
                            "after merging duplicates")
    try:
        check_not_collinear(nodes[:, :2] - nodes[:, :2].mean(axis=0), "TIN nodes")
    except ValueError as exc:
        raise TinBuildError(str(exc)) from None
    n_break = len(segments)
    if nodes_ready is not None and n_break == 0 and boundary is None and not concave:
        nodes_ready(nodes, source, merged)
    tri, z, spread = _triangulate(nodes, segments, np.ones(n_break))
    inside = None
    if boundary is not None:
        # heights of the boundary's vertices come from the unclipped TIN; then the boundary is
        # inserted as constrained edges and everything outside it is dropped
        first_xyz = np.column_stack([tri.vertices, z])
        tri, z, inside, boundary_nodes, spread, clip_report = _clip_to_boundary(
            first_xyz, tri.triangles, nodes, segments, boundary)
        report["boundary"] = clip_report
        source = np.concatenate([source, np.full(boundary_nodes, BOUNDARY, np.int8)])
        merged = np.concatenate([merged, np.zeros(boundary_nodes, np.int64)])
    xyz = np.column_stack([tri.vertices, z])
    source = np.concatenate([source, _steiner_sources(tri, n_break)])
    merged = np.concatenate([merged, np.zeros(tri.steiner_count, np.int64)])
    # breakline edges: output subsegments whose parent is a breakline segment
    sub = tri.segments[(tri.segment_parents >= 0) & (tri.segment_parents < n_break)]
    sub = sub.astype(np.int64)
    if inside is not None:
        triangles, neighbors, node_old = _renumber(inside, tri.triangles, tri.neighbors,
                                                   len(xyz))
        node_new = np.full(len(xyz), -1, dtype=np.int64)
        node_new[node_old] = np.arange(len(node_old))
        xyz, source, merged = xyz[node_old], source[node_old], merged[node_old]
        spread = spread[node_old]
        sub = node_new[sub]
    else:  # every node is kept, in its place: the triangulation's own (int32) arrays
        triangles, neighbors = tri.triangles, tri.neighbors
    sub = sub[(sub >= 0).all(axis=1)] if len(sub) else sub.reshape(0, 2)
    if concave:
        if concave_max_edge is None:
            concave_max_edge = CONCAVE_DEFAULT_FACTOR * median_edge_length(xyz, triangles,
                                                                          neighbors)
        alive = erode_concave(xyz[:, :2], triangles, neighbors, float(concave_max_edge))
        report["concave_hull"] = {"max_edge": float(concave_max_edge),
                                  "triangles_removed": int((~alive).sum())}
        if not alive.all():
            triangles, neighbors, node_old = _renumber(alive, triangles, neighbors, len(xyz))
            node_new = np.full(len(xyz), -1, dtype=np.int64)
            node_new[node_old] = np.arange(len(node_old))
            xyz, source, merged = xyz[node_old], source[node_old], merged[node_old]
            spread = spread[node_old]
            sub = node_new[sub]
            sub = sub[(sub >= 0).all(axis=1)]
    report["crossings"] = {"count": int((source == CROSSING).sum()),
                           "max_z_disagreement": float(spread.max()) if len(spread) else 0.0}
    report.update(nodes=len(xyz), triangles=len(triangles))
    sub = np.unique(np.sort(sub, axis=1), axis=0) if len(sub) else np.zeros((0, 2), np.int64)
    return TinModel(xyz, source, merged, triangles, neighbors, sub, report)


def _steiner_sources(tri: Triangulation, n_break: int) -> np.ndarray:
    """Source code of each vertex Triangle added: BOUNDARY if it lies on a boundary segment
    (parent index >= ``n_break``), else CROSSING (breaklines crossing each other)."""
    codes = np.full(tri.steiner_count, CROSSING, dtype=np.int8)
    if tri.steiner_count:
        on_boundary = tri.segments[tri.segment_parents >= n_break].ravel()
        on_boundary = on_boundary[on_boundary >= tri.n_input] - tri.n_input
        codes[on_boundary] = BOUNDARY
    return codes


def _vertices_in(region, xy: np.ndarray, triangles: np.ndarray, span: float) -> np.ndarray:
    """Which ``triangles`` have all three vertices in ``region`` (or on its edge, up to
    rounding): a sliver along the data's hull, where a boundary edge meets it, can have its
    centroid inside by rounding and a vertex well outside (a zero-area triangle, slope 90°)."""
    import shapely

    pts = xy[triangles.ravel()]
    ok = shapely.contains_xy(region, pts[:, 0], pts[:, 1])
    if not ok.all():  # boundary vertices, mostly: on the edge
        tol = max(1e-6 * span, coordinate_rounding(float(np.abs(xy).max())))
        check = np.flatnonzero(~ok)
        ok[check] = shapely.distance(region, shapely.points(pts[check])) <= tol
    return ok.reshape(-1, 3).all(axis=1)


def _clip_to_boundary(first_xyz: np.ndarray, first_triangles: np.ndarray, nodes: np.ndarray,
                      segments: np.ndarray, boundary):
    """Re-triangulate ``nodes`` with the boundary (inside the data's convex hull) as nodes and
    constrained edges; the boundary's heights come from the first TIN.

    Returns the triangulation, all heights, the mask of triangles inside the boundary, the
    number of boundary nodes added, the largest Z disagreement at crossings and a report.
    """
    import shapely
    from scipy.spatial import cKDTree

    from toolbox.terrain.points import local_origin

    hull = shapely.convex_hull(shapely.multipoints(first_xyz[:, :2]))
    region = shapely.intersection(shapely.make_valid(boundary), hull)
    parts = [g for g in shapely.get_parts(region) if shapely.get_type_id(g) == 3]
    region = shapely.union_all(parts) if parts else shapely.Polygon()
    if region.is_empty or region.area == 0:
        raise TinBuildError("BOUNDARY does not overlap the convex hull of the points")
    outside_area = max(0.0, float(shapely.area(boundary) - region.area))
    # below the rounding of the coordinates along the boundary it is no area (at a northing of
    # 5,000,000 a boundary inside the hull came out 3e-18 "outside", and was warned about)
    far = float(np.abs(first_xyz[:, :2]).max())
    if outside_area <= coordinate_rounding(far) * float(shapely.length(boundary)):
        outside_area = 0.0
    span = max(float(np.ptp(first_xyz[:, :2], axis=0).max()), 1.0)
    ring_xy = [np.asarray(ring.coords)[:-1, :2] for poly in shapely.get_parts(region)
               for ring in [poly.exterior, *poly.interiors]]
    all_xy = np.vstack(ring_xy)
    bz = interpolate_tin(first_xyz, first_triangles, all_xy[:, 0], all_xy[:, 1],
                         tolerance=1e-7 * span)
    if np.isnan(bz).any():
        raise TinBuildError("internal: boundary vertices inside the hull got no height")
    # boundary vertices on an existing node reuse it
    origin = local_origin(nodes)
    dist, near = cKDTree(nodes[:, :2] - origin).query(all_xy - origin, k=1)
    snap = dist <= 1e-9 * span
    index = np.where(snap, near, -1)
    # new boundary vertices, once each (rings may touch at a vertex)
    key = all_xy[:, 0] + 1j * all_xy[:, 1]
    _, fresh, inverse = np.unique(np.where(snap, np.nan, key), return_index=True,
                                  return_inverse=True)
    keep_fresh = ~snap[fresh]
    rank = np.cumsum(keep_fresh) - 1
    index = np.where(snap, index, len(nodes) + rank[inverse.ravel()])
    fresh = fresh[keep_fresh]
    xyz2 = np.vstack([nodes, np.column_stack([all_xy[fresh], bz[fresh]])])
    bounds = np.cumsum([0] + [len(r) for r in ring_xy])
    bseg = np.vstack([np.column_stack([index[i:j], np.roll(index[i:j], -1)])
                      for i, j in zip(bounds[:-1], bounds[1:], strict=True)])
    bseg = bseg[bseg[:, 0] != bseg[:, 1]]
    all_segments = np.vstack([segments, bseg]) if len(segments) else bseg
    priority = np.concatenate([np.ones(len(segments)), np.zeros(len(bseg))])
    tri, z, spread = _triangulate(xyz2, all_segments, priority)
    xy = tri.vertices
    centroid = (xy[tri.triangles[:, 0]] + xy[tri.triangles[:, 1]] + xy[tri.triangles[:, 2]]) / 3
    shapely.prepare(region)
    keep = shapely.contains_xy(region, centroid[:, 0], centroid[:, 1])
    keep[np.flatnonzero(keep)] = _vertices_in(region, xy, tri.triangles[keep], span)
    if not keep.any():
        raise TinBuildError("BOUNDARY contains no triangle of the TIN")
    used = np.zeros(len(xy), dtype=bool)
    used[tri.triangles[keep].ravel()] = True
    report = {"boundary_nodes_added": int(len(fresh)),
              "nodes_dropped_outside": int((~used[:len(nodes)]).sum()),
              "triangles_dropped_outside": int((~keep).sum()),
              "boundary_area_outside_data_hull": outside_area}
    return tri, z, keep, len(fresh), spread, report
