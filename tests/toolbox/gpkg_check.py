"""A GeoPackage 1.2 conformance check for the tests, equivalent in scope to the vector part of
GDAL's ``validate_gpkg.py`` (written from the GeoPackage 1.2 specification, not copied).

:func:`gpkg_problems` returns a list of human-readable problems (empty = valid): file header
(application id ``GPKG``, user version 10200), SQLite integrity and foreign keys, the required
tables with their columns, the three required SRS rows, ``gpkg_contents`` entries, feature tables
(one INTEGER PRIMARY KEY, geometry column declared once, allowed column types), every geometry
blob's header (magic, version, flags, SRS id, WKB type matching the declared type, Z flag), the
R-tree extension (declared ``write-only``; insert, update1-4 and delete triggers) and
``gpkg_extensions`` (known names or ``author_name``, valid scopes).
"""

from __future__ import annotations

import re
import sqlite3
import struct
import subprocess
from pathlib import Path

APPLICATION_ID = int.from_bytes(b"GPKG", "big")
USER_VERSION_1_2 = 10200

# (name, type, not null, primary key) of the required tables (GeoPackage 1.2, tables 1, 2, 3, 6)
SRS_COLUMNS = [("srs_name", "TEXT", 1, 0), ("srs_id", "INTEGER", 1, 1),
               ("organization", "TEXT", 1, 0), ("organization_coordsys_id", "INTEGER", 1, 0),
               ("definition", "TEXT", 1, 0), ("description", "TEXT", 0, 0)]
CONTENTS_COLUMNS = [("table_name", "TEXT", 1, 1), ("data_type", "TEXT", 1, 0),
                    ("identifier", "TEXT", 0, 0), ("description", "TEXT", 0, 0),
                    ("last_change", "DATETIME", 1, 0), ("min_x", "DOUBLE", 0, 0),
                    ("min_y", "DOUBLE", 0, 0), ("max_x", "DOUBLE", 0, 0),
                    ("max_y", "DOUBLE", 0, 0), ("srs_id", "INTEGER", 0, 0)]
GEOMETRY_COLUMNS = [("table_name", "TEXT", 1, 1), ("column_name", "TEXT", 1, 2),
                    ("geometry_type_name", "TEXT", 1, 0), ("srs_id", "INTEGER", 1, 0),
                    ("z", "TINYINT", 1, 0), ("m", "TINYINT", 1, 0)]
EXTENSIONS_COLUMNS = [("table_name", "TEXT", 0, 0), ("column_name", "TEXT", 0, 0),
                      ("extension_name", "TEXT", 1, 0), ("definition", "TEXT", 1, 0),
                      ("scope", "TEXT", 1, 0)]
WKB_TYPES = ["GEOMETRY", "POINT", "LINESTRING", "POLYGON", "MULTIPOINT", "MULTILINESTRING",
             "MULTIPOLYGON", "GEOMETRYCOLLECTION"]
COLUMN_TYPES = {"BOOLEAN", "TINYINT", "SMALLINT", "MEDIUMINT", "INT", "INTEGER", "FLOAT",
                "DOUBLE", "REAL", "TEXT", "BLOB", "DATE", "DATETIME"}
KNOWN_EXTENSIONS = {"gpkg_rtree_index", "gpkg_zoom_other", "gpkg_webp", "gpkg_metadata",
                    "gpkg_schema", "gpkg_crs_wkt", "gpkg_crs_wkt_1_1", "gpkg_related_tables",
                    "gpkg_2d_gridded_coverage"}


SYSTEM_VALIDATOR = Path("/usr/lib/python3/dist-packages/osgeo_utils/samples/validate_gpkg.py")


def gdal_validator_problems(path: Path) -> str:
    """GDAL's own validate_gpkg.py (Debian's python3-gdal) on ``path``: '' when it accepts it
    (or when Debian's GDAL is not installed)."""
    if not (SYSTEM_VALIDATOR.exists() and Path("/usr/bin/python3").exists()):
        return ""
    result = subprocess.run(["/usr/bin/python3", str(SYSTEM_VALIDATOR), str(path)],
                            capture_output=True, text=True, timeout=60)
    return "" if result.returncode == 0 else (result.stdout + result.stderr)[-300:]


