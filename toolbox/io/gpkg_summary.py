"""What ``vector:info`` says of a GeoPackage of points, read with the standard library's
``sqlite3`` only (no numpy, pyogrio or shapely: importing them is most of a small run).

:func:`summarise` gives the layers as ``vector:info`` reports them through OGR and shapely
(:func:`algorithms.vector.info.geometry_summary`), or None whenever it cannot be certain of
giving the same answer; the caller then takes that path. It answers only for:

- a GeoPackage (application id ``GPKG`` with user version 1.2-1.4, or ``GP10``/``GP11``)
  without views, virtual tables, several geometry columns in a table, related-tables mappings
  or extensions beyond the R-tree, metadata, schema and CRS-WKT ones (each of these OGR lists,
  names or warns about in its own way);
- layers listed as OGR's GeoPackage driver lists them (its own query: feature tables, attribute
  tables, and the tables not in ``gpkg_contents`` when no attribute table is registered), at
  most :data:`MAX_LAYERS`, each with one ``INTEGER PRIMARY KEY`` (OGR's FID) and columns of
  the declared types in :data:`FIELD_TYPES` (the dtype ``pyogrio.read_info`` reports);
- feature layers whose spatial reference system is a plain EPSG code (OGR reads it as
  ``EPSG:n``: :func:`epsg_label`), without M, whose geometries are null or standard
  GeoPackage binary Points (not extended, not empty) in 2D or Z (WKB type 1, 1001 or the
  25D flag) with finite coordinates, at most :data:`MAX_POINTS` in the file.

The file is opened read-only (``mode=ro``: a ``-wal`` file's content is read as OGR reads it;
nothing is written to the database).
"""

from __future__ import annotations

import array
import math
import re
import sqlite3
import struct
import sys
from operator import itemgetter
from pathlib import Path
from typing import Any
from urllib.parse import quote

#: more points than this in the file: the general path. Measured up to here (whole process,
#: bench/results/startup.md) this module took less CPU and memory than the general path's
#: numpy and shapely (1,000,000 PointZ: 0.9 s against 1.6 s, no crossover found); beyond it
#: is not measured
MAX_POINTS = 1_000_000
#: more layers than this: the general path (OGR's per-layer answer)
MAX_LAYERS = 100

#: SQLite declared type (upper case) -> the dtype ``pyogrio.read_info`` gives the field
#: (GDAL's GeoPackage driver; checked against pyogrio 0.13 / GDAL 3.12 in the tests)
FIELD_TYPES = {"INTEGER": "int64", "INT": "int64", "MEDIUMINT": "int32", "SMALLINT": "int16",
               "TINYINT": "int32", "BOOLEAN": "bool", "FLOAT": "float32", "REAL": "float64",
               "DOUBLE": "float64", "NUMERIC": "float64", "TEXT": "object", "DATE":
               "datetime64[D]", "DATETIME": "datetime64[ms]", "BLOB": "object"}
_SIZED = re.compile(r"(TEXT|BLOB)\(\d+\)")

_APPLICATION_IDS = {0x47504B47: (10200, 10300, 10400),  # 'GPKG' with its user_version
                    0x47503130: None, 0x47503131: None}  # 'GP10', 'GP11'
_KNOWN_EXTENSIONS = {"gpkg_rtree_index", "gpkg_metadata", "gpkg_schema", "gpkg_crs_wkt",
                     "gpkg_crs_wkt_1_1"}
#: bytes of the envelope after the header, by the envelope indicator of the flags (bits 1-3)
_ENVELOPE_BYTES = {0: 0, 1: 32, 2: 48, 3: 48, 4: 64}

#: the root authority of a WKT 1 or 2 definition, at its end
_ROOT_EPSG = re.compile(r'(?:AUTHORITY\["EPSG",\s*"(\d+)"\]|ID\["EPSG",\s*(\d+)\])\]\s*$',
                        re.IGNORECASE)

