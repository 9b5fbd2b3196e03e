"""GeoPackage layers of millions of fixed-size features, written in bulk.

GDAL creates each layer empty (its table, spatial index, triggers and metadata rows: the same
GeoPackage as GDAL's own writing); the features then go into the file as SQLite B-tree pages
built with numpy (:mod:`toolbox.io.sqlite_pages`), the spatial index as a packed R-tree
(:mod:`toolbox.io.sqlite_rtree`), and the metadata GDAL keeps about the rows (the extent in
``gpkg_contents``, the count in ``gpkg_ogr_contents``, the ``sqlite_sequence`` row) is set with
SQL. GDAL inserts a feature at a time through SQLite (about 3.5 us a feature with its index);
this writes pages at memory speed. The oracle is GDAL's writer: the same rows, values and types,
and R-tree entries (the tests).

Only what is certain is written this way: a new GeoPackage, geometries given as fixed-size
little-endian ISO WKB records of one type (points, line strings, single-ring polygons), and
integer, real, Boolean and text fields. :class:`BulkUnsupported` says why anything else is not
(the caller then writes with GDAL).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np

from toolbox.aot import compiled_kernel
from toolbox.io.sqlite_pages import BtreeAppender, UnsupportedDatabase, encode_records
from toolbox.io.sqlite_rtree import packed_rtree_stored, stored_boxes

BATCH = 1 << 16  # features encoded at a time

Columns = dict[str, tuple[np.ndarray, "np.ndarray | None"]]


class BulkUnsupported(Exception):
    """The layer or file is not one the bulk writer is sure to write right (the reason)."""


class BulkLayer(Protocol):
    """A layer of ``n`` features made in slices: ``make(lo, hi)`` returns the fields (name ->
    (values, null mask or None), in the layer's order) and the ``(hi - lo, size)`` uint8 ISO WKB
    records of features ``lo:hi``; ``schema()`` the pyarrow schema of the fields and a
    ``geometry`` binary column. ``make`` is called from several threads at once (disjoint
    slices). ``release``, when not None, is called once every slice was made: the layer may
    let its data go (the R-tree is packed after that)."""

    name: str
    n: int
    geometry_type: str
    make: Callable[[int, int], tuple[Columns, np.ndarray]]
    release: Callable[[], None] | None

    def schema(self) -> Any: ...


# -- geometry blobs ----------------------------------------------------------------------------
_NO_BOXES = np.empty((0, 4), np.float32)  # the compiled pass's "no stored boxes"
_WKB_HEADER = {1: 5, 2: 9, 3: 13}  # base type -> bytes before the coordinates (one ring)


def geometry_blobs(wkb: np.ndarray, srs_id: int,
                   stored: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """GeoPackage binary geometries of fixed-size little-endian ISO WKB records ``(n, size)``,
    laid out as GDAL writes them: ``GP``, version 0, flags (little endian; no envelope for a
    point, else ``[minx, maxx, miny, maxy]`` and, with Z, ``[minz, maxz]``), the ``srs_id``,
    then the WKB. Returns the ``(n, size')`` blobs and the ``(n, 4)`` boxes
    ``[minx, maxx, miny, maxy]`` (float64) of the R-tree; ``stored``, when given (``(n, 4)``
    float32), gets the boxes as SQLite stores them (:func:`toolbox.io.sqlite_rtree.stored_boxes`).
    In one compiled pass where :mod:`toolbox.io.blob_kernel` is built, else in numpy steps."""
    wkb = np.ascontiguousarray(wkb, dtype=np.uint8)
    n, size = wkb.shape
    code = int(wkb[0, 1:5].view("<u4")[0]) if n else 0
    base, dims = code % 1000, 3 if code // 1000 == 1 else 2 if code < 1000 else 0
    head = _WKB_HEADER.get(base)
    if n == 0 or head is None or dims == 0 or wkb[0, 0] != 1:
        raise BulkUnsupported(f"WKB type {code} (byte order {wkb[0, 0] if n else '-'})")
    if (size - head) % (8 * dims) or not (wkb[:, :head] == wkb[0, :head]).all():
        raise BulkUnsupported("WKB records of different types or sizes")
    envelope = 0 if base == 1 else 2 * dims  # doubles
    indicator = 0 if base == 1 else dims - 1  # 1: XY, 2: XYZ
    header = b"GP\x00" + bytes([1 | indicator << 1]) + np.int32(srs_id).astype("<i4").tobytes()
    compiled = compiled_kernel("gpkg_blobs")
    if compiled is not None:
        out = np.empty((n, 8 + 8 * envelope + size), dtype=np.uint8)
        boxes = np.empty((n, 4))
        bad = compiled(wkb, head, dims, np.frombuffer(header, np.uint8), envelope, out, boxes,
                       _NO_BOXES if stored is None else stored)
        if bad:
            raise BulkUnsupported("NaN or infinite coordinates")
        return out, boxes
    vertices = wkb[:, head:].view("<f8").reshape(n, -1, dims)  # no copy (unaligned: fine)
    low, high = vertices[:, 0].copy(), vertices[:, 0].copy()
    for j in range(1, vertices.shape[1]):
        np.minimum(low, vertices[:, j], out=low)
        np.maximum(high, vertices[:, j], out=high)
    if not (np.isfinite(low).all() and np.isfinite(high).all()):
        raise BulkUnsupported("NaN or infinite coordinates")
    boxes = np.empty((n, 4))
    boxes[:, 0::2], boxes[:, 1::2] = low[:, :2], high[:, :2]
    if stored is not None:
        stored_boxes(*boxes.T, out=stored)
    out = np.empty((n, 8 + 8 * envelope + size), dtype=np.uint8)
    out[:, :8].view("<u8")[:, 0] = np.frombuffer(header, dtype="<u8")[0]  # one store a row
    if envelope:
        view = out[:, 8:8 + 8 * envelope].view("<f8")
        view[:, 0::2], view[:, 1::2] = low, high  # minx, maxx, miny, maxy(, minz, maxz)
    out[:, 8 + 8 * envelope:] = wkb
    return out, boxes


# -- the table's columns ---------------------------------------------------------------------------
def _kind(declared: str) -> str | None:
    """The record kind of a GeoPackage column type (None: not one written in bulk)."""
    declared = declared.upper()
    if declared in ("INTEGER", "INT", "MEDIUMINT", "SMALLINT", "TINYINT"):
        return "int"
    if declared in ("REAL", "DOUBLE", "FLOAT"):
        return "real"
    if declared == "BOOLEAN":
        return "bool"
    if declared.startswith("TEXT"):
        return "text"
    return None


class _Table:
    """A layer's table as the skeleton GDAL made holds it: its columns, SRS and R-tree."""

    def __init__(self, db: sqlite3.Connection, layer: str, spatial_index: bool):
        info = db.execute(f'PRAGMA table_info("{layer}")').fetchall()
        geometry = db.execute("SELECT column_name, srs_id FROM gpkg_geometry_columns WHERE "
                              "lower(table_name) = lower(?)", (layer,)).fetchone()
        if not info or geometry is None:
            raise BulkUnsupported(f"layer {layer!r} not found after GDAL created it")
        self.geometry_column, self.srs_id = geometry
        self.columns: list[tuple[str, str | None]] = []  # (name, kind); kind None = the fid
        for _, name, declared, _, _, pk in info:
            if pk:
                if declared.upper() != "INTEGER":
                    raise BulkUnsupported(f"primary key {name!r} of type {declared}")
                self.columns.append((name, None))
            elif name == self.geometry_column:
                self.columns.append((name, "blob"))
            else:
                kind = _kind(declared)
                if kind is None:
                    raise BulkUnsupported(f"field {name!r} of type {declared}")
                self.columns.append((name, kind))
        self.rtree = f"rtree_{layer}_{self.geometry_column}" if spatial_index else None

    def records(self, fields: Columns, blobs: np.ndarray) -> list:
        """The column specs of :func:`toolbox.io.sqlite_pages.encode_records`, in table order."""
        names = [name for name, kind in self.columns if kind not in (None, "blob")]
        if list(fields) != names:
            raise BulkUnsupported(f"fields {list(fields)} against the table's {names}")
        specs: list = []
        for name, kind in self.columns:
            if kind is None:
                specs.append(None)
            elif kind == "blob":
                specs.append(("blob", blobs, None))
            else:
                values, mask = fields[name]
                if kind == "real":
                    values = np.asarray(values, dtype=np.float64)
                    nan = np.isnan(values)  # SQLite stores a NaN as NULL: so does GDAL
                    if nan.any():
                        mask = nan if mask is None else (mask | nan)
                elif kind == "int":
                    values = np.asarray(values, dtype=np.int64)
                elif kind == "bool":
                    values = np.asarray(values, dtype=bool)
                specs.append((kind, values, mask))
        return specs


# -- writing -------------------------------------------------------------------------------------
def import_gdal_writer() -> None:
    """Import what :func:`create_empty_layer` calls: all of pyogrio (its ``__init__`` imports
    pandas and geopandas: 0.3-0.45 s) and pyarrow. A caller may run this on a thread while it
    does other work (tin:delaunay: while the triangulation runs)."""
    import pyogrio

    pyogrio.write_arrow  # noqa: B018  (the package's __init__ runs on the first name)
    try:
        import pyarrow  # noqa: F401
    except ImportError:  # pragma: no cover - pyarrow is a dependency
        pass


def create_empty_layer(path: Path, layer: BulkLayer, crs_text: str | None,
                       spatial_index: bool, dataset_options: dict | None) -> None:
    """GDAL creates the layer, its spatial index and metadata, with no feature."""
    import warnings

    import pyogrio

    try:
        import pyarrow as pa
    except ImportError:  # pragma: no cover - pyarrow is a dependency; tests remove it
        raise BulkUnsupported("pyarrow is not installed") from None
    reader = pa.RecordBatchReader.from_batches(layer.schema(), iter([]))
    with warnings.catch_warnings():  # a layer without CRS is the caller's (reported) choice
        warnings.filterwarnings("ignore", message="'crs' was not provided")
        pyogrio.write_arrow(reader, path, layer=layer.name, driver="GPKG",
                            geometry_name="geometry", geometry_type=layer.geometry_type,
                            crs=crs_text,
                            layer_options={"SPATIAL_INDEX": "YES" if spatial_index else "NO"},
                            dataset_options=dataset_options)


class RtreeToWrite(NamedTuple):
    """A layer's R-tree left for :func:`write_rtrees_bulk`: its table, the features' boxes as
    SQLite stores them (fids 1..n), the file's page size."""

    rtree: str
    stored: np.ndarray
    page_size: int


def write_layer_bulk(path: Path, layer: BulkLayer, crs_text: str | None, spatial_index: bool,
                     dataset_options: dict | None = None, created: bool = False,
                     rtrees: list[RtreeToWrite] | None = None) -> None:
    """Add ``layer`` to the GeoPackage ``path`` (created when it does not exist): GDAL makes it
    empty, the features and the R-tree are then written as pages (see the module's docs).
    ``created``: :func:`create_empty_layer` made it already (with ``spatial_index``).
    ``rtrees``: the R-tree is added to this list instead of written (see
    :func:`write_rtrees_bulk`).

    Raises :class:`BulkUnsupported` for what it does not write (the page writer's
    :class:`toolbox.io.sqlite_pages.UnsupportedDatabase` too); the file may then be left
    half-written: the caller removes it and writes the whole file with GDAL.
    """
    if not created:
        create_empty_layer(path, layer, crs_text, spatial_index, dataset_options)
    if layer.n == 0:
        return
    db = sqlite3.connect(path, isolation_level=None)
    try:
        table = _Table(db, layer.name, spatial_index)
        page_size = int(db.execute("PRAGMA page_size").fetchone()[0])
        if table.rtree is not None:  # the empty tree's root row: the packed tree replaces it
            db.execute(f'DELETE FROM "{table.rtree}_node"')
    finally:
        db.close()
    # the R-tree's boxes as SQLite stores them (float32 rounded outward: 16 bytes a feature)
    stored = np.empty((layer.n, 4), np.float32) if table.rtree is not None else None
    extent = [np.inf, -np.inf, np.inf, -np.inf]  # minx, maxx, miny, maxy

    def encoded(lo: int, hi: int):
        """Rows ``lo:hi`` as records, and their boxes' extent (on an encoding thread)."""
        fields, wkb = layer.make(lo, hi)
        blobs, boxes = geometry_blobs(wkb, table.srs_id, None if stored is None else stored[lo:hi])
        flat, offsets = encode_records(table.records(fields, blobs), hi - lo)
        part = (boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max())
        return np.arange(lo + 1, hi + 1, dtype=np.int64), flat, offsets, part

    def batches() -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        slices = ((lo, min(layer.n, lo + BATCH)) for lo in range(0, layer.n, BATCH))
        for rowids, flat, offsets, part in ahead_map(encoded, slices):
            for j, pick in enumerate((min, max, min, max)):
                extent[j] = pick(extent[j], float(part[j]))
            yield rowids, flat, offsets

    try:
        with BtreeAppender(path) as pages:
            pages.fill(layer.name, batches())
            if getattr(layer, "release", None) is not None:
                layer.release()
            if stored is not None and rtrees is not None:
                rtrees.append(RtreeToWrite(table.rtree, stored, page_size))
            elif stored is not None:
                tree = _packed(RtreeToWrite(table.rtree, stored, page_size))
                stored = None
                _fill_rtree(pages, table.rtree, tree)
    except UnsupportedDatabase as exc:
        raise BulkUnsupported(str(exc)) from exc
    _set_metadata(path, layer.name, layer.n, extent)


def write_rtrees_bulk(path: Path, rtrees: list[RtreeToWrite]) -> None:
    """Write the R-trees that :func:`write_layer_bulk` left in ``rtrees`` (emptied), packed on
    two threads at once, each written as soon as it is packed: the packing is numpy's work and
    new memory, which a second core halves (a 1 M-point TIN's triangles and edges trees: 0.48
    -> 0.28 s); holding them all at once is the cost."""
    from concurrent.futures import ThreadPoolExecutor

    if not rtrees:
        return
    names = [r.rtree for r in rtrees]
    with ThreadPoolExecutor(2, thread_name_prefix="gpkg-bulk-rtree") as pool:
        trees = pool.map(_packed, list(rtrees))  # all submitted now, yielded in order
        rtrees.clear()
        try:
            with BtreeAppender(path) as pages:
                for name, tree in zip(names, trees, strict=True):
                    _fill_rtree(pages, name, tree)
        except UnsupportedDatabase as exc:
            raise BulkUnsupported(str(exc)) from exc


def _packed(rtree: RtreeToWrite):
    """The packed tree of a layer's stored boxes (fids 1..n)."""
    n = len(rtree.stored)
    return packed_rtree_stored(np.arange(1, n + 1, dtype=np.int64), rtree.stored,
                               rtree.page_size)


def ahead_map(func: Callable, args: Iterable[tuple], workers: int = 2,
              depth: int = 4) -> Iterator:
    """``func(*a)`` for each ``a`` of ``args``, in order, computed by ``workers`` threads up to
    ``depth`` calls ahead of the consumer: the cores encode the next batches (numpy releases
    the GIL) while the consumer writes pages. The encoding of a 1 M-point TIN was the writer's
    bottleneck on one thread (the page writer waited 1.6 s of 6.5). An exception of a call is
    raised here, in order; a consumer that stops early cancels the calls not started and waits
    for the running ones."""
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(workers, thread_name_prefix="gpkg-bulk-encode")
    pending: deque = deque()
    try:
        for a in args:
            pending.append(pool.submit(func, *a))
            if len(pending) >= depth:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        for future in pending:
            future.cancel()
        pool.shutdown(wait=True)


def _fill_rtree(pages: BtreeAppender, rtree: str, tree) -> None:
    """The R-tree's three shadow tables from :func:`toolbox.io.sqlite_rtree.packed_rtree`'s
    rows (their keys ascending), each in batches of about 16 MB (node blobs are 1228 bytes)."""
    tables = {"node": (tree.node_numbers, "blob", tree.node_blobs),
              "rowid": (tree.rowids, "int", tree.rowid_nodes),
              "parent": (tree.parent_nodes, "int", tree.parents)}
    for part, (keys, kind, values) in tables.items():
        step = max(1, min(BATCH, (16 << 20) // max(1, values[:1].nbytes)))

        def encoded(lo: int, hi: int, keys=keys, kind=kind, values=values):
            flat, offsets = encode_records([None, (kind, values[lo:hi], None)], hi - lo)
            return np.asarray(keys[lo:hi], dtype=np.int64), flat, offsets

        if len(keys):
            slices = ((lo, min(len(keys), lo + step)) for lo in range(0, len(keys), step))
            pages.fill(f"{rtree}_{part}", ahead_map(encoded, slices))


def _set_metadata(path: Path, layer: str, n: int, extent: list[float]) -> None:
    """What GDAL sets after writing features: the layer's extent and last change in
    ``gpkg_contents``, its count in ``gpkg_ogr_contents``, its AUTOINCREMENT counter."""
    db = sqlite3.connect(path, isolation_level=None)
    try:
        db.execute("BEGIN")
        db.execute("UPDATE gpkg_contents SET min_x = ?, min_y = ?, max_x = ?, max_y = ?, "
                   "last_change = strftime('%Y-%m-%dT%H:%M:%fZ', 'now') "
                   "WHERE lower(table_name) = lower(?)",
                   (*(float(f"{extent[j]:.16g}") for j in (0, 2, 1, 3)),
                    layer))  # 16 significant digits, as GDAL writes the extent
        db.execute("UPDATE gpkg_ogr_contents SET feature_count = ? "
                   "WHERE lower(table_name) = lower(?)", (n, layer))
        if db.execute("SELECT 1 FROM sqlite_sequence WHERE name = ?", (layer,)).fetchone():
            db.execute("UPDATE sqlite_sequence SET seq = ? WHERE name = ?", (n, layer))
        else:
            db.execute("INSERT INTO sqlite_sequence (name, seq) VALUES (?, ?)", (layer, n))
        db.execute("COMMIT")
    finally:
        db.close()