def _columns(c, table: str) -> list[tuple]:
    return [(name, typ, notnull, pk) for _, name, typ, notnull, _, pk in
            c.execute(f'PRAGMA table_info("{table}")').fetchall()]


def _check_columns(c, table: str, expected: list[tuple], problems: list[str],
                   optional: tuple[str, ...] = ()) -> None:
    found = {name: (typ, notnull, pk) for name, typ, notnull, pk in _columns(c, table)}
    if not found:
        problems.append(f"table {table} is missing")
        return
    for name, typ, notnull, pk in expected:
        if name not in found:
            problems.append(f"{table}: column {name} missing")
            continue
        got_type, got_notnull, got_pk = found[name]
        if typ == "INTEGER" and pk:
            got_notnull = notnull  # an INTEGER PRIMARY KEY is implicitly NOT NULL
        if (got_type, got_notnull, bool(got_pk)) != (typ, notnull, bool(pk)):
            problems.append(f"{table}.{name}: {got_type} notnull={got_notnull} pk={got_pk}, "
                            f"expected {typ} notnull={notnull} pk={pk}")
    extra = set(found) - {e[0] for e in expected} - set(optional)
    if extra:
        problems.append(f"{table}: unexpected columns {sorted(extra)}")


def _header(path: Path) -> tuple[int, int]:
    with open(path, "rb") as f:
        head = f.read(100)
    return struct.unpack(">I", head[68:72])[0], struct.unpack(">I", head[60:64])[0]


def _check_blob(blob: bytes, table: str, declared: str, srs_id: int, z: int,
                problems: list[str]) -> str | None:
    """Check one GeoPackageBinary header; returns the WKB base type name."""
    if len(blob) < 8 or blob[:2] != b"GP" or blob[2] != 0:
        problems.append(f"{table}: geometry blob without a GeoPackage header")
        return None
    flags = blob[3]
    if flags & 0b100000:
        problems.append(f"{table}: ExtendedGeoPackageBinary geometry")
    envelope = (flags >> 1) & 7
    if envelope > 4:
        problems.append(f"{table}: invalid envelope code {envelope}")
        return None
    empty = bool(flags & 0b1000)
    if empty and envelope:
        problems.append(f"{table}: empty geometry with an envelope")
    endian = "<" if flags & 1 else ">"
    if struct.unpack(endian + "i", blob[4:8])[0] != srs_id:
        problems.append(f"{table}: geometry SRS id differs from gpkg_geometry_columns ({srs_id})")
    start = 8 + 8 * {0: 0, 1: 4, 2: 6, 3: 6, 4: 8}[envelope]
    wkb_endian = "<" if blob[start] == 1 else ">"
    code = struct.unpack(wkb_endian + "I", blob[start + 1:start + 5])[0]
    base, dim = code % 1000, code // 1000
    if base >= len(WKB_TYPES):
        problems.append(f"{table}: WKB type {code} unknown")
        return None
    if dim in (1, 3) and z == 0:
        problems.append(f"{table}: Z in a geometry of a layer declared without Z")
    if z == 1 and dim not in (1, 3):
        problems.append(f"{table}: geometry without Z in a layer declared with Z")
    name = WKB_TYPES[base]
    if declared not in ("GEOMETRY", "GEOMETRYCOLLECTION") and name != declared:
        problems.append(f"{table}: {name} geometry in a layer declared {declared}")
    return name