#: OGR's GeoPackage driver's list of vector layers (GDAL 3.12
#: GDALGeoPackageDataset::Open), its order included
_LAYERS_SQL = (
    "SELECT c.table_name, 1 AS is_spatial, g.column_name, g.m, g.srs_id, "
    "(SELECT type FROM sqlite_master WHERE lower(name) = lower(c.table_name) AND type IN "
    "('table', 'view')) AS object_type FROM gpkg_geometry_columns g JOIN gpkg_contents c ON "
    "(g.table_name = c.table_name) WHERE c.table_name <> 'ogr_empty_table' AND "
    "c.data_type = 'features' "
    "UNION ALL SELECT table_name, 0 AS is_spatial, NULL, 0, NULL, "
    "(SELECT type FROM sqlite_master WHERE lower(name) = lower(table_name) AND type IN "
    "('table', 'view')) AS object_type FROM gpkg_contents WHERE data_type IN ('aspatial', "
    "'attributes') ")
_UNREGISTERED_SQL = (
    "UNION ALL SELECT name, 0 AS is_spatial, NULL, 0, NULL, type AS object_type FROM "
    "sqlite_master WHERE type IN ('table', 'view') AND name NOT LIKE 'gpkg_%' AND name NOT "
    "LIKE 'vgpkg_%' AND name NOT LIKE 'rtree_%' AND name NOT LIKE 'sqlite_%' AND name NOT IN "
    "('st_spatial_ref_sys', 'spatial_ref_sys', 'st_geometry_columns', 'geometry_columns') "
    "AND lower(name) NOT IN (SELECT lower(table_name) FROM gpkg_contents)")


class Uncertain(Exception):
    """The file is outside what this module answers for: the general path must read it."""


def epsg_label(srs_id: Any, organization: Any, code: Any, definition: Any) -> str | None:
    """``EPSG:code`` when OGR reads the GeoPackage's spatial reference system row as that EPSG
    code, else None. GDAL takes a system from its EPSG code when ``organization`` is EPSG and
    ``organization_coordsys_id`` equals ``srs_id``, else from ``definition``: only a system
    whose definition's root authority is that same EPSG code is answered, so that either way
    OGR (and pyogrio's ``crs``) says ``EPSG:code``."""
    root = _ROOT_EPSG.search(str(definition or ""))
    if str(organization or "").upper() != "EPSG" or root is None:
        return None
    try:
        same = int(code) == int(srs_id) == int(root.group(1) or root.group(2))
    except (TypeError, ValueError):  # a null or text code: OGR says
        return None
    return f"EPSG:{int(code)}" if same else None


def connect_read_only(path: str | Path) -> sqlite3.Connection:
    """A read-only connection to the SQLite file ``path`` (a URI with ``mode=ro``: nothing is
    written to it; a ``-wal`` file beside it is read, as SQLite and GDAL read it)."""
    uri = "file:" + quote(str(Path(path).absolute()), safe="/") + "?mode=ro"
    return sqlite3.connect(uri, uri=True, check_same_thread=False)


def unread_wal(path: str | Path) -> str | None:
    """Why the ``-wal`` beside the SQLite file ``path`` (a GeoPackage) cannot be read, or None
    (no ``-wal``, an empty one, or one SQLite reads). SQLite cannot open a file in WAL mode when
    it cannot create its ``-shm`` beside it (a read-only folder): GDAL then reopens it with
    ``IMMUTABLE=YES`` and reads it without the rows committed to the ``-wal``, with a warning
    only (OSGeo/gdal#6407); the readers refuse it instead, as SQLite does."""
    wal = Path(f"{path}-wal")
    try:
        size = wal.stat().st_size
        if not size:
            return None
        with open(path, "rb") as f:
            if f.read(16) != b"SQLite format 3\x00":
                return None
        con = connect_read_only(path)
        try:
            con.execute("SELECT count(*) FROM sqlite_master").fetchone()
        finally:
            con.close()
    except OSError:
        return None
    except sqlite3.Error as exc:
        if getattr(exc, "sqlite_errorcode", None) != sqlite3.SQLITE_CANTOPEN:
            return None  # (locked, damaged...: the reader reports it)
        return (f"'{path}': its write-ahead log '{wal.name}' ({size} bytes) cannot be read here "
                f"(SQLite must create '{Path(path).name}-shm' beside it: a read-only folder?), "
                "so its last committed edits would be missing; copy the file with its -wal to a "
                "writable folder, or open it once where it is writable")
    return None


