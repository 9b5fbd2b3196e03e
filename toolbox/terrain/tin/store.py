"""The TIN GeoPackage: write the three layers of a :class:`~toolbox.terrain.tin.build.TinModel`, read
a TIN back (from those layers, or from any layer of triangle polygons).

Layers (ids are 1-based; a missing neighbour or triangle is NULL):

``triangles`` (PolygonZ)
    ``id``; ``node1, node2, node3`` (counter-clockwise); ``nbr1, nbr2, nbr3``, the triangle
    across the edge facing ``node1``/``node2``/``node3``; ``edge1, edge2, edge3``, that edge's id;
    ``area_2d`` (planimetric), ``area_3d`` (surface); ``slope_deg``, ``slope_pct``;
    ``aspect_deg`` (the direction the slope faces, clockwise from north; -1 where flat).
``nodes`` (PointZ)
    ``id``; ``source`` (point, breakline, crossing, boundary); ``merged`` (input vertices merged
    into the node: 1 normally, more for duplicates, 0 for added nodes); ``z``.
``edges`` (LineStringZ, each edge once)
    ``id``; ``node_from``, ``node_to``; ``left_tri``, ``right_tri`` (looking from ``node_from`` to
    ``node_to``; ``right_tri`` is NULL on the border); ``breakline`` (true for breakline edges);
    ``length_2d``, ``length_3d``.

Geometries are encoded to WKB with numpy and streamed in batches through Arrow
(``pyogrio.write_arrow`` of a record-batch reader) when pyarrow is installed, else written
through ``pyogrio.raw.write``: no per-feature Python objects.
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.io.vector import (
    GPKG_DATASET_OPTIONS,
    is_multi_layer,
    is_parquet,
    sibling_layer_path,
    vector_driver,
)
from toolbox.io.vector_write import dbf_booleans, layer_paths, staged_gpkg_writes
from toolbox.io.write_failures import writing
from toolbox.terrain.tin.build import SOURCES, TinModel
from toolbox.terrain.tin.help import TIN_HELP  # noqa: F401  (re-exported: its old home)
from toolbox.terrain.tin.topology import EdgeTable, corner_measures, edge_table, triangle_corners

_WKB_POINT_Z, _WKB_LINESTRING_Z, _WKB_POLYGON_Z = 1001, 1002, 1003
BATCH = 1 << 16  # features per Arrow batch (GDAL's own Arrow batch size)
# up to this many triangles (a memory budget: the 10 M-point peak), the edge table is made once
# and the R-trees are packed together at the end
SMALL_TIN_TRIANGLES = 4_000_000


def _wkb_buffer(type_code: int, n: int, k: int, ring: bool) -> tuple[np.ndarray, np.ndarray]:
    """The ``(n, size)`` uint8 WKB records with their headers filled, and an ``(n, k')`` view of
    their vertices to fill (k' = k + 1 for a closed ring), each a 24-byte void: a vertex is
    copied whole (unaligned float64 views copy value by value, several times slower)."""
    if ring:
        k += 1
        header = np.array([type_code, 1, k], dtype="<u4")
    elif type_code == _WKB_POINT_Z:
        header = np.array([type_code], dtype="<u4")
    else:
        header = np.array([type_code, k], dtype="<u4")
    head = 1 + 4 * len(header)
    out = np.empty((n, head + 24 * k), dtype=np.uint8)
    # 1 (little endian) and the header, one void item a record (a (n, head) slice copies byte
    # by byte: 10 times slower)
    start = np.concatenate([[1], header.view(np.uint8)]).astype(np.uint8).view(f"V{head}")[0]
    np.ndarray(n, dtype=f"V{head}", buffer=out, strides=(out.shape[1],))[:] = start
    return out, np.ndarray((n, k), dtype="V24", buffer=out, offset=head, strides=(out.shape[1], 24))


def _vertices(xyz: np.ndarray) -> np.ndarray:
    """``(..., 3)`` little-endian coordinates as ``(...)`` 24-byte voids (WKB's XYZ vertices)."""
    return np.ascontiguousarray(xyz, dtype="<f8").view("V24")[..., 0]


def wkb_records(type_code: int, coords: np.ndarray, ring: bool = False) -> np.ndarray:
    """ISO WKB of fixed-size geometries, one row of bytes each, ``(n, size)`` uint8.

    ``coords`` is ``(n, k, 3)``: k XYZ vertices per geometry. ``ring`` writes one closed polygon
    ring (the first vertex repeated at the end) instead of a point or line string.
    """
    vertices = _vertices(coords)
    n, k = vertices.shape
    out, slots = _wkb_buffer(type_code, n, k, ring)
    slots[:, :k] = vertices
    if ring:
        slots[:, k] = vertices[:, 0]
    return out


Columns = dict[str, tuple[np.ndarray, "np.ndarray | None"]]


class _Layer:
    """One layer to write, produced in slices: ``make(lo, hi)`` returns the columns (field name
    -> (values, null mask or None)) and the ``(hi - lo, size)`` WKB records of features
    ``lo:hi``, so a writer holds one batch of geometries and Arrow arrays at a time.
    ``release``: see :class:`toolbox.io.gpkg_bulk.BulkLayer`."""

    def __init__(self, name: str, n: int, make, geometry_type: str, release=None):
        self.name, self.n, self.make, self.geometry_type = name, n, make, geometry_type
        self.release = release

    def schema(self):
        import pyarrow as pa

        columns, _ = self.make(0, min(self.n, 1))
        return pa.schema([pa.field(k, pa.from_numpy_dtype(v.dtype) if v.dtype.kind != "O"
                                   else pa.string()) for k, (v, _) in columns.items()]
                         + [pa.field("geometry", pa.binary())])

    def batches(self, schema):
        """The Arrow record batches of :data:`BATCH` features, built one by one."""

        for lo in range(0, max(self.n, 1), BATCH):
            hi = min(self.n, lo + BATCH)
            columns, wkb = self.make(lo, hi)
            yield _record_batch(schema, columns, wkb)

    def reader(self):
        """A ``pyarrow.RecordBatchReader`` streaming :meth:`batches`."""
        import pyarrow as pa

        schema = self.schema()
        return pa.RecordBatchReader.from_batches(schema, self.batches(schema))


def _record_batch(schema, columns: Columns, wkb: np.ndarray):
    """An Arrow record batch of the columns and a ``geometry`` WKB column, built from the numpy
    buffers (no per-feature Python objects)."""
    import pyarrow as pa

    n = len(wkb)
    size = wkb.shape[1] if n else 0
    arrays = [pa.array(v, mask=m, type=schema.field(k).type) for k, (v, m) in columns.items()]
    offsets = np.arange(n + 1, dtype=np.int32) * size
    data = pa.py_buffer(np.ascontiguousarray(wkb).ravel())
    arrays.append(pa.Array.from_buffers(pa.binary(), n, [None, pa.py_buffer(offsets), data]))
    return pa.record_batch(arrays, schema=schema)


def _write_geoparquet(path: Path, layer: _Layer, crs: Any) -> None:
    """GeoParquet 1.0: the WKB column plus the ``geo`` schema metadata (CRS as PROJJSON),
    written batch by batch."""
    import json

    import pyarrow.parquet as pq

    geo = {"version": "1.0.0", "primary_column": "geometry",
           "columns": {"geometry": {"encoding": "WKB",
                                    "geometry_types": [layer.geometry_type],
                                    "crs": None if crs is None else crs.to_json_dict()}}}
    schema = layer.schema().with_metadata({b"geo": json.dumps(geo).encode()})
    # dictionary encoding only pays for the text columns: on ids and coordinates it made the
    # write 4-5 times slower for no smaller file
    text = [f.name for f in schema if str(f.type) == "string"]
    with pq.ParquetWriter(path, schema, compression="snappy", use_dictionary=text) as writer:
        for batch in layer.batches(schema):
            writer.write_batch(batch)


def _dbf_columns(make):
    """``make`` (:class:`_Layer`) with its Boolean columns as Integer 0/1
    (:func:`toolbox.io.vector_write.dbf_booleans`: the edges' ``breakline`` in a Shapefile)."""
    def dbf_make(lo: int, hi: int):
        columns, wkb = make(lo, hi)
        return {k: (dbf_booleans(v), m) for k, (v, m) in columns.items()}, wkb

    return dbf_make


def _write_layer(path: Path, layer: _Layer, crs: Any, spatial_index: bool,
                 bulk: bool = False, created: bool = False, rtrees: list | None = None) -> None:
    """Write one layer in the format of ``path``'s extension (``path`` is this layer's own file
    for one-layer formats). ``bulk``: a GeoPackage's layer through
    :func:`toolbox.io.gpkg_bulk.write_layer_bulk` (pages written with numpy; ``created``: GDAL
    made the layer empty already, :class:`NodesAhead`; ``rtrees``: its R-tree is left in the
    list, see :func:`toolbox.io.gpkg_bulk.write_rtrees_bulk`). Otherwise through
    Arrow, the batches stream into GDAL one at a time; GDAL builds a GeoPackage's spatial index
    once, after the last feature (in bulk, on a thread of its own), not feature by feature."""
    import pyogrio

    driver = vector_driver(path)
    crs_text = None if crs is None else crs.to_wkt()
    dataset_options = GPKG_DATASET_OPTIONS if driver == "GPKG" and not path.exists() else None
    if bulk:
        from toolbox.io.gpkg_bulk import write_layer_bulk

        with staged_gpkg_writes(), writing(path):
            write_layer_bulk(path, layer, crs_text, spatial_index, dataset_options, created,
                             rtrees)
        return
    options = {"SPATIAL_INDEX": "YES" if spatial_index else "NO"} \
        if driver in ("GPKG", "FlatGeobuf", "ESRI Shapefile") else {}
    try:
        import pyarrow  # noqa: F401
    except ImportError:  # pragma: no cover - exercised when pyarrow is absent
        pyarrow = None
    if driver == "Parquet":
        _write_geoparquet(path, layer, crs)
        return
    if driver == "ESRI Shapefile":  # Booleans as 0/1: GDAL < 3.9 reads a DBF Logical as text
        layer = _Layer(layer.name, layer.n, _dbf_columns(layer.make), layer.geometry_type)
    if pyarrow is not None:
        with warnings.catch_warnings():  # a TIN without CRS is the caller's (reported) choice
            warnings.filterwarnings("ignore", message="'crs' was not provided")
            with staged_gpkg_writes(), writing(path):  # a full disk: OUTPUT's error
                pyogrio.write_arrow(layer.reader(), path, layer=layer.name, driver=driver,
                                    geometry_name="geometry",
                                    geometry_type=layer.geometry_type, crs=crs_text,
                                    layer_options=options, dataset_options=dataset_options)
        return
    from pyogrio.raw import write

    columns, wkb = layer.make(0, layer.n)
    n = len(wkb)
    flat = np.ascontiguousarray(wkb).tobytes()
    size = wkb.shape[1] if n else 0
    geometry = np.empty(n, dtype=object)
    geometry[:] = [flat[i * size:(i + 1) * size] for i in range(n)]
    names = list(columns)
    with staged_gpkg_writes(), writing(path):
        write(path, geometry, [columns[k][0] for k in names], names,
              field_mask=[columns[k][1] for k in names], layer=layer.name, driver=driver,
              geometry_type=layer.geometry_type, crs=crs_text, layer_options=options,
              dataset_options=dataset_options)


def _ids(index: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """0-based index (-1 = none) -> 1-based id column with a null mask."""
    index = np.asarray(index, dtype=np.int64)
    missing = index < 0
    return index + 1, (missing if missing.any() else None)


def _serial(lo: int, hi: int) -> tuple[np.ndarray, None]:
    """The 1-based ids ``lo + 1 .. hi``."""
    return np.arange(lo + 1, hi + 1, dtype=np.int64), None


def write_tin(path: str | Path, model: TinModel, crs: Any = None, spatial_index: bool = True,
              feedback=None, edges_layer: bool = True,
              ahead: NodesAhead | None = None) -> dict[str, int]:
    """Write the ``triangles``, ``nodes`` and (unless ``edges_layer`` is False) ``edges`` layers
    of ``model`` to a GeoPackage (1.2), or in the format of ``path``'s extension: FlatGeobuf,
    GeoParquet (a third of a new GeoPackage's size, a little slower), Shapefile or GeoJSON, one
    file per layer (``tin.fgb`` holds the triangles, ``tin_nodes.fgb`` and ``tin_edges.fgb`` the
    others).

    Features are encoded and written in batches of :data:`BATCH` (geometries, Arrow arrays):
    memory holds the model and one batch, not a second copy of every layer. A new GeoPackage
    is written in bulk (:mod:`toolbox.io.gpkg_bulk`: SQLite pages built with numpy, several
    times faster than GDAL's inserts); what that writer does not take is written by GDAL.
    ``ahead``: the :class:`NodesAhead` that was given the model's nodes while it was built
    (same ``path``, ``crs``, ``spatial_index`` and ``edges_layer``); its layers are kept.
    Returns the feature count of each layer (edges are counted even when not written).
    """
    path = Path(path)
    started = ahead is not None and ahead.started
    if started or _new_geopackage(path):
        from toolbox.io.gpkg_bulk import BulkUnsupported

        try:
            if started:
                ahead.wait(model, path, spatial_index, edges_layer)
            return _write_tin(path, model, crs, spatial_index, feedback, edges_layer, bulk=True,
                              nodes_written=started)
        except BulkUnsupported as exc:
            import logging

            logging.getLogger(__name__).debug("GeoPackage written by GDAL: %s", exc)
            for leftover in (path, path.with_name(path.name + "-journal")):
                leftover.unlink(missing_ok=True)
    return _write_tin(path, model, crs, spatial_index, feedback, edges_layer)


def _new_geopackage(path: Path) -> bool:
    """A GeoPackage that does not exist yet: what the bulk writer writes."""
    return vector_driver(path) == "GPKG" and not path.exists()


def _write_tin(path: Path, model: TinModel, crs: Any, spatial_index: bool, feedback,
               edges_layer: bool, bulk: bool = False, nodes_written: bool = False
               ) -> dict[str, int]:
    """``nodes_written``: the three layers exist (empty) and the nodes layer is written."""
    targets = layer_paths(path, ["triangles", "nodes", "edges"])
    xyz, tri, nb = model.xyz, model.triangles, model.neighbors
    # A big TIN keeps only the triangles' edge ids while the triangles layer is written (GDAL
    # builds its R-tree in memory then: a 10 M-point TIN peaked there), and the edge table is
    # made again for the edges; a small one keeps the whole table (no second making: 0.2-0.3 s
    # of CPU at 1 M points)
    keep = [edge_table(tri, nb)]
    triangle_edges = keep[0].triangle_edges  # set to None after that layer
    if not edges_layer or len(tri) > SMALL_TIN_TRIANGLES:
        keep.clear()
    n_edges = int(triangle_edges.max()) + 1 if triangle_edges.size else 0  # ids 0..n-1
    # a small TIN's R-trees are packed at the end, two at once (gpkg_bulk.write_rtrees_bulk); a
    # big one's each after its layer's rows (its layers' boxes are never all held at once)
    rtrees = [] if bulk and spatial_index and len(tri) <= SMALL_TIN_TRIANGLES else None
    step = _Steps(feedback, (3 if edges_layer else 2) - nodes_written + (rtrees is not None))
    with step("write triangles"):
        _write_layer(targets["triangles"], _triangles_layer(xyz, tri, nb, triangle_edges), crs,
                     spatial_index, bulk, nodes_written, rtrees)
    triangle_edges = None  # the layer's reference went with it: freed before the nodes layer
    with ThreadPoolExecutor(1, thread_name_prefix="tin-edges") as pool:
        # the edges' table (without triangle_edges, T x 3), made again beside the nodes layer
        # (1 M points: 0.3 s) unless kept; popped when used: _write_edges holds the only
        # reference
        table = [pool.submit(lambda: _without_triangle_edges(keep.pop() if keep
                                                             else edge_table(tri, nb)))] \
            if edges_layer else []
        if not nodes_written:
            with step("write nodes"):
                _write_layer(targets["nodes"],
                             _nodes_layer_of(model.xyz, model.source, model.merged), crs,
                             spatial_index, bulk, rtrees=rtrees)
        if table:
            with step("write edges"):
                _write_edges(targets["edges"], model, table.pop().result(), crs, spatial_index,
                             bulk, nodes_written, rtrees)
    if rtrees is not None:
        from toolbox.io.gpkg_bulk import write_rtrees_bulk

        with step("write spatial indexes"), writing(path):
            write_rtrees_bulk(path, rtrees)
    return {"triangles": len(tri), "nodes": len(xyz), "edges": n_edges}


def _triangles_layer(xyz: np.ndarray, tri: np.ndarray, nb: np.ndarray,
                     triangle_edges: np.ndarray) -> _Layer:
    """The ``triangles`` layer: ids, nodes, neighbours, edges, measures and PolygonZ rings."""
    def triangles(lo: int, hi: int):
        columns = {"id": _serial(lo, hi)}
        for prefix, table in (("node", tri), ("nbr", nb), ("edge", triangle_edges)):
            for j in range(3):
                columns[f"{prefix}{j + 1}"] = _ids(table[lo:hi, j])
        vertices = triangle_corners(xyz, tri[lo:hi])
        measures = corner_measures(vertices)  # per batch: never (T,) x 5 at once
        for name in ("area_2d", "area_3d", "slope_deg", "slope_pct", "aspect_deg"):
            columns[name] = (getattr(measures, name), None)
        return columns, wkb_records(_WKB_POLYGON_Z, vertices, ring=True)

    return _Layer("triangles", len(tri), triangles, "Polygon Z")


_SOURCE_NAMES = np.asarray(SOURCES)  # numpy str: written without a Python object a node


def _nodes_layer_of(xyz: np.ndarray, source: np.ndarray, merged: np.ndarray) -> _Layer:
    """The ``nodes`` layer: ids, source names, merged counts, Z and PointZ geometries."""
    def nodes(lo: int, hi: int):
        columns = {"id": _serial(lo, hi), "source": (_SOURCE_NAMES[source[lo:hi]], None),
                   "merged": (merged[lo:hi].astype(np.int64), None),
                   "z": (xyz[lo:hi, 2].copy(), None)}
        return columns, wkb_records(_WKB_POINT_Z, xyz[lo:hi, None, :])

    return _Layer("nodes", len(xyz), nodes, "Point Z")


class NodesAhead:
    """A new TIN GeoPackage's ``nodes`` layer, written on a thread while the triangulation runs.

    Without breaklines, boundary and concave hull, a TIN's nodes are its (merged) input points,
    known before the triangulation: :func:`toolbox.terrain.tin.build.build_tin` hands them to
    its ``nodes_ready`` callback, this object. PythonCDT lets the GIL go while it inserts the
    points, so the other core creates the empty layers (triangles, nodes, edges: GDAL lists a
    GeoPackage's layers in the order they were made) and writes the nodes in bulk then (a
    million points: 0.45 s of writing, done before CDT's insertion ends). :func:`write_tin`
    given this object waits for that writing and writes the other two layers; any failure of it
    is raised there.
    """

    def __init__(self, path: str | Path, crs: Any, spatial_index: bool, edges_layer: bool,
                 pool) -> None:
        self.path, self.crs, self.pool = Path(path), crs, pool
        self.spatial_index, self.edges_layer = spatial_index, edges_layer
        self._future = None
        self._xyz: np.ndarray | None = None

    @property
    def started(self) -> bool:
        return self._future is not None

    def __call__(self, xyz: np.ndarray, source: np.ndarray, merged: np.ndarray) -> None:
        """Start writing these nodes (a new GeoPackage only; otherwise nothing is done)."""
        if self.started or not _new_geopackage(self.path):
            return
        self._xyz = xyz
        self._future = self.pool.submit(self._write, _nodes_layer_of(xyz, source, merged))

    def _write(self, nodes: _Layer) -> None:
        from toolbox.io.gpkg_bulk import create_empty_layer

        crs_text = None if self.crs is None else self.crs.to_wkt()
        shape = _one_triangle_model()  # the other layers' fields, from their own code
        shape_edges = edge_table(shape.triangles, shape.neighbors)
        layers = [_triangles_layer(shape.xyz, shape.triangles, shape.neighbors,
                                   shape_edges.triangle_edges), nodes]
        if self.edges_layer:
            layers.append(_edges_layer(shape, [shape_edges]))
        with staged_gpkg_writes(), writing(self.path):
            for layer in layers:
                create_empty_layer(self.path, layer, crs_text, self.spatial_index,
                                   None if self.path.exists() else GPKG_DATASET_OPTIONS)
        _write_layer(self.path, nodes, self.crs, self.spatial_index, bulk=True, created=True)

    def wait(self, model: TinModel, path: Path, spatial_index: bool, edges_layer: bool) -> None:
        """Wait for the writing (raising its error) and check that it wrote ``model``'s nodes."""
        if (path, spatial_index, edges_layer) != (self.path, self.spatial_index,
                                                   self.edges_layer):
            raise ValueError("write_tin: ahead was made for another file or other options")
        self._future.result()
        if not np.array_equal(self._xyz, model.xyz):  # build_tin's contract: never expected
            raise RuntimeError("internal: the TIN's nodes are not those written ahead")


def _one_triangle_model() -> TinModel:
    """A TIN of one triangle: the layers' fields and types without a real model."""
    xyz = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return TinModel(xyz, np.zeros(3, np.int8), np.ones(3, np.int64),
                    np.array([[0, 1, 2]], np.int32), np.full((1, 3), -1, np.int32),
                    np.zeros((0, 2), np.int64))


def breakline_flags(edges: EdgeTable, breakline_edges: np.ndarray, n_nodes: int) -> np.ndarray:
    """True for the edges whose node pair is in ``breakline_edges``."""
    if len(breakline_edges) == 0:
        return np.zeros(len(edges.nodes), dtype=bool)
    key = np.sort(edges.nodes, axis=1) @ np.array([n_nodes, 1], dtype=np.int64)
    ref = np.sort(breakline_edges, axis=1) @ np.array([n_nodes, 1], dtype=np.int64)
    return np.isin(key, ref)


def _without_triangle_edges(table: EdgeTable) -> EdgeTable:
    return EdgeTable(table.nodes, table.left, table.right, np.zeros((0, 3), np.int32))


def _write_edges(path: Path, model: TinModel, edges: EdgeTable, crs: Any,
                 spatial_index: bool, bulk: bool = False, created: bool = False,
                 rtrees: list | None = None) -> None:
    """The edges layer. In bulk, the edge table is let go once every batch was made (the
    caller keeps no reference): the R-tree is packed without it (10 M points: 0.5 GB less at
    the run's peak). A bulk refusal rewrites the whole TIN through GDAL from the model."""
    held = [edges]
    del edges
    _write_layer(path, _edges_layer(model, held), crs, spatial_index, bulk, created, rtrees)


def _edges_layer(model: TinModel, held: list[EdgeTable]) -> _Layer:
    """The ``edges`` layer of the edge table ``held[0]``; the layer's ``release`` empties
    ``held`` (the writer in bulk lets the table go once every batch is made)."""
    xyz = model.xyz
    breakline = breakline_flags(held[0], model.breakline_edges, len(xyz))
    n = len(held[0].nodes)

    def make(lo: int, hi: int):
        edges = held[0]
        ends = edges.nodes[lo:hi]
        ends_xyz = np.take(xyz, ends, axis=0)  # (n, 2, 3): for the lengths and the WKB
        d = ends_xyz[:, 1] - ends_xyz[:, 0]
        length_2d = np.hypot(d[:, 0], d[:, 1])
        columns = {"id": _serial(lo, hi), "node_from": _ids(ends[:, 0]),
                   "node_to": _ids(ends[:, 1]), "left_tri": _ids(edges.left[lo:hi]),
                   "right_tri": _ids(edges.right[lo:hi]), "breakline": (breakline[lo:hi], None),
                   "length_2d": (length_2d, None),
                   "length_3d": (np.hypot(length_2d, d[:, 2]), None)}
        return columns, wkb_records(_WKB_LINESTRING_Z, ends_xyz)

    return _Layer("edges", n, make, "LineString Z", held.clear)


class _Steps:
    """``with steps("name"):`` times a block in the feedback and advances its progress."""

    def __init__(self, feedback, total: int):
        self.feedback, self.total, self.done = feedback, total, 0

    def __call__(self, name: str):
        from contextlib import nullcontext

        if self.feedback is None:
            return nullcontext()
        self.feedback.check_canceled()
        self.done += 1
        self.feedback.set_progress(100.0 * (self.done - 1) / self.total, name)
        return self.feedback.timed(name)


# -- reading ---------------------------------------------------------------------------------------
def read_tin(ref) -> tuple[np.ndarray, np.ndarray, Any]:
    """Nodes ``(N, 3)`` and triangles ``(T, 3)`` (0-based, counter-clockwise) of a TIN layer.

    ``ref`` is a :class:`~toolbox.io.vector.VectorLayerRef` to a layer of triangles: the
    ``triangles`` layer of a tin:delaunay GeoPackage (nodes taken from its ``nodes`` layer by
    the ``node1..3`` ids), or any layer of triangular polygons with Z (nodes rebuilt from the
    shared vertices). Returns ``(xyz, triangles, crs)``.
    """

    from toolbox.io.vector import read_vector

    if ref.path is not None and not ref.filtered \
            and {"node1", "node2", "node3"} <= set(ref.fields):
        nodes = _nodes_layer(ref.path)
        if nodes is not None:
            return _read_tin_tables(ref, *nodes)
    frame = read_vector(ref, name="TIN")
    return (*tin_from_triangle_geometries(frame.geometry.values, "TIN"), ref.crs)


def _nodes_layer(path: Path) -> tuple[Path, str | None] | None:
    """Where the ``nodes`` layer of the TIN whose triangles are in ``path`` is: the ``nodes``
    layer of the same GeoPackage, or the ``<stem>_nodes`` file beside a one-layer file."""
    import pyogrio

    if is_multi_layer(path):
        layers = [str(row[0]) for row in pyogrio.list_layers(path)]
        return (path, "nodes") if "nodes" in layers else None
    sibling = sibling_layer_path(path, "nodes")
    return (sibling, None) if sibling.exists() else None


def _read_table(path: Path, layer: str | None, columns: list[str],
                geometry: bool) -> tuple[list[np.ndarray], Any]:
    """Columns of a layer as numpy arrays, and its geometries as WKB (an ``(n, size)`` uint8
    array when every record has the same size, else an object array of bytes). Arrow is used
    when pyarrow is installed (several times faster on millions of features); GeoParquet is
    read with pyarrow directly."""
    if is_parquet(path):
        import pyarrow.parquet as pq

        table = pq.read_table(path, columns=[*columns, "geometry"] if geometry else columns)
        values = [table.column(c).to_numpy() for c in columns]
        return values, (_wkb_array(table.column("geometry").combine_chunks())
                        if geometry else None)
    try:
        import pyarrow  # noqa: F401
    except ImportError:  # pragma: no cover - exercised when pyarrow is absent
        from pyogrio.raw import read

        _, _, wkb, fields = read(path, layer=layer, columns=columns, read_geometry=geometry)
        return [np.asarray(f) for f in fields], wkb
    import pyogrio

    meta, table = pyogrio.read_arrow(path, layer=layer, columns=columns,
                                     read_geometry=geometry)
    values = [table.column(c).to_numpy() for c in columns]
    if not geometry:
        return values, None
    return values, _wkb_array(table.column(meta["geometry_name"] or "wkb_geometry")
                              .combine_chunks())


def _wkb_array(arr) -> Any:
    """An Arrow binary array of WKB as an ``(n, size)`` uint8 array when every record has the
    same size, else an object array of bytes."""
    offset_type = np.int64 if str(arr.type) == "large_binary" else np.int32
    offsets = np.frombuffer(arr.buffers()[1], dtype=offset_type)[arr.offset:
                                                                 arr.offset + len(arr) + 1]
    sizes = np.diff(offsets)
    data = np.frombuffer(arr.buffers()[2], dtype=np.uint8)
    if len(sizes) and (sizes == sizes[0]).all() and arr.null_count == 0:
        return data[offsets[0]:offsets[-1]].reshape(len(arr), int(sizes[0]))
    return np.asarray(arr.to_pylist(), dtype=object)


def points_from_wkb(wkb) -> np.ndarray:
    """XYZ of point geometries given as WKB (fixed-size records are decoded with numpy)."""
    import shapely

    if isinstance(wkb, np.ndarray) and wkb.dtype == np.uint8 and wkb.ndim == 2 \
            and wkb.shape[1] == 29 and (wkb[:, 0] == 1).all():
        kind = wkb[:, 1:5].copy().view("<u4").ravel()
        if np.isin(kind, [_WKB_POINT_Z, 0x80000001]).all():
            return wkb[:, 5:29].copy().view("<f8").reshape(-1, 3)
    if isinstance(wkb, np.ndarray) and wkb.dtype == np.uint8:
        wkb = np.array([row.tobytes() for row in wkb], dtype=object)
    return shapely.get_coordinates(shapely.from_wkb(wkb), include_z=True)


def _read_tin_tables(ref, nodes_path: Path, nodes_layer: str | None
                     ) -> tuple[np.ndarray, np.ndarray, Any]:
    fields, _ = _read_table(ref.path, ref.layer, ["node1", "node2", "node3"], geometry=False)
    tri_ids = np.column_stack([np.asarray(f, dtype=np.int64) for f in fields])
    (node_ids,), wkb = _read_table(nodes_path, nodes_layer, ["id"], geometry=True)
    node_ids = np.asarray(node_ids, dtype=np.int64)
    xyz = points_from_wkb(wkb)
    if len(xyz) != len(node_ids) or not np.isfinite(xyz).all():
        raise InputDataError(f"TIN {ref}: the nodes layer must hold one PointZ per node, with Z")
    if np.array_equal(node_ids, np.arange(1, len(node_ids) + 1)):
        triangles = tri_ids - 1
    else:
        order = np.argsort(node_ids)
        pos = np.searchsorted(node_ids[order], tri_ids)
        pos = np.minimum(pos, len(order) - 1)
        if not np.array_equal(node_ids[order][pos], tri_ids):
            raise InputDataError(f"TIN {ref}: triangles refer to node ids missing from 'nodes'")
        triangles = order[pos]
    if len(triangles) and (triangles.min() < 0 or triangles.max() >= len(xyz)):
        raise InputDataError(f"TIN {ref}: triangles refer to node ids missing from 'nodes'")
    return xyz, _counter_clockwise(xyz, triangles), ref.crs


Z_TOLERANCE = 1e-3
"""Largest height difference (Z units: metres) between the corners of adjacent triangles at one XY that are
taken as one node (their mean): above float32 rounding of any terrain height (under 1 mm up to
16 km), below any real step."""


def tin_from_triangle_geometries(geoms, name: str = "TIN") -> tuple[np.ndarray, np.ndarray]:
    """Nodes and triangles from triangle polygons (PolygonZ with 3 distinct vertices each).

    The corners at one XY become one node, at the mean of their Z; an InputDataError names the
    features (rows counted from 1) that are null, empty, not triangles or without finite Z, and
    the XY where corners differ by more than :data:`Z_TOLERANCE` (not a single-valued surface).
    """
    import shapely

    from toolbox.io.vector import feature_rows, no_geometry

    geoms = np.asarray(geoms)
    if len(geoms) == 0:
        raise InputDataError(f"{name} has no triangles")

    def refuse(bad: np.ndarray, what: str) -> None:
        if bad.any():
            raise InputDataError(f"{name}: {int(bad.sum())} of {len(geoms)} feature(s) "
                                 f"({feature_rows(np.flatnonzero(bad))}) {what}")

    refuse(no_geometry(geoms),
           "have no geometry (null or empty): every feature must be a triangle")
    refuse(shapely.get_type_id(geoms) != 3, "are not single triangles (Polygon Z)")
    refuse(~shapely.has_z(geoms), "have no Z: triangles need 3D vertices")
    coords, index = shapely.get_coordinates(shapely.get_exterior_ring(geoms), include_z=True,
                                            return_index=True)
    counts = np.bincount(index, minlength=len(geoms))
    refuse(counts != 4, "are not triangles (not 3 vertices)")
    refuse(np.bincount(index, ~np.isfinite(coords).all(axis=1), len(geoms)) > 0,
           "have NaN/inf coordinates or Z")
    corners = coords.reshape(-1, 4, 3)[:, :3].reshape(-1, 3)
    key = corners[:, 0] + 1j * corners[:, 1]
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    xyz = corners[first]
    z = corners[:, 2]
    low, high = np.full(len(xyz), np.inf), np.full(len(xyz), -np.inf)
    np.minimum.at(low, inverse, z)
    np.maximum.at(high, inverse, z)
    spread = high - low
    if (spread > Z_TOLERANCE).any():
        node = int(np.argmax(spread))
        at = np.flatnonzero(inverse == node)
        a, b = at[np.argmin(z[at])], at[np.argmax(z[at])]
        raise InputDataError(
            f"{name} is not a single-valued surface: {int((spread > Z_TOLERANCE).sum())} "
            f"vertex position(s) have different heights in different triangles (more than "
            f"{Z_TOLERANCE:g}), the largest at X {xyz[node, 0]:.3f} Y {xyz[node, 1]:.3f}: "
            f"Z {z[a]:.3f} in row {a // 3 + 1} and {z[b]:.3f} in row {b // 3 + 1}, counting "
            "from 1")
    xyz[:, 2] = np.bincount(inverse, z) / np.bincount(inverse)  # the mean: not the first's
    triangles = inverse.reshape(-1, 3)
    return xyz, _counter_clockwise(xyz, triangles)


def _counter_clockwise(xyz: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    p = xyz[triangles]
    area = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) \
        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])
    out = np.array(triangles, dtype=np.int64)
    cw = area < 0
    out[cw] = out[cw][:, [0, 2, 1]]
    return out