def _check_features(c, problems: list[str]) -> None:
    _check_columns(c, "gpkg_geometry_columns", GEOMETRY_COLUMNS, problems)
    contents = dict(c.execute("SELECT table_name, srs_id FROM gpkg_contents "
                              "WHERE data_type = 'features'").fetchall())
    srs_ids = {row[0] for row in c.execute("SELECT srs_id FROM gpkg_spatial_ref_sys")}
    for table, contents_srs in contents.items():
        rows = c.execute("SELECT column_name, geometry_type_name, srs_id, z, m FROM "
                         "gpkg_geometry_columns WHERE table_name = ?", (table,)).fetchall()
        if len(rows) != 1:
            problems.append(f"{table}: {len(rows)} rows in gpkg_geometry_columns, expected 1")
            continue
        column, declared, srs_id, z, m = rows[0]
        if srs_id not in srs_ids:
            problems.append(f"{table}: srs_id {srs_id} not in gpkg_spatial_ref_sys")
        if srs_id != contents_srs:
            problems.append(f"{table}: srs_id {srs_id} in gpkg_geometry_columns, "
                            f"{contents_srs} in gpkg_contents")
        if z not in (0, 1, 2) or m not in (0, 1, 2):
            problems.append(f"{table}: z={z} m={m}, expected 0, 1 or 2")
        if declared not in WKB_TYPES:
            problems.append(f"{table}: geometry type {declared} needs an extension")
        cols = _columns(c, table)
        keys = [name for name, typ, _, pk in cols if pk]
        if len(keys) != 1 or dict((n, t) for n, t, _, _ in cols)[keys[0]] != "INTEGER":
            problems.append(f"{table}: needs exactly one INTEGER PRIMARY KEY, got {keys}")
        for name, typ, _, _ in cols:
            if name == column:
                if typ != declared:
                    problems.append(f"{table}.{name}: SQL type {typ}, declared {declared}")
            elif typ not in COLUMN_TYPES and not re.fullmatch(r"(TEXT|BLOB)\(\d+\)", typ):
                problems.append(f"{table}.{name}: column type {typ} not allowed")
        for (blob,) in c.execute(f'SELECT "{column}" FROM "{table}"'):
            if blob is not None:
                _check_blob(bytes(blob), table, declared, srs_id, z, problems)
        _check_rtree(c, table, column, problems)


def _check_rtree(c, table: str, column: str, problems: list[str]) -> None:
    rtree = f"rtree_{table}_{column}"
    if c.execute("SELECT 1 FROM sqlite_master WHERE name = ?", (rtree,)).fetchone() is None:
        return
    scope = c.execute("SELECT scope FROM gpkg_extensions WHERE extension_name = "
                      "'gpkg_rtree_index' AND table_name = ? AND column_name = ?",
                      (table, column)).fetchone()
    if scope is None or scope[0] != "write-only":
        problems.append(f"{rtree}: not declared write-only in gpkg_extensions")
    names = [row[1] for row in c.execute(f'PRAGMA table_info("{rtree}")').fetchall()]
    if names != ["id", "minx", "maxx", "miny", "maxy"]:
        problems.append(f"{rtree}: columns {names}")
    triggers = {row[0] for row in c.execute("SELECT name FROM sqlite_master WHERE "
                                            "type = 'trigger' AND name LIKE ?", (rtree + "_%",))}
    expected = {f"{rtree}_{s}" for s in ("insert", "update1", "update2", "update3", "update4",
                                         "delete")}
    if triggers != expected:  # GeoPackage 1.2: these six, no 1.4-style update5..7
        problems.append(f"{rtree}: triggers {sorted(triggers)}, expected {sorted(expected)}")


