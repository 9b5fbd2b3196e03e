"""QGIS 3 layer style (QML) of a :class:`~toolbox.styles.model.LayerStyle`.

The document has what QGIS reads: ``<renderer-v2 type="singleSymbol">``,
``type="categorizedSymbol" attr="code"`` with ``<categories>`` (value, symbol, label) or
``type="graduatedSymbol"`` with ``<ranges>`` (lower, upper, symbol, label), and ``<symbols>``;
each ``<symbol type="marker|line|fill">`` holds one symbol layer (SimpleMarker, SimpleLine,
SimpleFill) whose properties are written both as ``<Option type="Map">`` (QGIS >= 3.18) and as
``<prop k v>`` (older readers); ``<labeling type="simple">`` when labelled.
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
            "outline_color": _rgba(style.rgb),
            "outline_style": "solid" if style.line_width > 0 else "no",
            "outline_width": f"{style.line_width:g}", "outline_width_unit": "MM",
            "joinstyle": "miter"}
    return "SimpleMarker", {
        "color": _rgba(style.fill or style.rgb), "name": "circle",
        "size": f"{style.size:g}", "size_unit": "MM", "outline_color": "35,35,35,255",
        "outline_style": "solid", "outline_width": f"{style.line_width:g}",
        "outline_width_unit": "MM", "angle": "0"}


def _symbol(parent: ET.Element, tag: str, name: str, style: CodeStyle) -> None:
    layers = _symbology_layers(style) if style.symbol is not None else [(*_properties(style),
                                                                         None)]
    _write_symbol(parent, tag, name, SYMBOL_TYPES[style.kind], layers)


def _write_symbol(parent: ET.Element, tag: str, name: str, symbol_type: str,
                  layers: list) -> None:
    """A ``<symbol>`` of ``layers``: (class, props, sub-symbol layers or None), bottom first."""
    symbol = ET.SubElement(parent, tag, {"type": symbol_type, "name": name, "alpha": "1",
                                         "clip_to_extent": "1", "force_rhr": "0"})
    for k, (layer_class, props, sub) in enumerate(layers):
        layer = ET.SubElement(symbol, "layer", {"class": layer_class, "pass": "0",
                                                "locked": "0", "enabled": "1"})
        option = ET.SubElement(layer, "Option", {"type": "Map"})
        for key, value in props.items():
            ET.SubElement(option, "Option", {"name": key, "value": value, "type": "QString"})
        for key, value in props.items():
            ET.SubElement(layer, "prop", {"k": key, "v": value})
        if sub is not None:  # the line a hatching or a hash line draws with
            _write_symbol(layer, "symbol", f"@{name}@{k}", "line", sub)


def _line(rgb: tuple[int, ...], width: float, linetype: str = "continuous") -> tuple:
    from toolbox.styles.symbology import DASHES

    props = {"line_color": _rgba(rgb), "line_style": "solid", "line_width": f"{width:g}",
             "line_width_unit": "MM", "capstyle": "round", "joinstyle": "round",
             "use_custom_dash": "0"}
    if linetype in DASHES:  # the pattern in mm of paper, flat caps (as the sheet draws it)
        props.update(use_custom_dash="1", customdash=";".join(f"{v:g}" for v in
                                                             DASHES[linetype]),
                     customdash_unit="MM", capstyle="flat")
    return "SimpleLine", props, None


def _ticks(rgb: tuple[int, ...], width: float) -> tuple:
    """Scarp ticks: perpendicular hashes ``SCARP_TICK_MM`` apart and long, the first half a
    spacing from the start, offset half their length to the left (negative: QGIS offsets a
    positive distance to the right of the line's direction)."""
    from toolbox.styles.symbology import SCARP_TICK_MM

    spacing, length = SCARP_TICK_MM
    return "HashLine", {
        "placement": "interval", "interval": f"{spacing:g}", "interval_unit": "MM",
        "offset_along_line": f"{spacing / 2:g}", "offset_along_line_unit": "MM",
        "hash_length": f"{length:g}", "hash_length_unit": "MM", "hash_angle": "0",
        "rotate": "1", "offset": f"{-length / 2:g}", "offset_unit": "MM"}, [
        _line(rgb, round(width * 0.7, 4))]


def _marker(name: str, rgb: tuple[int, ...], size: float, width: float, filled: bool,
            offset: float = 0.0) -> tuple:
    return "SimpleMarker", {
        "name": name, "size": f"{size:g}", "size_unit": "MM",
        "color": _rgba(rgb) if filled else "0,0,0,0", "outline_color": _rgba(rgb),
        "outline_style": "no" if filled else "solid", "outline_width": f"{width:g}",
        "outline_width_unit": "MM", "offset": f"0,{offset:g}", "offset_unit": "MM",
        "angle": "0"}, None


def _symbology_layers(style: CodeStyle) -> list[tuple]:
    """The symbol layers drawing ``style.symbol`` (see the module docstring)."""
    symbol, rgb = style.symbol, style.rgb
    if style.kind == "point":
        if symbol.symbol == "tree":  # matplotlib's tree marker: crown 2/3, stem 1/3 of size
            size = symbol.size
            return [_marker("circle", rgb, size * 2 / 3, symbol.width, False, -size / 6),
                    _marker("line", rgb, size / 3, symbol.width, False, size / 3)]
        name = {"dot": "circle"}.get(symbol.symbol, symbol.symbol)
        return [_marker(name, rgb, symbol.size, symbol.width, symbol.symbol == "dot")]
    layers = []
    if style.kind == "polygon":
        if symbol.hatch == "solid":
            layers.append(("SimpleFill", {"color": _rgba(style.fill or (*rgb, 96)),
                                          "style": "solid", "outline_style": "no"}, None))
        elif isinstance(symbol.hatch, tuple):
            from toolbox.styles.symbology import HATCH_WIDTH_MM

            angle, spacing = symbol.hatch
            layers.append(("LinePatternFill", {
                "angle": f"{angle:g}", "distance": f"{spacing:g}", "distance_unit": "MM",
                "color": _rgba(rgb), "line_width": f"{HATCH_WIDTH_MM:g}",
                "line_width_unit": "MM"}, [_line(rgb, HATCH_WIDTH_MM)]))
    layers.append(_line(rgb, symbol.width, symbol.linetype))
    if symbol.linetype == "scarp":
        layers.append(_ticks(rgb, symbol.width))
    return layers


def _labeling(root: ET.Element, field: str, kind: str, expression: str | None = None) -> None:
    labeling = ET.SubElement(root, "labeling", {"type": "simple"})
    settings = ET.SubElement(labeling, "settings", {"calloutType": "simple"})
    ET.SubElement(settings, "text-style", {
        "fieldName": expression or field, "isExpression": "1" if expression else "0",
        "fontFamily": "Sans Serif", "fontSize": "8",
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
                "label": style.legend or (f"{style.code} {style.label}".strip()
                                          if style.label != style.code else style.code)})
        symbols = ET.SubElement(renderer, "symbols")
        for k, style in enumerate(layer.styles):
            _symbol(symbols, "symbol", str(k), style)
        source = ET.SubElement(renderer, "source-symbol")
        _symbol(source, "symbol", "0", layer.styles[0])
    elif layer.graduated:  # QGIS draws a value in the first range holding it, ends included
        renderer = ET.SubElement(root, "renderer-v2", {
            "type": "graduatedSymbol", "attr": layer.field, "graduatedMethod": "GraduatedColor",
            "symbollevels": "0", "enableorderby": "0", "forceraster": "0",
            "referencescale": "-1"})
        ranges = ET.SubElement(renderer, "ranges")
        for k, ((lower, upper), style) in enumerate(zip(layer.ranges, layer.styles)):
            ET.SubElement(ranges, "range", {"lower": f"{lower:g}", "upper": f"{upper:g}",
                                            "symbol": str(k), "label": style.label,
                                            "render": "true"})
        symbols = ET.SubElement(renderer, "symbols")
        for k, style in enumerate(layer.styles):
            _symbol(symbols, "symbol", str(k), style)
    else:
        renderer = ET.SubElement(root, "renderer-v2", {
            "type": "singleSymbol", "symbollevels": "0", "enableorderby": "0",
            "forceraster": "0", "referencescale": "-1"})
        symbols = ET.SubElement(renderer, "symbols")
        _symbol(symbols, "symbol", "0", layer.styles[0])
    if layer.label_field:
        _labeling(root, layer.label_field, layer.kind, layer.label_expression)
    ET.SubElement(root, "layerGeometryType").text = GEOMETRY_TYPES[layer.kind]
    ET.indent(root)
    body = ET.tostring(root, encoding="unicode")
    return "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n" + body + "\n"
