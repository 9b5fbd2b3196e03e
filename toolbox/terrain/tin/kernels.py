"""TIN kernels: (constrained) Delaunay triangulation and the plane of each triangle at points and
at raster cell centres.

Arrays in, arrays out; no files, no CRS. Conventions:

- ``xy`` / ``xyz`` are ``(N, 2)`` / ``(N, 3)`` float64 map coordinates (x east, y north, z up);
- ``triangles`` are ``(T, 3)`` int vertex indices, counter-clockwise in map coordinates;
- rasters are north-up: cell ``(r, c)`` has its centre at
  ``(x0 + (c + 0.5) * cell_x, y0 - (r + 0.5) * cell_y)``, ``(x0, y0)`` being the top-left corner;
- "outside the TIN" is NaN.

The triangulation is constrained Delaunay with exact predicates, by one of two libraries:

- ``cdt`` (the default): pythoncdt, bindings of Artem Amirkhanov's CDT library (MPL-2.0, a core
  dependency: redistributable in commercial products);
- ``triangle``: Shewchuk's Triangle (the ``triangle`` package; its licence forbids commercial
  redistribution, so it is the optional extra ``pip install photogrammetry-toolbox[triangle]``),
  as fast as CDT on a million random points (CDT 1.08 times faster; 1.13 times with the bench's
  breaklines: bench/results/tin_core.md; Triangle was 1.4 times faster before CDT's points went
  in Z-order).

The environment variable ``TOOLBOX_TRIANGULATOR`` chooses: ``cdt`` (default), ``triangle``, or
``auto`` (Triangle when installed, else CDT); the ``triangulator`` argument of
:func:`triangulate_pslg` overrides it. Both give the same triangles on points in general position
(the Delaunay triangulation is then unique); with four or more points on one circle each breaks
the tie its own way. Crossing segments are split at their intersection by both. CDT's own
result does not depend on the points' order in memory: the same arrays (points in general
position, or an insertion sequence provably unchanged), else the same triangles, kept only once
a check shows no four points of two neighbouring triangles on one circle (:func:`_cdt`).
The height
inside a triangle is the plane through its three nodes, thesis eq. [43]-[44]
(domain notes par. 14), evaluated with coordinates relative to the triangle's first
vertex so large projected coordinates lose no digits.

Point-in-triangle tests evaluate the orientation of each edge in one canonical direction (from its
lower to its higher vertex index), so the two triangles sharing an edge always agree on which
side a point is: a point or cell centre inside the TIN is never lost in a crack between triangles.
"""

from __future__ import annotations

import itertools
import operator
import os
import re
from dataclasses import dataclass

import numpy as np

from toolbox.errors import ToolboxError
from toolbox.terrain.points import local_origin


class CrossingSegmentsError(ValueError):
    """Constraint segments cross away from their vertices (split them first)."""