def _check_extensions(c, problems: list[str]) -> None:
    if c.execute("SELECT 1 FROM sqlite_master WHERE name = 'gpkg_extensions'").fetchone() is None:
        return
    _check_columns(c, "gpkg_extensions", EXTENSIONS_COLUMNS, problems)
    for table, column, name, scope in c.execute(
            "SELECT table_name, column_name, extension_name, scope FROM gpkg_extensions"):
        if name.startswith("gpkg_") and name not in KNOWN_EXTENSIONS:
            problems.append(f"extension {name} unknown to GeoPackage 1.2")
        if not name.startswith("gpkg_") and not re.fullmatch(r"[A-Za-z0-9]+_[A-Za-z0-9_]+", name):
            problems.append(f"extension name {name} is not author_name")
        if scope not in ("read-write", "write-only"):
            problems.append(f"extension {name}: scope {scope}")
        if table is not None and c.execute("SELECT 1 FROM sqlite_master WHERE name = ?",
                                           (table,)).fetchone() is None:
            problems.append(f"extension {name}: table {table} missing")
        elif table is not None and column is not None \
                and column not in {n for n, *_ in _columns(c, table)}:
            problems.append(f"extension {name}: column {table}.{column} missing")
    declared_wkt = c.execute("SELECT 1 FROM gpkg_extensions WHERE extension_name IN "
                             "('gpkg_crs_wkt', 'gpkg_crs_wkt_1_1')").fetchone() is not None
    has_column = "definition_12_063" in {n for n, *_ in _columns(c, "gpkg_spatial_ref_sys")}
    if has_column != declared_wkt:
        problems.append("gpkg_spatial_ref_sys.definition_12_063 and the gpkg_crs_wkt "
                        "extension must come together")


def gpkg_problems(path: str | Path) -> list[str]:
    """Every GeoPackage 1.2 conformance problem found in ``path`` (empty list: valid)."""
    path = Path(path)
    problems: list[str] = []
    if path.suffix.lower() != ".gpkg":
        problems.append("extension is not .gpkg")
    application_id, user_version = _header(path)
    if application_id != APPLICATION_ID:
        problems.append(f"application_id {application_id:#x}, expected 'GPKG'")
    if user_version != USER_VERSION_1_2:
        problems.append(f"user_version {user_version}, expected {USER_VERSION_1_2}")
    with sqlite3.connect(path) as conn:
        c = conn.cursor()
        if c.execute("PRAGMA integrity_check").fetchone()[0] != "ok":
            problems.append("SQLite integrity_check failed")
        if c.execute("PRAGMA foreign_key_check").fetchall():
            problems.append("foreign_key_check failed")
        _check_columns(c, "gpkg_spatial_ref_sys", SRS_COLUMNS, problems,
                       optional=("definition_12_063", "epoch"))
        rows = {r[0]: r[1:] for r in c.execute(
            "SELECT srs_id, organization, organization_coordsys_id, definition FROM "
            "gpkg_spatial_ref_sys WHERE srs_id IN (-1, 0, 4326)")}
        for srs_id in (-1, 0):
            if rows.get(srs_id) != ("NONE", srs_id, "undefined"):
                problems.append(f"gpkg_spatial_ref_sys row {srs_id}: {rows.get(srs_id)}")
        if 4326 not in rows or rows[4326][0].upper() != "EPSG" \
                or rows[4326][1] != 4326 or rows[4326][2] == "undefined":
            problems.append(f"gpkg_spatial_ref_sys row 4326: {rows.get(4326)}")
        _check_columns(c, "gpkg_contents", CONTENTS_COLUMNS, problems)
        srs_ids = {row[0] for row in c.execute("SELECT srs_id FROM gpkg_spatial_ref_sys")}
        for table, data_type, last_change, srs_id in c.execute(
                "SELECT table_name, data_type, last_change, srs_id FROM gpkg_contents"
        ).fetchall():
            if data_type not in ("features", "tiles", "attributes", "2d-gridded-coverage"):
                problems.append(f"gpkg_contents {table}: data_type {data_type}")
            if c.execute("SELECT 1 FROM sqlite_master WHERE lower(name) = lower(?) AND type IN "
                         "('table', 'view')", (table,)).fetchone() is None:
                problems.append(f"gpkg_contents {table}: no such table")
            if not re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?Z", str(last_change)):
                problems.append(f"gpkg_contents {table}: last_change {last_change!r}")
            if srs_id is not None and srs_id not in srs_ids:
                problems.append(f"gpkg_contents {table}: srs_id {srs_id} unknown")
        _check_features(c, problems)
        _check_extensions(c, problems)
    return problems
