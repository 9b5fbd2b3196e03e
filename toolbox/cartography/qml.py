"""The style of contour layers, for QGIS (QML) and OGC clients (SLD): index contours heavier,
elevations labelled along them. Embedded in the GeoPackage's ``layer_styles`` table with the
shared :func:`toolbox.styles.write_layer_styles`, so QGIS opens the layer styled.

The contour style is rule-based (on ``index``), which the per-code style model does not
express, so its documents are written here; colours and widths are the ones the map sheet
draws contours with.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import quoteattr

from toolbox.styles.gpkg import write_layer_styles
from toolbox.styles.sld import OGC, PIXEL_MM, SLD, _e, _param

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


def _sld_rule(parent: ET.Element, title: str, is_index: bool, index_field: str,
              elev_field: str, colour: str, width_mm: float) -> None:
    rule = _e(parent, "Rule")
    _e(rule, "Name", "index" if is_index else "normal")
    _e(rule, "Title", title)
    eq = _e(_e(rule, "Filter", ns=OGC),
            "PropertyIsEqualTo" if is_index else "PropertyIsNotEqualTo", ns=OGC)
    _e(eq, "PropertyName", index_field, ns=OGC)
    _e(eq, "Literal", "1", ns=OGC)
    stroke = _e(_e(rule, "LineSymbolizer"), "Stroke")
    _param(stroke, "CssParameter", "stroke", colour)
    _param(stroke, "CssParameter", "stroke-width", f"{width_mm / PIXEL_MM:.2f}")
    _param(stroke, "CssParameter", "stroke-linecap", "round")
    _param(stroke, "CssParameter", "stroke-linejoin", "round")
    if is_index:  # elevation labels along the index contours
        text = _e(rule, "TextSymbolizer")
        _e(_e(text, "Label"), "PropertyName", elev_field, ns=OGC)
        font = _e(text, "Font")
        _param(font, "CssParameter", "font-family", "Sans Serif")
        _param(font, "CssParameter", "font-size", "10")
        _e(_e(_e(text, "LabelPlacement"), "LinePlacement"), "PerpendicularOffset", "0")
        halo = _e(text, "Halo")
        _e(halo, "Radius", "1")
        _param(_e(halo, "Fill"), "CssParameter", "fill", "#ffffff")
        _param(_e(text, "Fill"), "CssParameter", "fill", colour)
        _param(text, "VendorOption", "followLine", "true")


def contour_sld(elev_field: str = "elev", index_field: str = "index",
                rgb: tuple[int, int, int] = CONTOUR_RGB, name: str = "contours") -> str:
    """SLD 1.0 of the same style: one rule for index contours (``index_field`` = 1, heavier,
    labelled along the line with ``elev_field``), one for the others."""
    colour = "#{:02x}{:02x}{:02x}".format(*rgb)
    root = ET.Element(f"{{{SLD}}}StyledLayerDescriptor", {"version": "1.0.0"})
    named = _e(root, "NamedLayer")
    _e(named, "Name", name)
    user = _e(named, "UserStyle")
    _e(user, "Name", name)
    _e(user, "Title", name)
    fts = _e(user, "FeatureTypeStyle")
    _sld_rule(fts, "index contour", True, index_field, elev_field, colour, INDEX_WIDTH_MM)
    _sld_rule(fts, "contour", False, index_field, elev_field, colour, WIDTH_MM)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") \
        + "\n"


def write_contour_style(gpkg: str | Path, layer: str = "contours") -> str:
    """Embed the contour QML and SLD as the default style of ``layer``; returns the QML."""
    qml = contour_qml()
    write_layer_styles(gpkg, layer, qml, contour_sld(name=layer), default=True,
                       description="contours: index contours heavier, labelled along them")
    return qml
