"""Default styles of the output layers an algorithm declares styled (``Layer(..., style=NAME)``):
one QML + SLD pair per style name, embedded in the GeoPackage's ``layer_styles`` table so QGIS
opens the layer styled. The runner writes them (:func:`write_declared_styles`) on the staged
GeoPackage of every output that declares one; beside a one-layer-per-file output (Shapefile,
GeoJSON, FlatGeobuf, GeoParquet), which has no style table, as ``<layer file stem>.qml`` /
``.sld`` (:func:`write_declared_style_files`), the default style QGIS loads with the file.

- ``areas``: light fill, thin dark outline;
- ``errors``: markers (point layers) or lines (line layers) categorised on ``severity``: red
  ``error``, orange ``fixable``, grey ``fixed``;
- ``footprints``: outline only, one colour;
- ``residuals``: markers categorised on ``role``: blue ``control``, green ``check``, red
  ``rejected``;
- ``tin_slope``: triangles graduated on ``slope_deg`` in 5 classes, green (flat) to red (steep),
  no outline.

``contours`` is written by carto:contours itself (:mod:`toolbox.cartography.qml`, rule-based
with labels); a style name not in :data:`STYLES` is left to its algorithm.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Iterable
from contextlib import closing
from pathlib import Path

from toolbox.styles.model import MARKER_SIZE_MM, CodeStyle, LayerStyle

DARK = (60, 60, 60)
RED, ORANGE, GREY = (227, 26, 28), (255, 127, 0), (150, 150, 150)
BLUE, GREEN = (31, 120, 180), (51, 160, 44)
ERROR_LINE_MM = 0.6
FOOTPRINT_MM = 0.5
#: slope classes of ``tin_slope``, degrees (upper ends included), and their fills
SLOPE_CLASSES = [(0.0, 5.0), (5.0, 10.0), (10.0, 20.0), (20.0, 35.0), (35.0, 90.0)]
SLOPE_RGB = [(26, 150, 65), (166, 217, 106), (255, 255, 191), (253, 174, 97), (215, 25, 28)]
#: GeoPackage geometry type names -> style kinds
KINDS = {"POINT": "point", "MULTIPOINT": "point", "LINESTRING": "line",
         "MULTILINESTRING": "line", "CIRCULARSTRING": "line", "COMPOUNDCURVE": "line",
         "MULTICURVE": "line", "POLYGON": "polygon", "MULTIPOLYGON": "polygon",
         "CURVEPOLYGON": "polygon", "MULTISURFACE": "polygon"}


def _value_style(value: str, kind: str, rgb: tuple[int, int, int], size: float = 2.5,
                 width: float = ERROR_LINE_MM) -> CodeStyle:
    """A filled marker (points) or a line of one attribute value."""
    if kind == "line":
        return CodeStyle(value, "line", rgb, width, None, value)
    return CodeStyle(value, "point", rgb, 0.2, (*rgb, 255), value, size)


def areas_style(layer: str, kind: str | None) -> LayerStyle:
    """Polygons: a light fill (alpha 128) with a thin dark outline."""
    return LayerStyle(layer, "polygon", [
        CodeStyle(layer, "polygon", DARK, 0.26, (255, 236, 170, 128), "area")])


def errors_style(layer: str, kind: str | None) -> LayerStyle:
    """Markers or lines (``kind``) by ``severity``: error red, fixable orange, fixed grey."""
    kind = "line" if kind == "line" else "point"
    return LayerStyle(layer, kind, [
        _value_style("error", kind, RED, 3.0), _value_style("fixable", kind, ORANGE, 3.0),
        _value_style("fixed", kind, GREY, 3.0)], field="severity")


def footprints_style(layer: str, kind: str | None) -> LayerStyle:
    """Polygons drawn as their outline only (a transparent fill)."""
    return LayerStyle(layer, "polygon", [
        CodeStyle(layer, "polygon", BLUE, FOOTPRINT_MM, (*BLUE, 0), "footprint")])


def residuals_style(layer: str, kind: str | None) -> LayerStyle:
    """Points by ``role``: control blue, check green, rejected red."""
    return LayerStyle(layer, "point", [
        _value_style("control", "point", BLUE, MARKER_SIZE_MM),
        _value_style("check", "point", GREEN, MARKER_SIZE_MM),
        _value_style("rejected", "point", RED, 3.0)], field="role")


def tin_slope_style(layer: str, kind: str | None) -> LayerStyle:
    """Triangles graduated on ``slope_deg`` (:data:`SLOPE_CLASSES`), no outline."""
    styles = [CodeStyle(f"slope_{k}", "polygon", rgb, 0.0, (*rgb, 255),
                        f"{lower:g} - {upper:g}°")
              for k, ((lower, upper), rgb) in enumerate(zip(SLOPE_CLASSES, SLOPE_RGB))]
    return LayerStyle(layer, "polygon", styles, field="slope_deg", ranges=SLOPE_CLASSES)


#: style name -> (layer name, kind of its geometry or None) -> LayerStyle
STYLES: dict[str, Callable[[str, str | None], LayerStyle]] = {
    "areas": areas_style, "errors": errors_style, "footprints": footprints_style,
    "residuals": residuals_style, "tin_slope": tin_slope_style}


def declared_style(style: str, layer: str, kind: str | None) -> tuple[str, str]:
    """The (QML, SLD) texts of style ``style`` for ``layer`` of geometry ``kind`` ("point",
    "line", "polygon"; None: unknown, the style's own)."""
    from toolbox.styles.qml import qml_document
    from toolbox.styles.sld import sld_document

    model = STYLES[style](layer, kind)
    return qml_document(model), sld_document(model)


def _layer_kinds(gpkg: Path) -> dict[str, str | None]:
    """Spatial layer of the GeoPackage -> its kind (None for a generic geometry type)."""
    with closing(sqlite3.connect(gpkg)) as db:
        rows = db.execute("SELECT table_name, geometry_type_name FROM gpkg_geometry_columns")
        return {name: KINDS.get(str(gtype).upper()) for name, gtype in rows}


def write_declared_styles(gpkg: str | Path, layers: Iterable[tuple[str, str]]) -> list[str]:
    """Embed, as its default, the style of each ``(layer, style name)`` whose layer is a spatial
    layer of the GeoPackage ``gpkg`` and whose style is in :data:`STYLES` (others are skipped).
    Returns the layers styled."""
    from toolbox.styles.gpkg import write_layer_styles

    wanted = [(layer, style) for layer, style in layers if style in STYLES]
    if not wanted:
        return []
    kinds = _layer_kinds(Path(gpkg))
    done = []
    for layer, style in wanted:
        if layer not in kinds:
            continue
        qml, sld = declared_style(style, layer, kinds[layer])
        write_layer_styles(gpkg, layer, qml, sld, default=True,
                           description=f"{style}: the toolbox's default style")
        done.append(layer)
    return done


def _kind(geometry_type: str | None) -> str | None:
    """The style kind of an OGR geometry type (``"Polygon Z"``, ``"PolygonZ"`` -> polygon)."""
    return KINDS.get(str(geometry_type or "").upper().removesuffix(" Z").removesuffix("Z")
                     .strip())


def style_file_names(layer_file: Path) -> list[Path]:
    """The default style files QGIS reads beside a one-layer file: ``<stem>.qml``, ``.sld``."""
    return [layer_file.with_suffix(".qml"), layer_file.with_suffix(".sld")]


def write_declared_style_files(path: str | Path,
                               layers: Iterable[tuple[str, str | None, str | None]]
                               ) -> list[Path]:
    """Write beside each layer file of the one-layer-per-file output ``path`` (the layers it
    declares, in order, as ``(layer, style name or None, declared geometry type)``: the first
    in ``path``, the others in their sibling files) whose style is in :data:`STYLES` the style's
    QML and SLD as ``<layer file stem>.qml`` / ``.sld``; a layer file not written is skipped.
    A Shapefile's style names the fields it references as the file holds them (cut to 10
    characters). Returns the files written."""
    from toolbox.io.vector_write import layer_paths
    from toolbox.styles.files import write_layer_style_files
    from toolbox.styles.qml import qml_document
    from toolbox.styles.sld import sld_document

    layers = list(layers)
    targets = layer_paths(Path(path), [name for name, _, _ in layers])
    written: list[Path] = []
    for name, style, geometry_type in layers:
        target = targets[name]
        if style not in STYLES or not target.is_file():
            continue
        kind = _kind(geometry_type)
        if kind is not None and _file_kind(target) not in (kind, None):
            continue  # the file holds another layer (written in another order): not its style
        model = STYLES[style](name, kind)
        write_layer_style_files(target, qml_document(model), sld_document(model),
                                referenced=[model.field, model.label_field])
        written += style_file_names(target)
    return written


def _file_kind(path: Path) -> str | None:
    """The style kind of the one layer of ``path`` (None: unknown, generic or no geometry);
    through the toolbox's reader, which reads GeoParquet's metadata with pyarrow (GDAL's
    attempt at a .parquet may need its ADBC driver's libduckdb)."""
    from toolbox.io.vector import open_layer

    return _kind(open_layer(path, "OUTPUT").geometry_type)
