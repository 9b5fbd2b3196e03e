"""Packed (bulk-loaded) SQLite R-trees: the rows of the three shadow tables of a 2-D ``rtree``
virtual table ``rtree(id, minx, maxx, miny, maxy)`` (a GeoPackage spatial index
``rtree_<table>_<geom>``), built with numpy so that a writer stores them as they are instead of
inserting every box through SQLite's R*-tree code.

The layout is SQLite's own (``ext/rtree/rtree.c``, https://www.sqlite.org/rtree.html):

- ``<name>_node(nodeno INTEGER PRIMARY KEY, data BLOB)``: one row a node, node 1 the root. Every
  blob has the same length, the node size SQLite picks for a new tree from the page size
  (:func:`node_size_for_page`). Bytes 0-1: the depth of the tree (0: the root is a leaf), big-endian,
  on the root only (0 on every other node, as SQLite writes them); bytes 2-3: the cell count; then
  24-byte cells: an 8-byte big-endian id (the rowid in a leaf, the child's node number in an
  interior node) and four big-endian float32 (minx, maxx, miny, maxy); the rest is zero.
- ``<name>_rowid(rowid INTEGER PRIMARY KEY, nodeno)``: the leaf holding each entry.
- ``<name>_parent(nodeno INTEGER PRIMARY KEY, parentnode)``: the parent of each non-root node.

Coordinates are rounded to float32 outward exactly as SQLite does when a row is inserted through
SQL (:func:`rtree_round_down`, :func:`rtree_round_up`), so a box reads back with the values SQLite
would have stored, and a query finds the same rows. Boxes are packed Sort-Tile-Recursive: full
nodes (cell counts differing by at most one on a level), tiled in vertical slices whose count
follows the extent's aspect ratio, each slice ordered by y; the levels above are packed the same
way on their children's boxes, each parent box being the float32 union of its children's (so
``rtreecheck`` finds every child inside its parent). SQLite keeps maintaining the tree afterwards
(inserts, deletes and updates through SQL).

Writing the rows straight into pages (a bulk writer): an rtree as SQLite (or GDAL) creates it
holds one row, ``<name>_node`` (1, zeroblob(node size)), and empty ``_rowid`` and ``_parent``; the
root row must be replaced, not kept beside node 1 of these rows. In all three tables the first
column is an INTEGER PRIMARY KEY, i.e. the B-tree's rowid (``node_numbers``, ``rowids``,
``parent_nodes``), stored as NULL in the record; the record's second column is the blob or the
integer. The blobs must have the length of the tree's root as SQLite created it (it reads the node
size from ``length(data)`` of node 1 when it connects): build the rows with the database's
page size.
"""

from __future__ import annotations

import math
import sqlite3
from dataclasses import dataclass

import numpy as np

from toolbox.errors import InputDataError, ParameterError

RTREE_MAXCELLS = 51
"""The most cells SQLite puts in a node (``RTREE_MAXCELLS`` in ``rtree.c``)."""
CELL_SIZE = 24
"""Bytes of a 2-D cell: an 8-byte id and four float32."""

# rtree.c's constants for the outward rounding of a double that float32 does not hold exactly
_RNDTOWARDS = 1.0 - 1.0 / 8388608.0
_RNDAWAY = 1.0 + 1.0 / 8388608.0

_CELL = np.dtype([("id", ">i8"), ("box", ">f4", (4,))])  # box: minx, maxx, miny, maxy
_Q_MAX = 4294967295.0  # the largest uint32: centres are quantised to 32 bits for sorting


@dataclass(frozen=True)
class RtreeRows:
    """The content of an R-tree's three shadow tables, as numpy arrays.

    Attributes
    ----------
    node_numbers : int64 (m,)
        ``<name>_node.nodeno``, ascending; 1 is the root.
    node_blobs : uint8 (m, node_size)
        ``<name>_node.data`` of each node.
    rowids : int64 (n,)
        ``<name>_rowid.rowid``, ascending.
    rowid_nodes : int32 (n,) (int64 beyond 2**31 - 1 nodes)
        ``<name>_rowid.nodeno``: the leaf node of each rowid.
    parent_nodes : int64 (m - 1,)
        ``<name>_parent.nodeno``, ascending (every node but the root).
    parents : int32 (m - 1,) (as ``rowid_nodes``)
        ``<name>_parent.parentnode`` of each.
    depth : int
        The tree's depth (bytes 0-1 of the root): 0 when the root is a leaf.
    node_size : int
        The length of every blob.
    """

    node_numbers: np.ndarray
    node_blobs: np.ndarray
    rowids: np.ndarray
    rowid_nodes: np.ndarray
    parent_nodes: np.ndarray
    parents: np.ndarray
    depth: int
    node_size: int


