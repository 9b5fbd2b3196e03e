"""Editing kernels of restitution (thesis S002 §2.2.1 parameter file, §2.2.2 sampling, §2.3):
building squaring, alignment of nearly collinear vertices, curve sampling and densification.

Arrays in, arrays out: vertex arrays (N, 2) or (N, 3) in map units, shifted by the caller to a
local origin. Each kernel returns the new vertices and what moved; none moves a vertex farther
than its tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# -- squaring ---------------------------------------------------------------------------------------


@dataclass
class SquaringResult:
    """Result of :func:`square_rings`.

    Attributes
    ----------
    rings : list of (N_k, D) arrays, the new rings (closed: last = first), same order as input.
    moved : (M,) node indices that moved; ``before``/``after`` (M, 2) their positions.
    squared : (P,) bool, polygon squared (else left as it was, reason in ``reasons``).
    reasons : dict polygon -> why it was not squared.
    orientation : (P,) dominant direction of each polygon's cluster, degrees from the X axis.
    corner_error : largest deviation from 90 (or 180) degrees of a corner between two squared
        walls of a squared building, degrees (0 up to rounding).
    """

    rings: list[np.ndarray]
    node_of_vertex: list[np.ndarray]
    moved: np.ndarray
    before: np.ndarray
    after: np.ndarray
    squared: np.ndarray
    reasons: dict[int, str] = field(default_factory=dict)
    orientation: np.ndarray | None = None
    corner_error: float = 0.0


class _UnionFind:
    def __init__(self, n: int):
        self.parent = np.arange(n)

    def find(self, i: int) -> int:
        root = i
        while self.parent[root] != root:
            root = self.parent[root]
        while self.parent[i] != root:
            self.parent[i], i = root, self.parent[i]
        return root

    def union(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[rb] = ra

    def labels(self) -> np.ndarray:
        return np.array([self.find(i) for i in range(len(self.parent))])


def _group_mean(values: np.ndarray, pairs: list[tuple[int, int]], nodes: np.ndarray
                ) -> np.ndarray:
    """``values`` with every group of nodes joined by ``pairs`` set to the group's mean (the
    least-squares solution of "these coordinates are equal")."""
    out = values.copy()
    if not pairs:
        return out
    index = {n: k for k, n in enumerate(nodes)}
    uf = _UnionFind(len(nodes))
    for a, b in pairs:
        uf.union(index[a], index[b])
    labels = uf.labels()
    sums = np.bincount(labels, weights=values[nodes], minlength=len(nodes))
    counts = np.bincount(labels, minlength=len(nodes))
    out[nodes] = sums[labels] / counts[labels]
    return out


def ring_area(ring: np.ndarray) -> float:
    """Signed shoelace area of a closed ring (last = first)."""
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * float(np.dot(x[:-1], y[1:]) - np.dot(x[1:], y[:-1]))


def corner_angles(ring: np.ndarray) -> np.ndarray:
    """Interior corner angles of a closed ring, degrees in [0, 180] (unsigned)."""
    pts = ring[:-1, :2]
    prev = np.roll(pts, 1, axis=0) - pts
    nxt = np.roll(pts, -1, axis=0) - pts
    cos = np.einsum("ij,ij->i", prev, nxt) / (np.linalg.norm(prev, axis=1)
                                              * np.linalg.norm(nxt, axis=1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _deviation90(phi: np.ndarray, theta: float) -> np.ndarray:
    """Angle (radians) between directions ``phi`` and the nearest of theta + k 90 degrees."""
    rel = (phi - theta) % (np.pi / 2)
    return np.minimum(rel, np.pi / 2 - rel)


def dominant_direction(phi: np.ndarray, length: np.ndarray, angle_tolerance: float) -> float:
    """Dominant wall direction (radians, modulo 90 degrees) of walls with directions ``phi`` and
    lengths ``length``: the wall direction that the longest total length of walls lies within
    ``angle_tolerance`` (degrees) of, refined by the length-weighted mean over those walls,
    atan2(sum L sin 4phi, sum L cos 4phi) / 4. An oblique wall does not pull it."""
    if len(phi) == 0:
        return 0.0
    tol = np.radians(angle_tolerance)
    support = [length[_deviation90(phi, t) <= tol].sum() for t in phi]
    seed = float(phi[int(np.argmax(support))])
    inliers = _deviation90(phi, seed) <= tol
    # mean of 4 (phi - seed) around 0, so the wrap-around at 90 degrees does not matter
    d = 4 * (phi[inliers] - seed)
    return seed + 0.25 * float(np.arctan2(np.sum(length[inliers] * np.sin(d)),
                                          np.sum(length[inliers] * np.cos(d))))


def square_rings(rings: list[np.ndarray], polygon_of_ring: np.ndarray, tolerance: float,
                 angle_tolerance: float, area_tolerance: float, precision: float = 1e-3,
                 exterior: np.ndarray | None = None, n_polygons: int | None = None
                 ) -> SquaringResult:
    """Square buildings: walls within ``angle_tolerance`` (degrees) of the dominant direction
    (or its perpendicular) made exactly parallel/perpendicular to it, by the least-squares
    smallest move of the vertices.

    Method: vertices closer than ``precision`` are one node (shared by neighbouring buildings,
    and so kept shared); buildings sharing nodes form a cluster with one dominant direction
    theta = atan2(sum L sin 4phi, sum L cos 4phi) / 4 over its walls (length L, direction phi).
    In the frame rotated by theta a wall along u makes its two nodes' v equal, a wall along v
    their u equal; the smallest move meeting all these equalities sets each group of equal
    coordinates to its mean. A building whose vertices would move more than ``tolerance``, or
    whose area would change by more than ``area_tolerance`` (a fraction), loses its
    constraints (with the buildings sharing the offending nodes) and the cluster is solved
    again: no vertex moves beyond the tolerance.

    Parameters
    ----------
    rings : closed (N_k, 2 or 3) vertex arrays (last = first), local coordinates.
    polygon_of_ring : (R,) polygon index of each ring (exterior and holes of one building).
    tolerance, angle_tolerance, area_tolerance, precision : see above.
    exterior : (R,) bool, the ring is an exterior (a multipolygon's building has several);
        by default the first ring of each polygon.
    n_polygons : number of polygons (default: the largest index + 1); one with no ring (a null
        or empty geometry) is left as it is.
    """
    n_poly = n_polygons if n_polygons is not None else \
        int(polygon_of_ring.max()) + 1 if len(rings) else 0
    open_rings = [r[:-1] for r in rings]
    xy_all = np.vstack([r[:, :2] for r in open_rings]) if rings else np.zeros((0, 2))
    keys = np.round(xy_all / precision).astype(np.int64)
    _, first, node_all = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    node_all = node_all.reshape(-1)
    nodes_xy = xy_all[first]
    splits = np.cumsum([len(r) for r in open_rings])[:-1]
    node_of_vertex = np.split(node_all, splits)
    # walls: (node a, node b, polygon)
    walls = []
    for r, nodes in enumerate(node_of_vertex):
        p = int(polygon_of_ring[r])
        for a, b in zip(nodes, np.roll(nodes, -1), strict=True):
            if a != b:
                walls.append((int(a), int(b), p))
    walls_arr = np.array(walls, dtype=np.int64).reshape(-1, 3)
    # clusters of polygons sharing nodes
    uf = _UnionFind(n_poly)
    owner = {}
    for a, _, p in walls:
        if a in owner:
            uf.union(owner[a], p)
        owner[a] = p
    cluster = uf.labels() if n_poly else np.zeros(0, int)
    node_polys: dict[int, set[int]] = {}
    for a, b, p in walls:
        node_polys.setdefault(a, set()).add(p)
        node_polys.setdefault(b, set()).add(p)
    d = nodes_xy[walls_arr[:, 1]] - nodes_xy[walls_arr[:, 0]]
    length = np.hypot(d[:, 0], d[:, 1])
    phi = np.arctan2(d[:, 1], d[:, 0])
    theta_of_cluster = {}
    for c in np.unique(cluster):
        sel = cluster[walls_arr[:, 2]] == c
        theta_of_cluster[c] = dominant_direction(phi[sel], length[sel], angle_tolerance)
    theta = np.array([theta_of_cluster[c] for c in cluster[walls_arr[:, 2]]]) if len(walls) \
        else np.zeros(0)
    rel = np.degrees(phi - theta) % 180.0  # 0 = along u, 90 = along v
    along_u = np.minimum(rel, 180.0 - rel) <= angle_tolerance
    along_v = np.abs(rel - 90.0) <= angle_tolerance
    active = np.ones(n_poly, dtype=bool)
    reasons: dict[int, str] = {}
    if exterior is None:
        exterior = np.r_[True, polygon_of_ring[1:] != polygon_of_ring[:-1]] if len(rings) \
            else np.zeros(0, bool)
    is_hole = ~np.asarray(exterior, bool)
    ringless = np.bincount(polygon_of_ring, minlength=n_poly) == 0
    for p in np.flatnonzero(ringless):
        reasons[int(p)] = "no geometry (null or empty): left as it is"

    def net_areas(ring_list: list[np.ndarray]) -> np.ndarray:
        """Area of each polygon: |exterior| - sum |holes| (whatever the rings' orientation)."""
        out = np.zeros(n_poly)
        for r, ring in enumerate(ring_list):
            out[polygon_of_ring[r]] += (-1 if is_hole[r] else 1) * abs(ring_area(ring))
        return out

    areas = net_areas(rings)
    new_xy = nodes_xy.copy()
    for _ in range(n_poly + 1):
        new_xy = nodes_xy.copy()
        for c in np.unique(cluster):
            sel = (cluster[walls_arr[:, 2]] == c) & active[walls_arr[:, 2]]
            if not sel.any():
                continue
            t = theta_of_cluster[c]
            cos, sin = np.cos(t), np.sin(t)
            nodes = np.unique(walls_arr[cluster[walls_arr[:, 2]] == c, :2])
            u = nodes_xy[:, 0] * cos + nodes_xy[:, 1] * sin
            v = -nodes_xy[:, 0] * sin + nodes_xy[:, 1] * cos
            v_pairs = [(a, b) for a, b, _ in walls_arr[sel & along_u]]
            u_pairs = [(a, b) for a, b, _ in walls_arr[sel & along_v]]
            u2 = _group_mean(u, u_pairs, nodes)
            v2 = _group_mean(v, v_pairs, nodes)
            new_xy[nodes, 0] = u2[nodes] * cos - v2[nodes] * sin
            new_xy[nodes, 1] = u2[nodes] * sin + v2[nodes] * cos
        shift = np.hypot(*(new_xy - nodes_xy).T)
        failed = set()
        new_areas = net_areas([np.vstack([new_xy[nodes], new_xy[nodes[:1]]])
                               for nodes in node_of_vertex])
        for p in range(n_poly):
            if ringless[p]:
                continue
            pnodes = np.unique(np.concatenate([node_of_vertex[r] for r in
                                               np.flatnonzero(polygon_of_ring == p)]))
            worst = float(shift[pnodes].max()) if len(pnodes) else 0.0
            change = abs(new_areas[p] - areas[p]) / abs(areas[p]) if areas[p] else 0.0
            if worst > tolerance + 1e-12:
                bad = pnodes[shift[pnodes] > tolerance + 1e-12]
                for n in bad:
                    failed |= node_polys.get(int(n), set())
                reasons.setdefault(p, f"a vertex would move {worst:.3f} (squaring tolerance "
                                      f"{tolerance:g})")
            elif change > area_tolerance:
                failed.add(p)
                reasons.setdefault(p, f"area would change by {100 * change:.2f}% (tolerance "
                                      f"{100 * area_tolerance:g}%)")
        failed = {p for p in failed if active[p]}
        if not failed:
            break
        active[list(failed)] = False
        for p in failed:
            reasons.setdefault(p, "shares a vertex with a building that cannot be squared")
    # a building left active with no constrained wall is "not squared" too
    has_constraint = np.zeros(n_poly, dtype=bool)
    for (_, _, p), cu, cv in zip(walls_arr, along_u, along_v, strict=True):
        has_constraint[p] |= bool(cu or cv)
    for p in np.flatnonzero(active & ~has_constraint):
        reasons.setdefault(int(p), f"no wall within {angle_tolerance:g} degrees of the dominant "
                                   "direction")
    squared = active & has_constraint
    for p in np.flatnonzero(squared):
        reasons.pop(int(p), None)
    out_rings = []
    for r, nodes in enumerate(node_of_vertex):
        ring = rings[r].copy()
        ring[:-1, :2] = new_xy[nodes]
        ring[-1] = ring[0]
        out_rings.append(ring)
    # corners between two squared walls: how far from 90/180 degrees they ended
    constrained = (along_u | along_v) & squared[walls_arr[:, 2]] if len(walls) else \
        np.zeros(0, bool)
    wall_ok = {(int(a), int(b)) for (a, b, _), ok in zip(walls_arr, constrained, strict=True)
               if ok}
    corner_error = 0.0
    for nodes in node_of_vertex:
        prev, nxt = np.roll(nodes, 1), np.roll(nodes, -1)
        for p_, n_, c_ in zip(prev, nxt, nodes, strict=True):
            if (int(p_), int(c_)) in wall_ok and (int(c_), int(n_)) in wall_ok:
                u, w = new_xy[p_] - new_xy[c_], new_xy[n_] - new_xy[c_]
                angle = np.degrees(np.arctan2(abs(u[0] * w[1] - u[1] * w[0]), u @ w))
                corner_error = max(corner_error, abs(((angle + 45) % 90) - 45))
    moved = np.flatnonzero(np.hypot(*(new_xy - nodes_xy).T) > 0)
    orientation = np.array([np.degrees(theta_of_cluster[c]) for c in cluster])
    orientation[ringless] = np.nan
    return SquaringResult(out_rings, node_of_vertex, moved, nodes_xy[moved], new_xy[moved],
                          squared, reasons, orientation, float(corner_error))


# -- alignment ---------------------------------------------------------------------------------------


def _distance_to_chord(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    n = np.hypot(*d)
    if n == 0:
        return np.hypot(*(points - a).T)
    return np.abs(d[0] * (points[:, 1] - a[1]) - d[1] * (points[:, 0] - a[0])) / n


def _project(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    t = ((points - a) @ d) / float(d @ d)
    return a + np.outer(t, d)


def align_vertices(coords: np.ndarray, tolerance: float, fixed: np.ndarray,
                   closed: bool = False) -> np.ndarray:
    """Make nearly collinear vertices collinear: the longest runs of vertices whose interior
    vertices are all within ``tolerance`` of the chord between the run's ends are projected onto
    that chord (greedy, from the first vertex). ``fixed`` (N,) bool marks vertices that never
    move and end a run (line ends, vertices shared with other entities). Returns the new
    coordinates (Z kept per vertex). For a closed ring (last = first) the ring is walked from
    its first fixed vertex (vertex 0 when none)."""
    coords = np.asarray(coords, dtype=float)
    if closed:
        body, fixed_body = coords[:-1], fixed[:-1].copy()
        start = int(np.flatnonzero(fixed_body)[0]) if fixed_body.any() else 0
        order = np.r_[np.arange(start, len(body)), np.arange(0, start), start]
        walked = align_vertices(body[order], tolerance, np.r_[fixed_body[order[:-1]], True]
                                | np.r_[True, np.zeros(len(body) - 1, bool), True])
        out = body.copy()
        out[order[:-1]] = walked[:-1]
        return np.vstack([out, out[:1]])
    out = coords.copy()
    n = len(coords)
    xy = coords[:, :2]
    i = 0
    while i < n - 1:
        j = i + 1
        while j + 1 < n and not fixed[j]:
            inner = xy[i + 1:j + 1]
            if (_distance_to_chord(inner, xy[i], xy[j + 1]) <= tolerance).all():
                j += 1
            else:
                break
        if j - i >= 2:
            out[i + 1:j, :2] = _project(xy[i + 1:j], xy[i], xy[j])
        i = j
    return out


# -- sampling ----------------------------------------------------------------------------------------


def sample_by_vectors(coords: np.ndarray, max_distance: float, max_angle: float
                      ) -> np.ndarray:
    """"Campionamento per vettori" (thesis S002 §2.2.2): indices of the vertices kept.

    Walking along the plotted vertices, the previous vertex is recorded as soon as the next one
    would be farther than ``max_distance`` from the last recorded vertex, or as soon as the
    direction of travel deviates by more than ``max_angle`` (degrees) from the line through the
    last two recorded vertices (the first segment's direction until two are recorded). The ends
    are always kept, so no chord between kept vertices is longer than ``max_distance`` unless a
    plotted segment already is.
    """
    n = len(coords)
    if n <= 2:
        return np.arange(n)
    xy = coords[:, :2]
    keep = [0]
    limit = np.radians(max_angle)
    for i in range(2, n):
        last = keep[-1]
        if i - 1 == last:
            continue
        ref = xy[last] - xy[keep[-2]] if len(keep) >= 2 else xy[1] - xy[0]
        step = xy[i] - xy[i - 1]
        far = float(np.hypot(*(xy[i] - xy[last]))) > max_distance
        turn = abs(np.arctan2(ref[0] * step[1] - ref[1] * step[0], ref @ step)) \
            if step.any() and ref.any() else 0.0
        if far or turn > limit:
            keep.append(i - 1)
    keep.append(n - 1)
    return np.array(keep)


def _chainage(coords: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.hypot(*np.diff(coords[:, :2], axis=0).T))]


def sample_by_distance(coords: np.ndarray, step: float) -> np.ndarray:
    """Vertices every ``step`` along the line (planimetric chainage), Z interpolated; the last
    vertex kept."""
    s = _chainage(coords)
    at = np.arange(0.0, s[-1], step)
    at = np.r_[at, s[-1]] if s[-1] - at[-1] > 1e-9 else np.r_[at[:-1], s[-1]]
    return np.column_stack([np.interp(at, s, coords[:, k]) for k in range(coords.shape[1])])


def densify(coords: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices added so that no segment is longer than ``step`` (the original vertices kept,
    Z interpolated). Returns (coords, added mask)."""
    parts, added = [coords[:1]], [np.zeros(1, bool)]
    for a, b in zip(coords[:-1], coords[1:], strict=True):
        pieces = max(1, int(np.ceil(np.hypot(*(b[:2] - a[:2])) / step - 1e-9)))
        t = np.arange(1, pieces + 1)[:, None] / pieces
        parts.append(a + t * (b - a))
        added.append(np.r_[np.ones(pieces - 1, bool), False])
    return np.vstack(parts), np.concatenate(added)


def deviation(original: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Distance of each original vertex from the new line (planimetric)."""
    import shapely

    line = shapely.LineString(new[:, :2])
    return shapely.distance(shapely.points(original[:, :2]), line)