def summarise(path: str | Path) -> list[dict[str, Any]] | None:
    """The layers of the GeoPackage ``path`` as ``vector:info`` describes them (``name``,
    ``crs``, ``fields``, ``features``, ``geometry_types``, ``empty_or_null``, ``invalid``,
    ``bounds``, ``has_z`` and ``z_range`` when it has Z), or None when this module cannot be
    certain of OGR's and shapely's answer (see the module's docstring)."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            if f.read(16) != b"SQLite format 3\x00":
                return None
        con = connect_read_only(path)
    except (OSError, sqlite3.Error):
        return None
    try:
        return _summarise(con)
    except (Uncertain, sqlite3.Error, struct.error, ValueError, TypeError, OverflowError):
        return None
    finally:
        con.close()


def _one(con: sqlite3.Connection, sql: str) -> Any:
    row = con.execute(sql).fetchone()
    return None if row is None else row[0]


def _summarise(con: sqlite3.Connection) -> list[dict[str, Any]]:
    con.execute("BEGIN")  # one read transaction: every statement sees the same snapshot
    application_id, user_version = _one(con, "PRAGMA application_id"), \
        _one(con, "PRAGMA user_version")
    if application_id not in _APPLICATION_IDS or (
            _APPLICATION_IDS[application_id] is not None
            and user_version not in _APPLICATION_IDS[application_id]):
        raise Uncertain
    tables = dict(con.execute("SELECT name, type FROM sqlite_master"))
    if "gpkgext_relations" in tables or "gpkg_geometry_columns" not in tables:
        raise Uncertain
    has_attributes = _one(con, "SELECT 1 FROM gpkg_contents WHERE data_type = 'attributes' "
                          "LIMIT 1") == 1
    if "gpkg_extensions" in tables:
        extensions = {str(row[0]) for row in con.execute(
            "SELECT DISTINCT extension_name FROM gpkg_extensions")}
        if extensions - _KNOWN_EXTENSIONS:  # gdal_aspatial too: it changes the listing
            raise Uncertain
    sql = _LAYERS_SQL + ("" if has_attributes else _UNREGISTERED_SQL) + \
        f" LIMIT {MAX_LAYERS + 1}"
    rows = con.execute(sql).fetchall()
    names = [str(row[0]) for row in rows]
    if not rows or len(rows) > MAX_LAYERS or len(set(names)) != len(names) \
            or any(row[0] is None or row[5] != "table" for row in rows):
        raise Uncertain  # no layer (OGR refuses it), views, doubles, missing tables
    srs_rows = con.execute("SELECT srs_id, organization, organization_coordsys_id, definition "
                           "FROM gpkg_spatial_ref_sys").fetchall()
    crs_of = {row[0]: epsg_label(*row) for row in srs_rows}
    budget = [MAX_POINTS]
    layers = []
    for name, spatial, column, m, srs_id, _ in rows:
        layers.append(_layer(con, str(name), bool(spatial), column, m, srs_id, crs_of, budget))
    return layers


def _quote(identifier: str) -> str:
    return '"' + identifier.replace('"', '""') + '"'


def _fields(con: sqlite3.Connection, table: str, geometry: str | None) -> dict[str, str]:
    """``{field: dtype}`` as pyogrio reports the table's fields (its FID and geometry columns
    left out); :class:`Uncertain` for anything else than one INTEGER PRIMARY KEY and columns of
    the known declared types."""
    row = con.execute("SELECT sql FROM sqlite_master WHERE name = ? AND type = 'table'",
                      (table,)).fetchone()
    sql = None if row is None else row[0]
    if sql is None or re.search(r"\bVIRTUAL\b|\bWITHOUT\s+ROWID\b", str(sql), re.IGNORECASE):
        raise Uncertain
    columns = con.execute("SELECT name, type, pk, hidden FROM pragma_table_xinfo(?)",
                          (table,)).fetchall()
    keys = [c for c in columns if c[2]]
    if len(keys) != 1 or str(keys[0][1]).upper() != "INTEGER" or any(c[3] for c in columns):
        raise Uncertain
    found_geometry = geometry is None
    fields = {}
    for name, declared, pk, _ in columns:
        if pk:
            continue
        if geometry is not None and name == geometry:
            found_geometry = True
            continue
        kind = str(declared or "").upper()
        kind = _SIZED.fullmatch(kind).group(1) if _SIZED.fullmatch(kind) else kind
        if kind not in FIELD_TYPES:
            raise Uncertain  # OGR warns and reads it as text: left to it
        fields[str(name)] = FIELD_TYPES[kind]
    if not found_geometry:
        raise Uncertain
    return fields


def _layer(con: sqlite3.Connection, name: str, spatial: bool, column: Any, m: Any,
           srs_id: Any, crs_of: dict, budget: list[int]) -> dict[str, Any]:
    if spatial and (m not in (0, "0") or crs_of.get(srs_id) is None):
        raise Uncertain  # measured (pyogrio warns), a CRS that is not a plain EPSG code
    fields = _fields(con, name, str(column) if spatial else None)
    out: dict[str, Any] = {"name": name, "crs": crs_of[srs_id] if spatial else "none",
                           "fields": fields}
    count = int(_one(con, f"SELECT COUNT(*) FROM {_quote(name)}"))
    if not spatial:
        return out | {"features": count, "geometry_types": [], "empty_or_null": count,
                      "invalid": 0, "bounds": None, "has_z": False}
    budget[0] -= count
    if budget[0] < 0:
        raise Uncertain  # many points: numpy decodes them faster (MAX_POINTS)
    return out | _points(con.execute(f"SELECT {_quote(str(column))} FROM {_quote(name)}"))


def _point_format(wkb_head: bytes) -> tuple[struct.Struct, bool]:
    """The coordinates' struct and whether they hold Z, from the WKB's byte order and type."""
    order = {0: ">", 1: "<"}.get(wkb_head[0]) if len(wkb_head) == 5 else None
    if order is None:
        raise Uncertain
    kind = struct.unpack(order + "I", wkb_head[1:5])[0]
    has_z = {1: False, 1001: True, 0x80000001: True}.get(kind)
    if has_z is None:
        raise Uncertain  # not a Point, or M: the general path
    return struct.Struct(order + ("ddd" if has_z else "dd")), has_z


def _wkb_start(head: bytes) -> int:
    """Where the WKB starts in a GeoPackage binary blob of header ``head`` (its first 4 bytes);
    :class:`Uncertain` for anything but a standard, non-empty one."""
    flags = head[3] if len(head) == 4 else 0xFF
    if head[:3] != b"GP\x00" or flags & 0b11110000 or (flags >> 1) & 7 not in _ENVELOPE_BYTES:
        raise Uncertain  # not GeoPackage binary 0; extended, empty, reserved bits
    return 8 + _ENVELOPE_BYTES[(flags >> 1) & 7]


#: rows decoded at once (bounds the memory: the blobs of a chunk, then their coordinates)
_CHUNK = 65536


def _points(cursor) -> dict[str, Any]:
    """Count, nulls, bounds and Z range of a column of GeoPackage binary Points, read by
    chunks; a chunk whose blobs share their header, WKB type and length (a layer one program
    wrote) is decoded at once (slices taken by ``map``, no Python loop), another point by
    point."""
    xs, ys, zs = array.array("d"), array.array("d"), array.array("d")
    count = nulls = 0
    while rows := cursor.fetchmany(_CHUNK):
        blobs = [row[0] for row in rows if row[0] is not None]
        count += len(rows)
        nulls += len(rows) - len(blobs)
        if set(map(type, blobs)) - {bytes}:
            raise Uncertain  # text or numbers in the geometry column
        if not _decode_uniform(blobs, xs, ys, zs):
            _decode_each(blobs, xs, ys, zs)
    return _point_summary(count, nulls, xs, ys, zs)


def _decode_uniform(blobs: list[bytes], xs, ys, zs) -> bool:
    """Append the coordinates of ``blobs`` when they share their header, WKB type and length;
    False (nothing appended) otherwise."""
    if not blobs or len(set(map(len, blobs))) != 1:
        return not blobs
    heads = set(map(itemgetter(slice(0, 4)), blobs))
    if len(heads) != 1:
        return False
    start = _wkb_start(heads.pop())
    wkb_heads = set(map(itemgetter(slice(start, start + 5)), blobs))
    if len(wkb_heads) != 1:
        return False
    unpack, has_z = _point_format(wkb_heads.pop())
    if len(blobs[0]) != start + 5 + unpack.size:
        raise Uncertain
    values = array.array("d")
    values.frombytes(b"".join(map(itemgetter(slice(start + 5, None)), blobs)))
    if (unpack.format[0] == "<") != (sys.byteorder == "little"):
        values.byteswap()
    dims = 3 if has_z else 2
    xs.extend(values[0::dims])
    ys.extend(values[1::dims])
    if has_z:
        zs.extend(values[2::dims])
    return True


def _decode_each(blobs: list[bytes], xs, ys, zs) -> None:
    """Append the coordinates of ``blobs``, one by one."""
    starts: dict[bytes, int] = {}
    formats: dict[bytes, tuple[struct.Struct, bool]] = {}
    for blob in blobs:
        head = blob[:4]
        start = starts.get(head)
        if start is None:
            start = starts[head] = _wkb_start(head)
        wkb_head = blob[start:start + 5]
        fmt = formats.get(wkb_head)
        if fmt is None:
            fmt = formats[wkb_head] = _point_format(wkb_head)
        unpack, has_z = fmt
        if len(blob) != start + 5 + unpack.size:
            raise Uncertain
        xyz = unpack.unpack_from(blob, start + 5)
        xs.append(xyz[0])
        ys.append(xyz[1])
        if has_z:
            zs.append(xyz[2])


def _point_summary(count: int, nulls: int, xs, ys, zs) -> dict[str, Any]:
    """The summary of ``count`` features, ``nulls`` of them without a geometry, the others
    points at ``xs``, ``ys`` (and ``zs`` for those with Z)."""
    if not (all(map(math.isfinite, xs)) and all(map(math.isfinite, ys))
            and all(map(math.isfinite, zs))):
        raise Uncertain  # NaN/inf: the general path refuses or reports them
    summary: dict[str, Any] = {
        "features": count, "geometry_types": ["Point"] if xs else [], "empty_or_null": nulls,
        "invalid": 0, "bounds": [min(xs), min(ys), max(xs), max(ys)] if xs else None,
        "has_z": bool(zs)}
    if zs:
        summary["z_range"] = [min(zs), max(zs)]
    return summary


class GpkgSummary:
    """A GeoPackage input that :func:`summarise` described (``layers``), standing for the
    :class:`~toolbox.io.vector.VectorLayerRef` that :func:`~toolbox.io.vector.open_layer` would
    give for the same path: its ``path``, ``layer`` (the first layer when the file has several,
    as OGR's default), ``info`` (that layer's ``crs`` label or None, the ``driver``), ``crs``
    and :meth:`as_text` as the run report records them."""

    frame = None

    def __init__(self, path: Path, layers: list[dict[str, Any]]):
        self.path = path
        self.layers = layers
        self.layer = layers[0]["name"] if len(layers) > 1 else None
        crs = layers[0]["crs"]
        self.info = {"driver": "GPKG", "crs": None if crs == "none" else crs}

    @property
    def crs(self):
        from pyproj import CRS

        crs = self.info["crs"]
        return None if crs is None else CRS.from_user_input(crs)

    def as_text(self) -> str:
        return f"{self.path}|layername={self.layer}" if self.layer else str(self.path)

    def __str__(self) -> str:
        return f"'{self.as_text()}'"