def node_size_for_page(page_size: int) -> int:
    """The node (blob) size SQLite gives a new R-tree in a database of ``page_size`` bytes a page:
    ``page_size - 64``, capped at ``4 + 24 * RTREE_MAXCELLS`` (1228 bytes) for a 2-D tree.

    >>> node_size_for_page(4096), node_size_for_page(1024), node_size_for_page(512)
    (1228, 960, 448)
    """
    if (isinstance(page_size, bool) or not isinstance(page_size, (int, np.integer))
            or page_size < 512 or page_size > 65536 or page_size & (page_size - 1)):
        raise ParameterError("page_size", f"is {page_size!r}: expected an SQLite page size, a "
                             "power of two from 512 to 65536")
    return min(int(page_size) - 64, 4 + CELL_SIZE * RTREE_MAXCELLS)


def rtree_round_down(values: np.ndarray) -> np.ndarray:
    """float64 -> float32 as SQLite's rtree stores a box's lower bound (``rtreeValueDown``): the
    nearest float32 if it is not above the value, else the float32 nearest to the value scaled
    by 1 -/+ 2**-23 towards minus infinity: not always the next float32 below (0.1 goes two
    float32 steps down, as SQLite stores it).

    >>> rtree_round_down(np.array([0.1, -0.1, 1.5])).tolist()
    [0.09999998658895493, -0.10000000149011612, 1.5]
    """
    return _round(np.asarray(values, dtype=np.float64), down=True)


def rtree_round_up(values: np.ndarray) -> np.ndarray:
    """float64 -> float32 as SQLite's rtree stores a box's upper bound (``rtreeValueUp``), the
    mirror of :func:`rtree_round_down`.

    >>> rtree_round_up(np.array([0.1, -0.1, 1.5])).tolist()
    [0.10000000149011612, -0.09999998658895493, 1.5]
    """
    return _round(np.asarray(values, dtype=np.float64), down=False)


def _round(d: np.ndarray, down: bool) -> np.ndarray:
    with np.errstate(over="ignore"):  # beyond float32's range: +-inf, as the C cast gives
        f = d.astype(np.float32)
        wrong = f > d if down else f < d
        idx = np.flatnonzero(wrong)
        if idx.size:
            dv = d[idx]
            away = (dv < 0) if down else (dv >= 0)
            f[idx] = (dv * np.where(away, _RNDAWAY, _RNDTOWARDS)).astype(np.float32)
    return f


def _as_coordinate(values, name: str, n: int) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape != (n,):
        raise ParameterError(name, f"has shape {arr.shape}: expected ({n},) like ids")
    if not np.isfinite(arr).all():
        where = np.flatnonzero(~np.isfinite(arr))
        raise InputDataError(f"{name}: {where.size} value(s) are NaN or infinite (first at index "
                             f"{where[0]}: {arr[where[0]]}); drop empty geometries first")
    return arr


def _check_order(lo: np.ndarray, hi: np.ndarray, names: str) -> None:
    bad = lo > hi
    if bad.any():
        where = np.flatnonzero(bad)
        i = where[0]
        raise InputDataError(f"{names}: {where.size} box(es) have min > max (first at index {i}: "
                             f"{lo[i]!r} > {hi[i]!r}); expected min <= max")


def _quantise(c: np.ndarray) -> np.ndarray:
    """Centres -> uint32 on a linear scale over their range (ties only cost packing quality;
    an infinite or NaN range gives all zeros: any order makes a valid tree)."""
    lo = float(c.min())
    with np.errstate(over="ignore", invalid="ignore"):
        span = float(c.max()) - lo
    if not span > 0 or not math.isfinite(span):
        return np.zeros(c.shape, np.uint32)
    out = np.empty(c.shape, np.uint32)
    for a in range(0, c.size, 1 << 20):  # in float64 by chunks: no (n,) float64 temporary
        t = c[a:a + (1 << 20)].astype(np.float64) - lo
        t *= _Q_MAX / span
        np.clip(t, 0.0, _Q_MAX, out=t)
        out[a:a + t.size] = t
    return out


