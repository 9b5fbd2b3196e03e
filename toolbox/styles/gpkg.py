"""Styles embedded in a GeoPackage: the ``layer_styles`` table QGIS reads and writes.

The table is the one QGIS creates (columns id, f_table_catalog, f_table_schema, f_table_name,
f_geometry_column, styleName, styleQML, styleSLD, useAsDefault, description, owner, ui,
update_time), registered in ``gpkg_contents`` as an attributes table so OGR (and so QGIS, which
reads it through OGR with ``f_table_schema = ''``) sees it. A layer's default style is the row
with ``useAsDefault`` true: QGIS applies it when the layer is opened.
"""

from __future__ import annotations

import sqlite3
from contextlib import closing
from pathlib import Path

from toolbox.io.source_date import gpkg_timestamp

CREATE = """CREATE TABLE layer_styles (
    id INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL,
    f_table_catalog TEXT(256), f_table_schema TEXT(256), f_table_name TEXT(256),
    f_geometry_column TEXT(256), styleName TEXT(30), styleQML TEXT, styleSLD TEXT,
    useAsDefault BOOLEAN, description TEXT, owner TEXT(30), ui TEXT(30),
    update_time DATETIME DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')))"""
NOW = "strftime('%Y-%m-%dT%H:%M:%fZ', 'now')"


def _geometry_column(db: sqlite3.Connection, layer: str) -> str:
    row = db.execute("SELECT column_name FROM gpkg_geometry_columns WHERE table_name = ?",
                     (layer,)).fetchone()
    if row is None:
        raise ValueError(f"'{layer}' is not a spatial layer of the GeoPackage")
    return row[0]


def write_layer_styles(gpkg_path: str | Path, layer: str, qml: str, sld: str | None = None,
                       default: bool = True, name: str | None = None,
                       description: str = "") -> None:
    """Store a style for ``layer`` (a spatial table of the GeoPackage) in ``layer_styles``.

    A row of the same layer and style name is replaced; with ``default`` the layer's other rows
    stop being the default.
    """
    name = name or layer
    stamp = gpkg_timestamp()  # SOURCE_DATE_EPOCH when set, else now (in SQLite)
    with closing(sqlite3.connect(gpkg_path)) as db, db:
        geometry_column = _geometry_column(db, layer)
        exists = db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = "
                            "'layer_styles'").fetchone()
        if not exists:
            db.execute(CREATE)
            db.execute(f"INSERT INTO gpkg_contents (table_name, data_type, identifier, "
                       f"description, last_change) VALUES ('layer_styles', 'attributes', "
                       f"'layer_styles', '', COALESCE(?, {NOW}))", (stamp,))
        if default:
            db.execute("UPDATE layer_styles SET useAsDefault = 0 WHERE f_table_name = ?",
                       (layer,))
        db.execute("DELETE FROM layer_styles WHERE f_table_name = ? AND styleName = ?",
                   (layer, name))
        db.execute("INSERT INTO layer_styles (f_table_catalog, f_table_schema, f_table_name, "
                   "f_geometry_column, styleName, styleQML, styleSLD, useAsDefault, "
                   f"description, owner, ui, update_time) VALUES ('', '', ?, ?, ?, ?, ?, ?, ?, "
                   f"'', NULL, COALESCE(?, {NOW}))",
                   (layer, geometry_column, name, qml, sld or "", 1 if default else 0,
                    description, stamp))


def read_layer_styles(gpkg_path: str | Path) -> list[dict]:
    """Rows of ``layer_styles`` as dicts (empty when the table does not exist)."""
    with closing(sqlite3.connect(gpkg_path)) as db:
        db.row_factory = sqlite3.Row
        if not db.execute("SELECT 1 FROM sqlite_master WHERE name = 'layer_styles'").fetchone():
            return []
        return [dict(row) for row in db.execute("SELECT * FROM layer_styles ORDER BY id")]
