"""A QGIS style (QML) for contour layers, and its embedding in a GeoPackage's ``layer_styles``
table so QGIS opens the layer styled: index contours heavier, elevations labelled along them.

A stop-gap until the shared style model (toolbox.styles) provides ``write_layer_styles``.
"""

from __future__ import annotations

import sqlite3
from datetime import UTC, datetime
from pathlib import Path
from xml.sax.saxutils import quoteattr

CONTOUR_RGB = (150, 90, 40)
WIDTH_MM = 0.18
INDEX_WIDTH_MM = 0.45


def _line_symbol(name: str, rgb: tuple[int, int, int], width_mm: float) -> str:
    colour = ",".join(str(v) for v in rgb) + ",255"
    return (f'<symbol type="line" name="{name}" alpha="1" clip_to_extent="1" force_rhr="0">'
            '<layer class="SimpleLine" enabled="1" locked="0" pass="0"><Option type="Map">'
            f'<Option name="line_color" type="QString" value="{colour}"/>'
            f'<Option name="line_width" type="QString" value="{width_mm}"/>'
            '<Option name="line_width_unit" type="QString" value="MM"/>'
            '<Option name="capstyle" type="QString" value="round"/>'
            '<Option name="joinstyle" type="QString" value="round"/>'
            '</Option></layer></symbol>')


def contour_qml(elev_field: str = "elev", index_field: str = "index",
                rgb: tuple[int, int, int] = CONTOUR_RGB) -> str:
    """QML: a rule-based renderer (index contours ``INDEX_WIDTH_MM`` wide, others ``WIDTH_MM``)
    and curved labels of ``elev_field`` along the index contours."""
    is_index = quoteattr(f'"{index_field}" = 1')
    label = quoteattr(f'CASE WHEN "{index_field}" = 1 THEN format_number("{elev_field}", 0) END')
    colour = ",".join(str(v) for v in rgb) + ",255"
    return (
        "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n"
        '<qgis version="3.28.0" styleCategories="Symbology|Labeling">'
        '<renderer-v2 type="RuleRenderer" symbollevels="0" enableorderby="0" forceraster="0">'
        '<rules key="root">'
        f'<rule key="index" filter={is_index} symbol="0" label="index contour"/>'
        '<rule key="normal" filter="ELSE" symbol="1" label="contour"/>'
        '</rules><symbols>'
        + _line_symbol("0", rgb, INDEX_WIDTH_MM) + _line_symbol("1", rgb, WIDTH_MM) +
        '</symbols></renderer-v2>'
        '<labeling type="simple"><settings calloutType="simple">'
        f'<text-style fieldName={label} isExpression="1" fontFamily="Sans Serif" fontSize="7" '
        f'fontSizeUnit="Point" textColor="{colour}" textOpacity="1">'
        '<text-buffer bufferDraw="1" bufferSize="0.8" bufferSizeUnits="MM" '
        'bufferColor="255,255,255,255" bufferOpacity="1"/></text-style>'
        '<placement placement="3" placementFlags="10" repeatDistance="60" '
        'repeatDistanceUnits="MM" maxCurvedCharAngleIn="25" maxCurvedCharAngleOut="-25"/>'
        '<rendering obstacle="1" scaleVisibility="0"/>'
        '</settings></labeling>'
        '<layerGeometryType>1</layerGeometryType></qgis>\n')


def embed_style(gpkg: str | Path, layer: str, qml: str, name: str | None = None) -> None:
    """Store ``qml`` as the default style of ``layer`` in the GeoPackage's ``layer_styles``
    table (the table QGIS reads; created and registered in ``gpkg_contents`` if missing)."""
    with sqlite3.connect(gpkg) as db:
        db.execute(
            "CREATE TABLE IF NOT EXISTS layer_styles (id INTEGER PRIMARY KEY AUTOINCREMENT, "
            "f_table_catalog TEXT(256), f_table_schema TEXT(256), f_table_name TEXT(256), "
            "f_geometry_column TEXT(256), styleName TEXT(30), styleQML TEXT, styleSLD TEXT, "
            "useAsDefault BOOLEAN, description TEXT, owner TEXT(30), ui TEXT(30), "
            "update_time DATETIME DEFAULT CURRENT_TIMESTAMP)")
        db.execute("INSERT OR IGNORE INTO gpkg_contents (table_name, data_type, identifier, "
                   "last_change) VALUES ('layer_styles', 'attributes', 'layer_styles', ?)",
                   (datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")[:-4] + "Z",))
        geom = db.execute("SELECT column_name FROM gpkg_geometry_columns WHERE table_name = ?",
                          (layer,)).fetchone()
        db.execute("UPDATE layer_styles SET useAsDefault = 0 WHERE f_table_name = ?", (layer,))
        db.execute("INSERT INTO layer_styles (f_table_catalog, f_table_schema, f_table_name, "
                   "f_geometry_column, styleName, styleQML, styleSLD, useAsDefault, description, "
                   "owner, ui) VALUES ('', '', ?, ?, ?, ?, '', 1, ?, '', '')",
                   (layer, geom[0] if geom else "geom", name or layer, qml,
                    "written by the toolbox"))