def _radix_argsort(key: np.ndarray, nbits: int) -> np.ndarray:
    """A stable argsort of unsigned ``key`` (its low ``nbits`` bits) by LSD radix passes of 16
    bits: numpy sorts uint16 with a counting sort, far faster than a comparison sort."""
    perm = None
    for shift in range(0, nbits, 16):
        digit = (key >> key.dtype.type(shift)).astype(np.uint16)
        if perm is not None:
            digit = digit.take(perm)
        if digit.size and digit.min() == digit.max():
            if perm is None:
                perm = np.arange(key.size)
            continue
        o = np.argsort(digit, kind="stable")
        perm = o if perm is None else perm.take(o)
        if perm.dtype != np.int32 and key.size < 2**31:
            perm = perm.astype(np.int32)  # half the memory of the next pass's gathers
        del o
    return np.arange(key.size) if perm is None else perm


def _node_starts(nodes: np.ndarray, q: int, r: int) -> np.ndarray:
    """First item of each node: ``r`` nodes of ``q + 1`` items, then nodes of ``q``."""
    return nodes * q + np.minimum(nodes, r)


def _slice_ids(qx: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """The STR slice of every item, in input order: slice ``t`` holds the items of x rank
    ``bounds[t]`` to ``bounds[t + 1] - 1`` (ties of ``qx`` in input order). Counted, not sorted:
    a histogram of the high 16 bits of ``qx`` places most items; only the items of the buckets a
    slice boundary cuts are ranked exactly (by a sort of those alone)."""
    high = (qx >> np.uint32(16)).astype(np.uint16)  # 2 bytes an item, not 8
    counts = np.bincount(high, minlength=65536)
    start = np.zeros(counts.size + 1, np.int64)
    np.cumsum(counts, out=start[1:])
    first = np.searchsorted(bounds, start[:-1], "right") - 1
    last = np.searchsorted(bounds, start[1:] - 1, "right") - 1
    slice_ids = first.astype(np.int32).take(high)
    cut = (first != last) & (counts > 0)
    if cut.any():
        members = np.flatnonzero(cut.take(high))
        members = members.take(_radix_argsort(qx.take(members), 32))  # by x, stable
        bucket = high.take(members)  # ascending
        rank = start.take(bucket) + np.arange(members.size) - np.searchsorted(bucket, bucket)
        slice_ids[members] = np.searchsorted(bounds, rank, "right") - 1
    return slice_ids


def _pack_order(cx: np.ndarray, cy: np.ndarray, n_nodes: int, q: int, r: int) -> np.ndarray:
    """Sort-Tile-Recursive order of ``k`` items into ``n_nodes`` consecutive nodes: slices in x
    made of whole nodes (their count from the aspect ratio of the centres' extent, for square
    nodes), each slice ordered by y."""
    k = cx.size
    with np.errstate(over="ignore", invalid="ignore"):  # inf/NaN extents: see below
        w = float(cx.max()) - float(cx.min())
        h = float(cy.max()) - float(cy.min())
    if w == 0 and h == 0:
        return np.arange(k)
    if h == 0:
        slices = n_nodes
    else:  # an infinite extent (coordinates beyond float32, stored as inf): any valid tiling
        ratio = math.sqrt(n_nodes * w / h) if w > 0 else 1.0
        slices = min(max(int(round(ratio)), 1), n_nodes) if math.isfinite(ratio) else n_nodes
    per_slice = -(-n_nodes // slices)
    slices = -(-n_nodes // per_slice)
    if slices == 1:
        return _radix_argsort(_quantise(cy), 32)
    if slices == n_nodes:  # one node a slice: the x order is the order
        return _radix_argsort(_quantise(cx), 32)
    bounds = _node_starts(np.arange(slices + 1) * per_slice, q, r)
    bounds[-1] = k
    # sorted by (slice, y): 32-bit keys (48 when the slices need more than 16 bits)
    slice_bits = max(1, int(slices - 1).bit_length())
    total = 32 if slice_bits <= 16 else 48
    y_bits = min(32, total - slice_bits)
    kind = np.uint32 if total == 32 else np.uint64
    key = _slice_ids(_quantise(cx), bounds).astype(kind)
    key <<= kind(y_bits)
    key |= (_quantise(cy) >> np.uint32(32 - y_bits)).astype(kind)
    return _radix_argsort(key, total)


def _fill_nodes(blobs: np.ndarray, cells: np.ndarray, ids: np.ndarray, boxes: np.ndarray, q: int,
                r: int) -> np.ndarray:
    """Write a level's nodes: the first ``r`` get ``q + 1`` of the (packed) items, the others
    ``q``; their cell counts in bytes 2-3. Returns the counts."""
    n_nodes = blobs.shape[0]
    sizes = np.full(n_nodes, q, np.int64)
    sizes[:r] += 1
    blobs[:, 2] = sizes >> 8
    blobs[:, 3] = sizes & 0xFF
    split = r * (q + 1)
    if r:
        cells[:r, :q + 1]["id"] = ids[:split].reshape(r, q + 1)
        cells[:r, :q + 1]["box"] = boxes[:split].reshape(r, q + 1, 4)
    if n_nodes > r and q:
        cells[r:, :q]["id"] = ids[split:].reshape(n_nodes - r, q)
        cells[r:, :q]["box"] = boxes[split:].reshape(n_nodes - r, q, 4)
    return sizes


def packed_rtree(ids, minx, maxx, miny, maxy, page_size: int = 4096) -> RtreeRows:
    """The shadow-table rows of a packed 2-D SQLite R-tree holding the boxes
    ``(minx[i], maxx[i], miny[i], maxy[i])`` under the rowids ``ids[i]``.

    Parameters
    ----------
    ids : int64 (n,)
        Rowids, unique (a GeoPackage: the features' fids).
    minx, maxx, miny, maxy : float64 (n,)
        The boxes, finite, min <= max (zero width allowed). Stored in float32 rounded outward as
        SQLite does on insert.
    page_size : int
        The database's page size, which fixes the node size (:func:`node_size_for_page`).

    Returns
    -------
    RtreeRows

    Raises
    ------
    ParameterError
        Arrays of different shapes, non-integer or duplicate ids, a page size SQLite does not have.
    InputDataError
        A NaN or infinite coordinate, or a box with min > max (both ValueError).

    Examples
    --------
    >>> rows = packed_rtree([7, 3], [0.0, 2.0], [1.0, 2.0], [0.0, 5.0], [1.0, 5.0])
    >>> rows.depth, rows.node_numbers.tolist(), rows.node_blobs.shape
    (0, [1], (1, 1228))
    >>> rows.rowids.tolist(), rows.rowid_nodes.tolist(), rows.parents.size
    ([3, 7], [1, 1], 0)
    >>> bytes(rows.node_blobs[0, :12]).hex()
    '000000020000000000000007'
    """
    node_size = node_size_for_page(page_size)
    ids_in = np.asarray(ids)
    if ids_in.ndim != 1:
        raise ParameterError("ids", f"has shape {ids_in.shape}: expected one dimension (n,)")
    if ids_in.size and not np.issubdtype(ids_in.dtype, np.integer):
        raise ParameterError("ids", f"has dtype {ids_in.dtype}: expected integers (rowids)")
    if ids_in.dtype == np.uint64 and ids_in.size and ids_in.max() > np.iinfo(np.int64).max:
        raise ParameterError("ids", "has values beyond the int64 range of SQLite rowids")
    ids_in = ids_in.astype(np.int64, copy=False)
    n = ids_in.size
    boxes = [_as_coordinate(v, name, n)
             for v, name in ((minx, "minx"), (maxx, "maxx"), (miny, "miny"), (maxy, "maxy"))]
    _check_order(boxes[0], boxes[1], "minx/maxx")
    _check_order(boxes[2], boxes[3], "miny/maxy")

    # the _rowid table: rowids ascending (a GeoPackage's fids usually come sorted)
    if n < 2 or bool((ids_in[1:] > ids_in[:-1]).all()):
        by_id = None
        rowids = ids_in.copy()
    else:
        by_id = np.argsort(ids_in, kind="stable")
        rowids = ids_in[by_id]
        dup = np.flatnonzero(rowids[1:] == rowids[:-1])
        if dup.size:
            raise ParameterError("ids", f"has {dup.size} duplicate value(s) (first {rowids[dup[0]]}):"
                                 " expected unique rowids")

    boxes32 = stored_boxes(*boxes)
    del boxes
    return _packed(ids_in, by_id, rowids, boxes32, node_size)


def stored_boxes(minx, maxx, miny, maxy, out: np.ndarray | None = None) -> np.ndarray:
    """``(n, 4)`` float32 ``[minx, maxx, miny, maxy]`` as SQLite's rtree stores the boxes
    (:func:`rtree_round_down` of the minima, :func:`rtree_round_up` of the maxima), into
    ``out`` when given (a slice of a bigger array)."""
    out = np.empty((len(minx), 4), np.float32) if out is None else out
    for j, (v, down) in enumerate(((minx, True), (maxx, False), (miny, True), (maxy, False))):
        out[:, j] = _round(np.asarray(v, dtype=np.float64), down)
    return out


def packed_rtree_stored(ids: np.ndarray, boxes32: np.ndarray, page_size: int = 4096) -> RtreeRows:
    """:func:`packed_rtree` of boxes already rounded as SQLite stores them: ``boxes32`` is
    ``(n, 4)`` float32 ``[minx, maxx, miny, maxy]`` (:func:`rtree_round_down` of the minima,
    :func:`rtree_round_up` of the maxima), ``ids`` strictly increasing int64 (a layer's fids).
    For big layers: no float64 copy of the boxes and no copy of the ids (a 30 M-feature layer's
    tree is built in about 1 GB less memory). Neither array is changed."""
    node_size = node_size_for_page(page_size)
    ids = np.asarray(ids, dtype=np.int64)
    boxes32 = np.asarray(boxes32)
    if boxes32.dtype != np.float32 or boxes32.shape != (ids.size, 4):
        raise ParameterError("boxes32", f"is {boxes32.dtype} {boxes32.shape}: expected float32 "
                             f"({ids.size}, 4)")
    if ids.size > 1 and not bool((ids[1:] > ids[:-1]).all()):
        raise ParameterError("ids", "must be strictly increasing")
    _check_order(boxes32[:, 0], boxes32[:, 1], "minx/maxx")
    _check_order(boxes32[:, 2], boxes32[:, 3], "miny/maxy")
    return _packed(ids, None, ids, boxes32, node_size)


_CHUNK_NODES = 1 << 14  # nodes filled at a time (their items gathered: bounded memory)


def _packed(ids_in: np.ndarray, by_id, rowids: np.ndarray, boxes32: np.ndarray,
            node_size: int) -> RtreeRows:
    """The tree of ``boxes32`` (stored float32) under ``ids_in`` (``by_id``: the order that sorts
    them, None when sorted; ``rowids`` the sorted ids)."""
    n = ids_in.size
    capacity = (node_size - 4) // CELL_SIZE
    with np.errstate(over="ignore", invalid="ignore"):  # +-inf: only the order matters
        centres = (boxes32[:, 0] + boxes32[:, 1],  # twice the centres, in float32 (4 bytes a box)
                   boxes32[:, 2] + boxes32[:, 3])

    # the nodes of each level, bottom-up (leaves first); the root holds the top level's items
    counts = []
    k = n
    while k > capacity:
        k = -(-k // capacity)
        counts.append(k)
    depth = len(counts)
    counts.append(1)
    m = sum(counts)
    # node numbers: the root 1, then level by level downwards (the leaves last)
    first = [m + 1 - sum(counts[:lvl + 1]) for lvl in range(depth + 1)]
    node_type = np.int32 if m < 2**31 - 1 else np.int64

    blobs = np.zeros((m, node_size), np.uint8)
    cells = np.ndarray(shape=(m, capacity), dtype=_CELL, buffer=blobs, offset=4,
                       strides=(node_size, CELL_SIZE))
    parents = np.empty(m - 1, node_type)
    rowid_nodes = np.empty(0, node_type)
    # ids in input order = ids[0] + position (fids 1..n): no gather needed
    consecutive = by_id is None and n and int(ids_in[-1]) - int(ids_in[0]) == n - 1
    items = boxes32
    for lvl in range(depth + 1):
        k = items.shape[0]
        n_nodes = counts[lvl]
        q, r = divmod(k, n_nodes)
        order = np.arange(k) if lvl == depth else _pack_order(*centres, n_nodes, q, r)
        centres = None  # freed before the level's nodes are filled
        row0 = first[lvl] - 1
        node_of_item = np.empty(k, node_type)
        above = np.empty((n_nodes, 4), np.float32) if lvl < depth else None
        for a in range(0, n_nodes, _CHUNK_NODES):  # a chunk of nodes and their items
            b = min(n_nodes, a + _CHUNK_NODES)
            lo, hi = _node_starts(np.array([a, b]), q, r)
            part = order[lo:hi].astype(np.int64)  # (the radix sort's order may be int32)
            if lvl:  # the items are the nodes of the level below
                cell_ids = first[lvl - 1] + part
            elif consecutive:
                cell_ids = part + int(ids_in[0]) if n else part
            else:
                cell_ids = ids_in.take(part)
            packed = items.take(part, axis=0)
            r_here = max(0, min(r - a, b - a))
            sizes = _fill_nodes(blobs[row0 + a:row0 + b], cells[row0 + a:row0 + b], cell_ids,
                                packed, q, r_here)
            node_of_item[part] = np.repeat(np.arange(first[lvl] + a, first[lvl] + b,
                                                     dtype=node_type), sizes)
            if above is not None:
                # the nodes' boxes (float32 unions of their items') are the items of the level above
                starts = _node_starts(np.arange(b - a), q, r_here)
                for j, reduce in enumerate((np.minimum, np.maximum) * 2):
                    above[a:b, j] = reduce.reduceat(packed[:, j], starts)
        del order
        if lvl == 0:
            rowid_nodes = node_of_item if by_id is None else node_of_item.take(by_id)
        else:
            parents[first[lvl - 1] - 2:first[lvl - 1] - 2 + k] = node_of_item
        del node_of_item
        if above is not None:
            items = above
            with np.errstate(over="ignore", invalid="ignore"):  # -inf + inf: a NaN centre, any
                centres = (items[:, 0] + items[:, 1], items[:, 2] + items[:, 3])  # order is valid
    blobs[0, 0] = depth >> 8
    blobs[0, 1] = depth & 0xFF
    return RtreeRows(node_numbers=np.arange(1, m + 1, dtype=np.int64), node_blobs=blobs,
                     rowids=rowids, rowid_nodes=rowid_nodes,
                     parent_nodes=np.arange(2, m + 1, dtype=np.int64), parents=parents,
                     depth=depth, node_size=node_size)


def _quote(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def insert_rtree_rows(connection: sqlite3.Connection, rtree_name: str, rows: RtreeRows, *,
                      replace: bool = False) -> None:
    """Write ``rows`` into the shadow tables of the existing 2-D rtree ``rtree_name`` through SQL
    (the slow path: a page writer stores the arrays directly).

    The tree must be empty (as created: its root alone, a zero blob), unless ``replace``, which
    discards its content (a GeoPackage layer's index when its triggers are not in play). All
    in one savepoint: on an error nothing is changed.

    Raises
    ------
    ParameterError
        No such rtree, a tree that is not empty without ``replace``, or a node size that is not
        the tree's (a database of another page size).
    """
    q = _quote(rtree_name)
    node_t, parent_t, rowid_t = (_quote(f"{rtree_name}_{s}") for s in ("node", "parent", "rowid"))
    try:
        root = connection.execute(f"SELECT length(data) FROM {node_t} WHERE nodeno = 1").fetchone()
        columns = connection.execute(f"SELECT * FROM {q} LIMIT 0").description
    except sqlite3.OperationalError as exc:
        raise ParameterError("rtree_name", f"is {rtree_name!r}: not an rtree of this database "
                             f"({exc})") from None
    if len(columns) != 5:
        raise ParameterError("rtree_name", f"is {rtree_name!r}: a {len(columns)}-column table, "
                             "expected a 2-D rtree (id, minx, maxx, miny, maxy)")
    if root is None or root[0] != rows.node_size:
        raise ParameterError("rows", f"have {rows.node_size}-byte nodes but the root of "
                             f"{rtree_name!r} has {None if root is None else root[0]}: build them "
                             "with the database's page size")
    if not replace:
        n_rowid = connection.execute(f"SELECT count(*) FROM {rowid_t}").fetchone()[0]
        n_node = connection.execute(f"SELECT count(*) FROM {node_t}").fetchone()[0]
        if n_rowid or n_node != 1:
            raise ParameterError("rtree_name", f"is {rtree_name!r}: the tree holds {n_rowid} "
                                 "entries; pass replace=True to discard them")
    blob_rows = ((int(k), b.tobytes()) for k, b in zip(rows.node_numbers, rows.node_blobs))
    connection.execute("SAVEPOINT insert_rtree_rows")
    try:
        for table in (node_t, parent_t, rowid_t):
            connection.execute(f"DELETE FROM {table}")
        connection.executemany(f"INSERT INTO {node_t} VALUES (?, ?)", blob_rows)
        connection.executemany(f"INSERT INTO {parent_t} VALUES (?, ?)",
                               zip(rows.parent_nodes.tolist(), rows.parents.tolist()))
        connection.executemany(f"INSERT INTO {rowid_t} VALUES (?, ?)",
                               zip(rows.rowids.tolist(), rows.rowid_nodes.tolist()))
    except BaseException:
        connection.execute("ROLLBACK TO insert_rtree_rows")
        connection.execute("RELEASE insert_rtree_rows")
        raise
    connection.execute("RELEASE insert_rtree_rows")