# -- triangulation --------------------------------------------------------------------------------
@dataclass
class Triangulation:
    """Result of :func:`triangulate_pslg`.

    Attributes
    ----------
    vertices : (V, 2) float64
        Map coordinates. The first ``n_input`` rows are the input points unchanged; rows after
        them are vertices the triangulator added where input segments cross (Steiner points).
    triangles : (T, 3) int32
        Vertex indices, counter-clockwise.
    neighbors : (T, 3) int32
        ``neighbors[t, j]`` is the triangle across the edge opposite corner ``j`` of ``t``
        (the edge ``triangles[t, j+1]`` - ``triangles[t, j+2]``), -1 on the hull.
    segments : (S, 2) int32
        Constrained edges of the result: input segments, split where crossed or touched by a
        vertex. A piece lying on several input segments (overlapping ones) may appear once per
        parent; with Triangle the convex hull edges are also listed (parent -1).
    segment_parents : (S,) int64
        Index of the input segment each row of ``segments`` comes from; -1 for hull edges.
    n_input : int
        Number of input points.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    neighbors: np.ndarray
    segments: np.ndarray
    segment_parents: np.ndarray
    n_input: int

    @property
    def steiner_count(self) -> int:
        """Vertices added at segment crossings."""
        return len(self.vertices) - self.n_input


def _check_xy(xy: np.ndarray) -> np.ndarray:
    xy = np.asarray(xy, dtype="float64")
    if xy.ndim != 2 or xy.shape[1] < 2:
        raise ValueError(f"xy must be an (N, 2) array, got shape {xy.shape}")
    xy = xy[:, :2]
    if len(xy) < 3:
        raise ValueError(f"a triangulation needs at least 3 points, got {len(xy)}")
    if not np.isfinite(xy).all():
        raise ValueError("xy contains NaN or infinite coordinates")
    return xy


def _box(xy: np.ndarray) -> np.ndarray:
    """``[[xmin, ymin], [xmax, ymax]]`` of ``(N, 2+)`` points, one reduction per column (a
    reduction along axis 0 of an ``(N, 2)`` array runs 40 times slower)."""
    x, y = xy[:, 0], xy[:, 1]
    return np.array([[x.min(), y.min()], [x.max(), y.max()]])


def _origin_of(xy: np.ndarray) -> np.ndarray:
    """:func:`local_origin` of the points, from their bounding box."""
    return local_origin(_box(xy))


def _check_segments(segments, n: int) -> np.ndarray:
    seg = np.asarray(segments)
    if seg.size == 0:
        return np.zeros((0, 2), dtype=np.int32)
    if seg.ndim != 2 or seg.shape[1] != 2 or seg.dtype.kind not in "iu":
        raise ValueError(f"segments must be an (M, 2) integer array, got shape {seg.shape} "
                         f"dtype {seg.dtype}")
    if seg.min() < 0 or seg.max() >= n:
        raise ValueError(f"segments must index the {n} points (0..{n - 1}), got values "
                         f"{int(seg.min())}..{int(seg.max())}")
    return seg.astype(np.int32)


TRIANGULATOR_ENV = "TOOLBOX_TRIANGULATOR"
TRIANGULATORS = ("cdt", "triangle", "auto")


def triangulator_name(choice: str | None = None) -> str:
    """The triangulator to use, ``"cdt"`` or ``"triangle"``: ``choice``, else the environment
    variable ``TOOLBOX_TRIANGULATOR``, else ``"cdt"``; ``"auto"`` is Triangle when installed.

    Raises :class:`~toolbox.errors.ToolboxError` for an unknown name, or Triangle asked for but
    not installed (naming the extra that installs it).
    """
    name = (choice or os.environ.get(TRIANGULATOR_ENV) or "cdt").strip().lower()
    if name not in TRIANGULATORS:
        raise ToolboxError(f"{TRIANGULATOR_ENV} must be one of {', '.join(TRIANGULATORS)}, got "
                           f"{name!r}")
    if name == "cdt":
        return name
    try:
        import triangle  # noqa: F401
    except ImportError:
        if name == "auto":
            return "cdt"
        raise ToolboxError("the 'triangle' triangulator is not installed: pip install "
                           "'photogrammetry-toolbox[triangle]' (non-commercial licence), or use "
                           f"{TRIANGULATOR_ENV}=cdt (the default)") from None
    return "triangle"


def triangulate_pslg(xy: np.ndarray, segments: np.ndarray | None = None,
                     neighbors: bool = True, parents: bool = True,
                     triangulator: str | None = None) -> Triangulation:
    """Delaunay triangulation of points, constrained by segments when given (convex hull).

    Parameters
    ----------
    xy : (N, 2) float array
        Map coordinates; distinct in XY (merge duplicates first with
        :func:`toolbox.terrain.points.merge_duplicate_xy`). Shifted to a local origin here.
    segments : (M, 2) int array, optional
        Vertex-index pairs that must be triangle edges. Crossing segments are split at their
        intersection, which becomes a new vertex (see :attr:`Triangulation.vertices`).
        Zero-length segments (both ends the same vertex) are ignored.
    neighbors : bool
        Also return the triangle neighbours; otherwise :attr:`Triangulation.neighbors` is an
        empty ``(0, 3)`` array.
    parents : bool
        Trace each output constrained edge back to its input segment
        (:attr:`Triangulation.segments`, :attr:`Triangulation.segment_parents`); otherwise both
        are empty.
    triangulator : {"cdt", "triangle", "auto"}, optional
        The library (see the module docstring); default from ``TOOLBOX_TRIANGULATOR``, else CDT.

    Returns
    -------
    Triangulation

    Raises
    ------
    ValueError
        Fewer than 3 points, NaN coordinates, all points collinear, points duplicated in XY,
        or malformed segments.
    """
    xy = _check_xy(xy)
    n = len(xy)
    origin = _origin_of(xy)
    local = np.ascontiguousarray(xy - origin)
    seg = np.zeros((0, 2), dtype=np.int32) if segments is None else _check_segments(segments, n)
    seg_index = np.flatnonzero(seg[:, 0] != seg[:, 1])
    run = _cdt if triangulator_name(triangulator) == "cdt" else _triangle
    try:
        added, triangles, nb, out_seg, owners = run(local, seg[seg_index], neighbors, parents)
    except _DuplicatePoint as dup:
        _raise_duplicates(xy, np.array([dup.index]))
    if len(triangles) == 0:
        raise ValueError(f"the {n} points are collinear (or all coincide): no triangle can be "
                         "formed")
    if not _uses_every_vertex(triangles, nb, n + len(added)):
        used = np.zeros(n + len(added), dtype=bool)
        used[triangles.ravel()] = True
        if not used[:n].all():
            _raise_duplicates(xy, np.flatnonzero(~used[:n]))
    vertices = xy if len(added) == 0 else np.vstack([xy, added + origin])
    out_parents = np.where(owners >= 0, seg_index[np.maximum(owners, 0)], -1) if len(owners) \
        else np.zeros(0, dtype=np.int64)
    return Triangulation(vertices, triangles, nb, out_seg, out_parents.astype(np.int64), n)


def _uses_every_vertex(triangles: np.ndarray, neighbors: np.ndarray, count: int) -> bool:
    """True when the triangles certainly use all ``count`` vertices, by Euler's formula: ``T``
    triangles covering a region without holes (a triangulation of the points' convex hull)
    with ``h`` border edges (the -1 neighbours) have ``(T + h + 2) / 2`` vertices. False when
    that is not ``count``, or without neighbours: then the caller looks at every vertex (a
    scatter of the ``(T, 3)`` indices, 0.03 s for a million points)."""
    if len(neighbors) != len(triangles):
        return False
    border = int(np.count_nonzero(neighbors < 0))
    return len(triangles) + border + 2 == 2 * count


class _DuplicatePoint(Exception):
    def __init__(self, index: int):
        super().__init__(index)
        self.index = index


def _raise_duplicates(xy: np.ndarray, missing: np.ndarray) -> None:
    first = int(missing[0])
    raise ValueError(f"points are duplicated in XY and cannot all be triangulated ({len(missing)}"
                     f" found, first index {first} at x={xy[first, 0]:.4f}, "
                     f"y={xy[first, 1]:.4f}); merge duplicates first")


_NO_SEGMENTS = (np.zeros((0, 2), dtype=np.int32), np.zeros(0, dtype=np.int64))


def _cdt(local: np.ndarray, seg: np.ndarray, neighbors: bool, parents: bool):
    """pythoncdt: returns added vertices (local), triangles, neighbours, constrained pieces and
    the index (into ``seg``) of each piece's input segment.

    From :data:`MEMORY_ORDER_MIN_POINTS` points on, the points go to CDT in Z-order
    (:func:`_memory_order`), the segments' vertices kept at their own index: CDT walks each
    constraint from its lower-numbered end, so the walks are the same as long as every edge it
    inserts joins segment vertices or crossings, i.e. no other point lies on a segment; where
    one does (an end of a constrained edge is a moved point), or CDT fails, the run is redone
    with the points as given. The triangles are then the very arrays of a run without the
    ordering (renumbered back). Where shared coordinates may change CDT's insertion sequence,
    the ordered run is kept only if its triangulation is the unique one (no added crossing
    vertex, no edge whose four points may lie on one circle: :func:`cocircular_edge_count`): the
    same triangles as the run as given, possibly listed in another order and from another
    corner."""
    import pythoncdt as cdt

    order, exact = _memory_order(local, seg.ravel())
    if order is not None:
        pinned = None
        if len(seg):
            pinned = np.zeros(len(local), dtype=bool)
            pinned[seg.ravel()] = True
            moved = order[~pinned[order]]
            order = np.arange(len(local), dtype=np.int32)
            order[~pinned] = moved
        try:
            result = _cdt_run(cdt, local, seg, neighbors, parents, order, pinned,
                              unique_only=not exact)
        except (RuntimeError, ValueError, _DuplicatePoint):
            result = None  # the run as given says what is wrong, in the input's numbering
        if result is not None:
            return result
    return _cdt_run(cdt, local, seg, neighbors, parents)


def _cdt_run(cdt, local: np.ndarray, seg: np.ndarray, neighbors: bool, parents: bool,
             order: np.ndarray | None = None, pinned: np.ndarray | None = None,
             unique_only: bool = False):
    """One CDT run for :func:`_cdt`, the points given in ``order`` (point ``order[i]`` is CDT's
    ``i``; the segment vertices, ``pinned``, keep their index); None when a moved point lies
    on a segment, or, with ``unique_only``, when the triangulation may not be the only one."""
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO,
                          cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
    try:
        t.insert_vertices(local if order is None else np.take(local, order, axis=0))
        if len(seg):
            t.insert_edges(np.ascontiguousarray(seg, dtype=np.uintc))
    except RuntimeError as exc:  # CDT reports duplicates as "#i is a duplicate of #j"
        text = str(exc).splitlines()[0]
        found = re.search(r"#(\d+) is a duplicate", text)
        if found:
            raise _DuplicatePoint(int(found.group(1))) from None
        raise ValueError(f"triangulation failed: {text}") from None
    n = len(local)
    fixed = None
    if len(seg) and (parents or (pinned is not None and t.piece_to_originals_count())):
        fixed = _edge_array(t.fixed_edges, t.fixed_edges_count())
        if pinned is not None:
            ends = fixed.ravel() - SUPER
            ends = ends[ends < n]
            if not pinned[ends].all():
                return None
    vertices = t.vertices_array(copy=False)
    tris = t.triangles_array(copy=False)
    if unique_only and (len(vertices) > SUPER + n or cocircular_edge_count(
            vertices.view(np.float64).reshape(-1, 2), tris.view(np.uint32).reshape(-1, 6))):
        return None  # a crossing vertex (numbered as it comes), or maybe not the only CDT
    added = np.column_stack([vertices["x"][SUPER + n:], vertices["y"][SUPER + n:]])
    renumber = None
    if order is not None:  # CDT's vertex SUPER + i is point order[i]; crossings as they come
        renumber = np.concatenate([np.zeros(SUPER, np.int32), order,
                                   np.arange(n, n + len(added), dtype=np.int32)])
    from toolbox.aot import compiled_kernel

    compiled = compiled_kernel("cdt_tables") if neighbors and tris.flags.c_contiguous else None
    if compiled is not None:  # both in one compiled pass (the numpy steps below: its oracle)
        triangles, nb = compiled(tris.view(np.uint32).reshape(-1, 6),
                                 _NO_RENUMBER if renumber is None else renumber, SUPER)
    else:
        triangles, kept = _drop_super_triangle(tris["vertices"], renumber)
        if neighbors:  # CDT: neighbour i is across edge (i, i+1); ours: across the edge facing i
            nb = _kept_neighbours(tris["neighbors"], kept, cdt.NO_NEIGHBOR)
        else:
            nb = np.zeros((0, 3), dtype=np.int32)
    if not (parents and len(seg)):
        return added, triangles, nb, *_NO_SEGMENTS
    return (added, triangles, nb, *_cdt_pieces(t, seg, fixed))


#: from this many points on, :func:`_memory_order` pays for itself (at 200 k points it about
#: breaks even: the triangulation's arrays fit the CPU caches)
MEMORY_ORDER_MIN_POINTS = 250_000


def cocircular_edge_count(xy: np.ndarray, triangles: np.ndarray) -> int:
    """:func:`toolbox.terrain.tin.unique_kernel.cocircular_edges` (see there: 0 means the
    triangulation is the only Delaunay one of its points), by its ahead-of-time build when this
    machine has one (:mod:`toolbox.aot`: numba is not imported), else by numba's JIT."""
    from toolbox.aot import compiled_kernel

    xy = np.ascontiguousarray(xy, dtype=np.float64)
    triangles = np.ascontiguousarray(triangles, dtype=np.uint32)
    compiled = compiled_kernel("cocircular_edges")
    if compiled is None:
        from toolbox.terrain.tin.unique_kernel import cocircular_edges

        return int(cocircular_edges(xy, triangles))
    return int(compiled(xy, triangles))


def _morton16(q: np.ndarray) -> np.ndarray:
    """Spread the 8 bits of ``q`` (uint16 < 256) to the even bits of a 16-bit Morton code."""
    q = (q | (q << 4)) & 0x0F0F
    q = (q | (q << 2)) & 0x3333
    return (q | (q << 1)) & 0x5555


def _memory_order(local: np.ndarray, probe: np.ndarray | None = None
                  ) -> tuple[np.ndarray | None, bool]:
    """Points in Z-order of a 256 x 256 grid (int32 permutation), to pass to CDT in that order,
    or None to pass them as given; and whether CDT's insertion sequence is then certainly the
    same (``exact``).

    CDT inserts the points in the order of its k-d tree (a breadth-first walk of median splits
    in x and y), whatever their order in the array; the array's order only decides where each
    point and its triangles sit in memory. In Z-order, neighbours sit together: 1 M random
    points insert in 0.7 s instead of 1.2 s CPU. The insertion sequence (hence every triangle,
    its order and its neighbours, even where four points lie on one circle) is the same if
    each median split picks the same point, which is certain unless the median's coordinate
    is shared by another point of the range split (then which of them lands at the median
    depends on the array's order): see :func:`_splits_unambiguous`. With many shared
    coordinates or an ambiguous split, the order with ``exact`` False: the caller keeps the
    result only if it is the unique triangulation. Fewer than
    :data:`MEMORY_ORDER_MIN_POINTS` points, or shared coordinates among the first 4096 points
    (grids, rounded coordinates: four points on one circle are likely), None. ``probe``:
    indices of points (the segments' vertices; the first 4096 are looked at) that give
    ``exact`` False at once if two of them share an x or a y, before the full check.
    """
    n = len(local)
    if n < MEMORY_ORDER_MIN_POINTS or _shares_coordinates(local[:4096]):
        return None, True
    exact = probe is None or not len(probe) or not _shares_coordinates(
        local[np.unique(probe[:4096])])
    groups = []
    for axis in range(2 if exact else 0):
        values = np.sort(local[:, axis])
        tied = values[1:][values[1:] == values[:-1]]
        if len(tied) > _MAX_TIED_VALUES:
            exact = False
            break
        groups += [np.flatnonzero(local[:, axis] == v) for v in np.unique(tied)]
    if exact and groups:
        exact = _splits_unambiguous(local, groups)
    low, high = _box(local)
    span = np.maximum(high - low, np.finfo(float).tiny)
    cell = ((local - low) * (255.999 / span)).astype(np.uint16)
    key = _morton16(cell[:, 0]) | (_morton16(cell[:, 1]) << 1)
    return np.argsort(key, kind="stable").astype(np.int32), exact


def _shares_coordinates(sample: np.ndarray) -> bool:
    """True when two of the points share an x or a y."""
    for axis in (0, 1):
        values = np.sort(sample[:, axis])
        if (values[1:] == values[:-1]).any():
            return True
    return False


#: more shared coordinate values than this: the split check gives up (it costs more)
_MAX_TIED_VALUES = 16


def _splits_unambiguous(local: np.ndarray, groups: list[np.ndarray]) -> bool:
    """True when no median split of CDT's k-d tree insertion order meets a shared coordinate.

    ``groups``: indices of points sharing one x (or one y). A split of a range is ambiguous
    only if two points of the range share the median's coordinate, so only ranges holding two
    or more points of a group need checking: this follows them down the tree as CDT builds it
    (``insertVertices_KDTreeBFS``: the points' bounding box; the range's point of rank
    ``len // 2`` along the box's longer side, x on a tie; the lower and upper points go to the
    two halves, the box cut at the median), each split computed from the range's points.
    """
    xy = local
    box0 = (xy[:, 0].min(), xy[:, 1].min(), xy[:, 0].max(), xy[:, 1].max())
    for group in groups:
        if len(group) > 8:
            return False
        stack = [(np.arange(len(xy)), box0)]
        while stack:
            members, box = stack.pop()
            if np.count_nonzero(np.isin(members, group)) < 2:
                continue
            axis = 0 if box[2] - box[0] >= box[3] - box[1] else 1
            values = xy[members, axis]
            median = np.partition(values, len(values) // 2)[len(values) // 2]
            if np.count_nonzero(values == median) > 1:
                return False
            low_box, high_box = list(box), list(box)
            low_box[2 + axis] = median
            high_box[axis] = median
            stack.append((members[values < median], tuple(low_box)))
            stack.append((members[values > median], tuple(high_box)))
    return True


def _edge_array(edges, count: int) -> np.ndarray:
    """(count, 2) int64 array of ``count`` pythoncdt Edges (two attribute reads per edge, in one
    :func:`numpy.fromiter`: no Python tuple or list per edge kept)."""
    pairs = itertools.chain.from_iterable(map(operator.attrgetter("v1", "v2"), edges))
    return np.fromiter(pairs, dtype=np.int64, count=2 * count).reshape(-1, 2)


def _find(table: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Position of each of ``values`` in the sorted, distinct ``table``; -1 when absent."""
    if len(table) == 0:
        return np.full(len(values), -1, dtype=np.int64)
    pos = np.minimum(np.searchsorted(table, values), len(table) - 1)
    return np.where(table[pos] == values, pos, -1)


def _cdt_pieces(t, seg: np.ndarray, fixed: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Constrained edges of CDT ``t`` (in the order of its fixed-edge set) and, for each, the
    index (into ``seg``) of the input segment it comes from: one row per (piece, parent), the
    piece's own segment (the first input segment joining its two nodes, when it is one) first,
    then the input segments CDT split into it, in CDT's order. Lookups on integer edge codes
    in arrays, not Python dicts: the Python loop over the pieces cost 4 s of 8 with 1500
    crossing breaklines (270 k crossings)."""
    count = t.vertices_count()

    def codes(pairs: np.ndarray) -> np.ndarray:
        pairs = np.sort(pairs, axis=1)
        return pairs[:, 0] * count + pairs[:, 1]

    seg_codes, first = np.unique(codes(seg.astype(np.int64) + SUPER), return_index=True)
    if fixed is None:  # (count, 2) CDT vertex pairs, in the order of its fixed-edge set
        fixed = _edge_array(t.fixed_edges, t.fixed_edges_count())
    fixed_codes = codes(fixed)
    at = _find(seg_codes, fixed_codes)
    own = np.where(at >= 0, first[at], -1)
    # (piece, original) pairs streamed from CDT's map: the map as a dict of lists of Edge
    # objects cost three times as much to build and to free
    split = np.fromiter(itertools.chain.from_iterable(
        (e.v1, e.v2, o.v1, o.v2) for e, origs in t.piece_to_originals_iter() for o in origs),
        dtype=np.int64).reshape(-1, 4)
    split_codes = codes(split[:, :2])
    key_codes, key_of_orig, lengths = np.unique(split_codes, return_inverse=True,
                                                return_counts=True)
    # rank of each original in its piece's list (the list of one piece arrives in one run)
    starts = np.ones(len(split), dtype=bool)
    starts[1:] = split_codes[1:] != split_codes[:-1]
    index = np.arange(len(split))
    rank = index - np.maximum.accumulate(np.where(starts, index, 0))
    at = _find(seg_codes, codes(split[:, 2:]))
    if (at < 0).any():
        raise RuntimeError("internal: CDT split an edge that is no input segment")
    orig_index = first[at]
    key_of_fixed = _find(key_codes, fixed_codes)  # -1: not a piece of a split input segment
    fixed_of_key = np.full(len(key_codes), -1, dtype=np.int64)
    fixed_of_key[key_of_fixed[key_of_fixed >= 0]] = np.flatnonzero(key_of_fixed >= 0)
    fixed_of_orig = fixed_of_key[key_of_orig]  # the fixed edge each original goes to
    used = fixed_of_orig >= 0
    fixed_of_orig, orig_index, rank = fixed_of_orig[used], orig_index[used], rank[used]
    duplicate = np.zeros(len(fixed), dtype=bool)  # its own segment is also among its originals
    duplicate[fixed_of_orig[orig_index == own[fixed_of_orig]]] = True
    add = (own >= 0) & ~duplicate
    rows = add.astype(np.int64)
    rows[key_of_fixed >= 0] += lengths[key_of_fixed[key_of_fixed >= 0]]
    offset = np.cumsum(rows) - rows
    owners = np.empty(int(rows.sum()), dtype=np.int64)
    owners[offset[add]] = own[add]
    owners[offset[fixed_of_orig] + add[fixed_of_orig] + rank] = orig_index
    pieces = np.repeat(fixed - SUPER, rows, axis=0).astype(np.int32)
    return pieces, owners


#: CDT's first vertices are those of its super-triangle (it encloses the points)
SUPER = 3
_NO_RENUMBER = np.zeros(0, np.int32)  # the compiled cdt_tables' "v - SUPER"


def _drop_super_triangle(vertices: np.ndarray, renumber: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """CDT's triangles without those touching the super-triangle, renumbered to the input
    points (int32; CDT's vertex ``v`` is ``renumber[v]`` when given, else ``v - SUPER``), and
    the mask of kept rows. What ``erase_super_triangle`` does (same triangles, same order)
    without its hash sets, which cost a third of the triangulation."""
    low = np.minimum(vertices[:, 0], vertices[:, 1])
    kept = np.minimum(low, vertices[:, 2], out=low) >= SUPER
    del low
    triangles = vertices[kept]  # a copy: CDT's memory goes with its object
    if renumber is not None:  # in place, by slices: no second (T, 3) array, no int64 copy
        triangles = triangles.view(np.int32)
        flat = triangles.reshape(-1)
        for start in range(0, len(flat), 1 << 20):
            flat[start:start + (1 << 20)] = renumber[flat[start:start + (1 << 20)]]
        return triangles, kept
    triangles -= SUPER
    return triangles.view(np.int32), kept  # indices < 2**31


def _kept_neighbours(raw: np.ndarray, kept: np.ndarray, none: int) -> np.ndarray:
    """CDT's neighbour indices ``raw`` (``(T, 3)``, neighbour ``i`` across the edge from corner
    ``i`` to corner ``i + 1``; ``none``: no neighbour) renumbered to the kept triangles, in our
    convention (the neighbour across the edge facing each corner: CDT's columns 1, 2, 0), int32;
    -1 across the hull (where the neighbour was a super-triangle one).

    One lookup table, the last slot (-1) for "none" (an index clipped to it: CDT's ``none`` is
    the largest index), read column by column: no ``(T, 3)`` int64 or mask temporaries (they
    took 0.1 s of a million points' 1.5 s, and up to 1 s more in page faults on a first run)."""
    t_all, count = len(kept), int(np.count_nonzero(kept))
    if int(none) < t_all:  # "none" must clip to the last slot
        raise ValueError(f"internal: CDT's no-neighbour value {none} is a triangle index")
    new_index = np.full(t_all + 1, -1, dtype=np.int32)
    new_index[:t_all][kept] = np.arange(count, dtype=np.int32)
    out = np.empty((count, 3), dtype=np.int32)
    for j in range(3):
        np.take(new_index, raw[:, (j + 1) % 3][kept], mode="clip", out=out[:, j])
    return out


def _triangle(local: np.ndarray, seg: np.ndarray, neighbors: bool, parents: bool):
    """Shewchuk's Triangle (``-pc`` with segments): same returns as :func:`_cdt`."""
    import triangle

    tri_in: dict[str, np.ndarray] = {"vertices": local}
    opts = ""
    if len(seg):
        tri_in["segments"] = np.ascontiguousarray(seg)
        if parents:
            # markers identify the parent segment of each output subsegment; 0/1 are Triangle's
            tri_in["segment_markers"] = (np.arange(len(seg), dtype=np.int32) + 2).reshape(-1, 1)
        opts = "pc"
    if neighbors:
        opts += "n"
    out = triangle.triangulate(tri_in, opts)
    triangles = out.get("triangles")
    if triangles is None or len(triangles) == 0:
        return np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int32), None, *_NO_SEGMENTS
    triangles = np.ascontiguousarray(triangles, dtype=np.int32)
    added = np.asarray(out["vertices"])[len(local):]
    nb = np.ascontiguousarray(out["neighbors"], dtype=np.int32) if neighbors else \
        np.zeros((0, 3), dtype=np.int32)
    if not (parents and len(seg)):
        return added, triangles, nb, *_NO_SEGMENTS
    out_seg = np.asarray(out["segments"], dtype=np.int32).reshape(-1, 2)
    markers = np.asarray(out["segment_markers"], dtype=np.int64).ravel()
    owners = np.where(markers >= 2, markers - 2, -1)
    return added, triangles, nb, out_seg, owners


def crossing_heights(tri: Triangulation, seg_xyz: np.ndarray, seg_nodes: np.ndarray,
                     priority: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Z of the vertices the triangulator added at segment crossings, interpolated along each parent
    segment; among parents, those with the highest ``priority`` count (mean of them; all
    parents when ``priority`` is None).

    Returns the heights (one per added vertex) and the disagreement between parents of the same
    priority (max - min of their heights there).
    """
    n, extra = tri.n_input, tri.steiner_count
    sub = tri.segments[tri.segment_parents >= 0]
    parent = tri.segment_parents[tri.segment_parents >= 0]
    ends = np.concatenate([sub[:, 0], sub[:, 1]])
    parents = np.concatenate([parent, parent])
    sel = ends >= n
    vertex, parents = ends[sel] - n, parents[sel]
    a = seg_xyz[seg_nodes[parents, 0]]
    b = seg_xyz[seg_nodes[parents, 1]]
    p = tri.vertices[n + vertex]
    d = b[:, :2] - a[:, :2]
    t = np.clip(np.einsum("ij,ij->i", p - a[:, :2], d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    z = a[:, 2] + t * (b[:, 2] - a[:, 2])
    prio = np.zeros(len(parents)) if priority is None else priority[parents]
    best = np.full(extra, -np.inf)
    np.maximum.at(best, vertex, prio)
    top = prio == best[vertex]
    count = np.bincount(vertex[top], minlength=extra)
    if np.any(count == 0):
        raise ValueError("internal: a crossing vertex lies on no input segment")
    heights = np.bincount(vertex[top], weights=z[top], minlength=extra) / count
    zmin = np.full(extra, np.inf)
    zmax = np.full(extra, -np.inf)
    np.minimum.at(zmin, vertex[top], z[top])
    np.maximum.at(zmax, vertex[top], z[top])
    return heights, zmax - zmin


def triangulate(xy: np.ndarray, segments: np.ndarray | None = None,
                triangulator: str | None = None) -> np.ndarray:
    """Delaunay triangulation of points (constrained Delaunay when ``segments`` is given).

    Parameters
    ----------
    xy : (N, 2) float array
        Map coordinates, distinct in XY (merge duplicates beforehand with
        :func:`toolbox.terrain.points.merge_duplicate_xy`); shifted to a local origin here.
    segments : (M, 2) int array, optional
        Vertex-index pairs that must be triangle edges (breaklines). They must not cross each
        other away from their vertices: a crossing would need a new vertex, which this function
        refuses (:func:`triangulate_pslg` accepts it and returns the new vertices).
    triangulator : {"cdt", "triangle", "auto"}, optional
        See :func:`triangulator_name`.

    Returns
    -------
    (T, 3) int32
        Vertex indices of each triangle, counter-clockwise. Every input point is a node.

    Raises
    ------
    ValueError
        Fewer than 3 points, collinear points, duplicated XY, malformed or crossing segments.

    Examples
    --------
    >>> import numpy as np
    >>> tri = triangulate(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    >>> tri.shape
    (2, 3)
    """
    result = triangulate_pslg(xy, segments, neighbors=False, parents=False,
                              triangulator=triangulator)
    if result.steiner_count:
        raise CrossingSegmentsError(f"segments cross each other away from their vertices "
                         f"({result.steiner_count} crossing points); split them at the crossings "
                         "first (tin:delaunay does this, interpolating Z)")
    return result.triangles


# -- plane values at cell centres and at points ---------------------------------------------------
def rasterize_tin(xyz: np.ndarray, triangles: np.ndarray, x0: float, y0: float, cell_x: float,
                  cell_y: float, width: int, height: int, compiled: bool = True,
                  magnitude: float = 0.0) -> np.ndarray:
    """Plane value of the containing triangle at every cell centre of a north-up grid.

    Parameters
    ----------
    xyz : (N, 3) float array
        Node coordinates (map units; z in height units).
    triangles : (T, 3) int array
        Triangles to draw (indices into ``xyz``); for a tile, pass only the triangles that touch
        it (see :func:`triangles_by_tile`) so work and memory stay bounded.
    x0, y0 : float
        Top-left corner of the grid (or window), map units.
    cell_x, cell_y : float
        Cell width and height, > 0. Cell ``(r, c)`` has its centre at
        ``(x0 + (c + 0.5) * cell_x, y0 - (r + 0.5) * cell_y)``.
    width, height : int
        Grid size in columns and rows.
    compiled : bool
        The numba kernel (default), or its numpy twin (:mod:`toolbox.terrain.tin.planes_numpy`:
        the same values, no numba import; for small rasters).
    magnitude : float
        Size of the map coordinates ``xyz`` and ``x0, y0`` were taken from when they are local
        (e.g. 5,000,000): a node within their rounding of a cell centre is on it
        (:func:`toolbox.io.grid.cell_slack`), so a TIN of points on the grid's lattice covers
        its border cells (a centre on the hull was lost to a 4e-16-cell rounding).

    Returns
    -------
    (height, width) float64
        ``z`` of the plane through the containing triangle (thesis eq. [43]-[44]), exactly, with
        no smoothing; NaN where the centre lies in no triangle. A centre on an edge or a node gets
        the (equal) value of either triangle.
    """
    from toolbox.io.grid import cell_slack

    if not (cell_x > 0 and cell_y > 0):
        raise ValueError(f"cell_x and cell_y must be > 0, got {cell_x}, {cell_y}")
    width, height = int(width), int(height)
    if width < 0 or height < 0:
        raise ValueError(f"width and height must be >= 0, got {width}, {height}")
    out = np.full((height, width), np.nan)
    tri = np.asarray(triangles)
    if len(tri) and width and height:
        if compiled:
            from toolbox.terrain.tin.planes import rasterize
        else:
            from toolbox.terrain.tin.planes_numpy import rasterize
        xyz = np.ascontiguousarray(xyz, dtype="float64")
        far = float(np.abs(xyz[:, :2]).max()) if len(xyz) else 0.0
        snap = cell_slack(min(cell_x, cell_y), magnitude, x0, y0, far)
        rasterize(xyz, np.ascontiguousarray(tri, dtype=np.int64), float(x0), float(y0),
                  float(cell_x), float(cell_y), width, height, out, snap)
    return out


def interpolate_tin(xyz: np.ndarray, triangles: np.ndarray, qx: np.ndarray, qy: np.ndarray,
                    tolerance: float = 0.0, origin: tuple[float, float] | None = None
                    ) -> np.ndarray:
    """Height of the TIN surface at query points: the plane of the containing triangle.

    Parameters
    ----------
    xyz : (N, 3) float array
        Node coordinates.
    triangles : (T, 3) int array
        Triangles (indices into ``xyz``).
    qx, qy : (Q,) float arrays
        Query coordinates, map units.
    tolerance : float, optional
        Points outside every triangle but within this planimetric distance of the TIN's outer
        edge take the value at the nearest point of that edge (for points that should lie on
        the border but miss it by rounding). 0 (default): outside is NaN.
    origin : (x, y), optional
        The origin the planes are computed from (default: a round point of the nodes' box).

    Returns
    -------
    (Q,) float64
        Plane value (thesis eq. [43]-[44]); NaN outside the TIN. A point on an edge or node gets
        the (equal) value of either triangle.
    """
    from toolbox.terrain.tin.planes import PointBuckets, locate, snap_to_edges

    qx = np.asarray(qx, dtype="float64").ravel()
    qy = np.asarray(qy, dtype="float64").ravel()
    if qx.shape != qy.shape:
        raise ValueError(f"qx and qy must have the same length, got {qx.shape} and {qy.shape}")
    out = np.full(qx.shape, np.nan)
    tri = np.ascontiguousarray(triangles, dtype=np.int64)
    xyz = np.ascontiguousarray(xyz, dtype="float64")
    finite = np.isfinite(qx) & np.isfinite(qy)
    if not len(tri) or not finite.any():
        return out
    used = np.zeros(len(xyz), dtype=bool)
    used[tri.ravel()] = True
    origin = _origin_of(xyz[used, :2]) if origin is None else origin
    ox, oy = float(origin[0]), float(origin[1])
    lx, ly = qx - ox, qy - oy
    vx, vy = xyz[used, 0] - ox, xyz[used, 1] - oy
    box = (float(vx.min()), float(vy.min()), float(vx.max()), float(vy.max()))
    span = max(box[2] - box[0], box[3] - box[1], 1e-300)
    # about one triangle per bucket, and no more buckets than the points need
    size = span / max(1.0, np.sqrt(min(len(tri), 4 * len(qx) + 16)))
    sel = np.flatnonzero(finite & (lx >= box[0]) & (lx <= box[2]) & (ly >= box[1])
                         & (ly <= box[3]))
    grid = PointBuckets(lx[sel], ly[sel], box[0], box[1], box[2], box[3], size)
    sub_out = np.full(len(sel), np.nan)
    locate(xyz, tri, ox, oy, grid.x, grid.y, grid.bu, grid.bv, grid.scale, grid.nx, grid.ny,
           grid.start, sub_out, np.zeros(len(sel), dtype=bool))
    out[sel[grid.order]] = sub_out
    if tolerance > 0:
        pad = float(tolerance)
        sel = np.flatnonzero(finite & np.isnan(out) & (lx >= box[0] - pad) & (lx <= box[2] + pad)
                             & (ly >= box[1] - pad) & (ly <= box[3] + pad))
        if len(sel):
            from toolbox.terrain.tin.topology import hull_edges

            grid = PointBuckets(lx[sel], ly[sel], box[0] - pad, box[1] - pad, box[2] + pad,
                                box[3] + pad, max(size, pad))
            sub_out = np.full(len(sel), np.nan)
            snap_to_edges(xyz, np.ascontiguousarray(hull_edges(tri), dtype=np.int64), ox, oy,
                          grid.x, grid.y, grid.bu, grid.bv, grid.scale, grid.nx, grid.ny,
                          grid.start, pad, sub_out, np.zeros(len(sel), dtype=bool))
            out[sel[grid.order]] = sub_out
    return out


# -- tiling ---------------------------------------------------------------------------------------
def triangles_by_tile(xy: np.ndarray, triangles: np.ndarray, x0: float, y0: float,
                      cell_x: float, cell_y: float, width: int, height: int,
                      tile: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Group triangles by the square output tiles their bounding boxes overlap.

    Tiles are ``tile`` x ``tile`` cells, numbered row by row from the top-left (as
    :func:`toolbox.raster.tile.iter_tiles` yields them): tile ``k`` is at tile row ``k // ntx``,
    tile column ``k % ntx``.

    Returns
    -------
    order : (K,) int64
        Triangle indices grouped by tile (a triangle overlapping several tiles appears in each).
    start : (ntiles + 1,) int64
        Tile ``k``'s triangles are ``order[start[k]:start[k + 1]]``.
    ntx : int
        Tiles per row.
    """
    xy = np.asarray(xy, dtype="float64")
    tri = np.asarray(triangles)
    ntx = max(1, -(-int(width) // tile))
    nty = max(1, -(-int(height) // tile))
    if len(tri) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(ntx * nty + 1, dtype=np.int64), ntx
    x, y = np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1])
    corners = [np.ascontiguousarray(tri[:, j]) for j in range(3)]
    (xa, xb, xc), (ya, yb, yc) = [x[i] for i in corners], [y[i] for i in corners]
    # cell index range each triangle's box covers (one cell of margin: centres are what count)
    c_lo = np.floor((np.minimum(np.minimum(xa, xb), xc) - x0) / cell_x - 0.5)
    c_hi = np.ceil((np.maximum(np.maximum(xa, xb), xc) - x0) / cell_x - 0.5)
    r_lo = np.floor((y0 - np.maximum(np.maximum(ya, yb), yc)) / cell_y - 0.5)
    r_hi = np.ceil((y0 - np.minimum(np.minimum(ya, yb), yc)) / cell_y - 0.5)
    keep = (c_hi >= 0) & (c_lo <= width - 1) & (r_hi >= 0) & (r_lo <= height - 1)
    idx = np.flatnonzero(keep)
    tx0 = (np.clip(c_lo[idx], 0, width - 1) // tile).astype(np.int64)
    tx1 = (np.clip(c_hi[idx], 0, width - 1) // tile).astype(np.int64)
    ty0 = (np.clip(r_lo[idx], 0, height - 1) // tile).astype(np.int64)
    ty1 = (np.clip(r_hi[idx], 0, height - 1) // tile).astype(np.int64)
    nxs = tx1 - tx0 + 1
    nys = ty1 - ty0 + 1
    counts = nxs * nys
    rep = np.repeat(np.arange(len(idx)), counts)
    offset = np.arange(len(rep)) - np.repeat(np.cumsum(counts) - counts, counts)
    tile_x = tx0[rep] + offset % nxs[rep]
    tile_y = ty0[rep] + offset // nxs[rep]
    key = tile_y * ntx + tile_x
    sort = np.argsort(key, kind="stable")
    order = idx[rep[sort]]
    start = np.searchsorted(key[sort], np.arange(ntx * nty + 1)).astype(np.int64)
    return order, start, ntx
