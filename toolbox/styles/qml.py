"""QGIS 3 layer style (QML) of a :class:`~toolbox.styles.model.LayerStyle`.

The document has what QGIS reads: ``<renderer-v2 type="singleSymbol">`` or
``type="categorizedSymbol" attr="code"`` with ``<categories>`` (value, symbol, label) and
``<symbols>``; each ``<symbol type="marker|line|fill">`` holds one symbol layer (SimpleMarker,
SimpleLine, SimpleFill) whose properties are written both as ``<Option type="Map">`` (QGIS >=
3.18) and as ``<prop k v>`` (older readers); ``<labeling type="simple">`` when labelled.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from toolbox.styles.model import CodeStyle, LayerStyle

QGIS_VERSION = "3.22.0-Białowieża"
SYMBOL_TYPES = {"point": "marker", "line": "line", "polygon": "fill"}
GEOMETRY_TYPES = {"point": "0", "line": "1", "polygon": "2"}  # QgsWkbTypes::GeometryType


def _rgba(rgb: tuple[int, ...], alpha: int = 255) -> str:
    return ",".join(str(int(c)) for c in (*rgb[:3], rgb[3] if len(rgb) > 3 else alpha))


def _properties(style: CodeStyle) -> tuple[str, dict[str, str]]:
    if style.kind == "line":
        return "SimpleLine", {
            "line_color": _rgba(style.rgb), "line_style": "solid",
            "line_width": f"{style.line_width:g}", "line_width_unit": "MM",
            "capstyle": "round", "joinstyle": "round"}
    if style.kind == "polygon":
        return "SimpleFill", {
            "color": _rgba(style.fill or style.rgb), "style": "solid",
            "outline_color": _rgba(style.rgb), "outline_style": "solid",
            "outline_width": f"{style.line_width:g}", "outline_width_unit": "MM",
            "joinstyle": "miter"}
    return "SimpleMarker", {
        "color": _rgba(style.fill or style.rgb), "name": "circle",
        "size": f"{style.size:g}", "size_unit": "MM", "outline_color": "35,35,35,255",
        "outline_style": "solid", "outline_width": f"{style.line_width:g}",
        "outline_width_unit": "MM", "angle": "0"}


def _symbol(parent: ET.Element, tag: str, name: str, style: CodeStyle) -> None:
    symbol = ET.SubElement(parent, tag, {"type": SYMBOL_TYPES[style.kind], "name": name,
                                         "alpha": "1", "clip_to_extent": "1",
                                         "force_rhr": "0"})
    layer_class, props = _properties(style)
    layer = ET.SubElement(symbol, "layer", {"class": layer_class, "pass": "0", "locked": "0",
                                            "enabled": "1"})
    option = ET.SubElement(layer, "Option", {"type": "Map"})
    for key, value in props.items():
        ET.SubElement(option, "Option", {"name": key, "value": value, "type": "QString"})
    for key, value in props.items():
        ET.SubElement(layer, "prop", {"k": key, "v": value})


def _labeling(root: ET.Element, field: str, kind: str) -> None:
    labeling = ET.SubElement(root, "labeling", {"type": "simple"})
    settings = ET.SubElement(labeling, "settings", {"calloutType": "simple"})
    ET.SubElement(settings, "text-style", {
        "fieldName": field, "isExpression": "0", "fontFamily": "Sans Serif", "fontSize": "8",
        "fontSizeUnit": "Point", "textColor": "0,0,0,255", "textOpacity": "1",
        "namedStyle": "Regular", "multilineHeight": "1"})
    buffer = ET.SubElement(settings, "text-buffer")
    buffer.attrib.update({"bufferDraw": "1", "bufferSize": "0.8", "bufferSizeUnits": "MM",
                          "bufferColor": "255,255,255,255", "bufferOpacity": "1"})
    # placement: around a point (6 = OrderedPositionsAroundPoint), inside a polygon (1 = OverPoint
    # at the centroid), along a line (2 = Line)
    placement = {"point": "6", "polygon": "1", "line": "2"}[kind]
    ET.SubElement(settings, "placement", {"placement": placement, "dist": "1",
                                          "distUnits": "MM", "centroidInside": "1"})
    ET.SubElement(settings, "rendering", {"scaleVisibility": "0", "obstacle": "1",
                                          "displayAll": "0", "fontLimitPixelSize": "0"})


def qml_document(layer: LayerStyle) -> str:
    """The QML text (UTF-8 XML with the QGIS doctype) of one layer style."""
    root = ET.Element("qgis", {"version": QGIS_VERSION, "styleCategories": "Symbology|Labeling",
                               "labelsEnabled": "1" if layer.label_field else "0"})
    if layer.categorised:
        renderer = ET.SubElement(root, "renderer-v2", {
            "type": "categorizedSymbol", "attr": layer.field, "symbollevels": "0",
            "enableorderby": "0", "forceraster": "0", "referencescale": "-1"})
        categories = ET.SubElement(renderer, "categories")
        for k, style in enumerate(layer.styles):
            ET.SubElement(categories, "category", {
                "value": style.code, "symbol": str(k), "render": "true",
                "label": f"{style.code} {style.label}".strip() if style.label != style.code
                else style.code})
        symbols = ET.SubElement(renderer, "symbols")
        for k, style in enumerate(layer.styles):
            _symbol(symbols, "symbol", str(k), style)
        source = ET.SubElement(renderer, "source-symbol")
        _symbol(source, "symbol", "0", layer.styles[0])
    else:
        renderer = ET.SubElement(root, "renderer-v2", {
            "type": "singleSymbol", "symbollevels": "0", "enableorderby": "0",
            "forceraster": "0", "referencescale": "-1"})
        symbols = ET.SubElement(renderer, "symbols")
        _symbol(symbols, "symbol", "0", layer.styles[0])
    if layer.label_field:
        _labeling(root, layer.label_field, layer.kind)
    ET.SubElement(root, "layerGeometryType").text = GEOMETRY_TYPES[layer.kind]
    ET.indent(root)
    body = ET.tostring(root, encoding="unicode")
    return "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n" + body + "\n"
