"""OGC Styled Layer Descriptor 1.0 (SLD) of a :class:`~toolbox.styles.model.LayerStyle`: one
rule per code (filtered on the code field when the layer holds several, on the value ranges
of a graduated style), Point/Line/Polygon
symbolizers, a TextSymbolizer for labels. Millimetres become pixels at 0.28 mm per pixel (the
OGC standard rendering pixel).

With the code file's symbology (:mod:`.symbology`): line types as ``stroke-dasharray``, hatching
as a ``GraphicFill`` of a ``horline`` mark (as QGIS writes a line pattern fill) rotated by minus
the hatch angle (SLD rotations are clockwise; QGIS 3.22 reads and writes that rotation as its
own counter-clockwise angle, so in QGIS use the QML, which the GeoPackage embeds), solid
fills at the sheet's opacity, point symbols as their well-known marks (a tree as a circle),
scarp ticks as a ``GraphicStroke`` of ``vertline`` marks every 2 mm (SLD 1.0 cannot put them on
one side: they are centred on the line).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from toolbox.styles.model import CodeStyle, LayerStyle

SLD = "http://www.opengis.net/sld"
OGC = "http://www.opengis.net/ogc"
ET.register_namespace("sld", SLD)
ET.register_namespace("ogc", OGC)
ET.register_namespace("xlink", "http://www.w3.org/1999/xlink")
ET.register_namespace("xsi", "http://www.w3.org/2001/XMLSchema-instance")
PIXEL_MM = 0.28


def _e(parent: ET.Element, tag: str, text: str | None = None, ns: str = SLD, **attrib):
    el = ET.SubElement(parent, f"{{{ns}}}{tag}", attrib)
    if text is not None:
        el.text = text
    return el


def _param(parent: ET.Element, tag: str, name: str, value: str) -> None:
    _e(parent, tag, value, name=name)


def _px(mm: float) -> str:
    return f"{mm / PIXEL_MM:.2f}"


def _stroke(parent: ET.Element, style: CodeStyle) -> None:
    from toolbox.styles.symbology import DASHES

    stroke = _e(parent, "Stroke")
    _param(stroke, "CssParameter", "stroke", style.hex)
    _param(stroke, "CssParameter", "stroke-width", _px(style.line_width))
    if style.symbol is not None and style.symbol.linetype in DASHES:
        _param(stroke, "CssParameter", "stroke-dasharray",
               " ".join(_px(v) for v in DASHES[style.symbol.linetype]))


def _mark(parent: ET.Element, name: str, colour: str, width_mm: float, size_mm: float,
          fill: str | None = None, rotation: float | None = None) -> None:
    graphic = _e(parent, "Graphic")
    mark = _e(graphic, "Mark")
    _e(mark, "WellKnownName", name)
    if fill is not None:
        _param(_e(mark, "Fill"), "CssParameter", "fill", fill)
    stroke = _e(mark, "Stroke")
    _param(stroke, "CssParameter", "stroke", colour)
    _param(stroke, "CssParameter", "stroke-width", _px(width_mm))
    _e(graphic, "Size", _px(size_mm))
    if rotation is not None:
        _e(graphic, "Rotation", f"{rotation:g}")


def _symbology(rule: ET.Element, style: CodeStyle) -> None:
    """The symbolizers of a code with the code file's symbology (module docstring)."""
    from toolbox.styles.symbology import HATCH_WIDTH_MM, SCARP_TICK_MM

    symbol = style.symbol
    if style.kind == "point":
        name = {"dot": "circle", "tree": "circle"}.get(symbol.symbol, symbol.symbol)
        _mark(_e(rule, "PointSymbolizer"), name, style.hex, symbol.width, symbol.size,
              fill=style.hex if symbol.symbol == "dot" else None)
        return
    if style.kind == "polygon" and symbol.hatch is not None:
        sym = _e(rule, "PolygonSymbolizer")
        if symbol.hatch == "solid":
            _fill(sym, style.fill or (*style.rgb, 96))
        else:  # SLD rotation is clockwise, the hatch angle counter-clockwise
            angle, spacing = symbol.hatch
            _mark(_e(_e(sym, "Fill"), "GraphicFill"), "horline", style.hex, HATCH_WIDTH_MM,
                  spacing, rotation=-angle)
    _stroke(_e(rule, "LineSymbolizer"), style)
    if symbol.linetype == "scarp":
        spacing, length = SCARP_TICK_MM
        stroke = _e(_e(rule, "LineSymbolizer"), "Stroke")
        _mark(_e(stroke, "GraphicStroke"), "shape://vertline", style.hex,
              symbol.width * 0.7, length)
        _param(stroke, "CssParameter", "stroke-dasharray", f"{_px(length)} {_px(spacing - length)}")


def _fill(parent: ET.Element, rgba: tuple[int, int, int, int]) -> None:
    fill = _e(parent, "Fill")
    _param(fill, "CssParameter", "fill", "#{:02x}{:02x}{:02x}".format(*rgba[:3]))
    _param(fill, "CssParameter", "fill-opacity", f"{rgba[3] / 255:.2f}")


def _compare(parent: ET.Element, operator: str, field: str, value: str) -> None:
    test = _e(parent, operator, ns=OGC)
    _e(test, "PropertyName", field, ns=OGC)
    _e(test, "Literal", value, ns=OGC)


def _rule(parent: ET.Element, layer: LayerStyle, style: CodeStyle, k: int) -> None:
    rule = _e(parent, "Rule")
    _e(rule, "Name", style.code)
    _e(rule, "Title", style.label)
    if layer.categorised:
        _compare(_e(rule, "Filter", ns=OGC), "PropertyIsEqualTo", layer.field, style.code)
    elif layer.graduated:  # lower < value <= upper, the first range's lower end included (QGIS)
        lower, upper = layer.ranges[k]
        both = _e(_e(rule, "Filter", ns=OGC), "And", ns=OGC)
        _compare(both, "PropertyIsGreaterThanOrEqualTo" if k == 0 else "PropertyIsGreaterThan",
                 layer.field, f"{lower:g}")
        _compare(both, "PropertyIsLessThanOrEqualTo", layer.field, f"{upper:g}")
    if style.symbol is not None:
        _symbology(rule, style)
    elif style.kind == "polygon":
        sym = _e(rule, "PolygonSymbolizer")
        _fill(sym, style.fill or (*style.rgb, 255))
        if style.line_width > 0:
            _stroke(sym, style)
    elif style.kind == "line":
        _stroke(_e(rule, "LineSymbolizer"), style)
    else:
        graphic = _e(_e(rule, "PointSymbolizer"), "Graphic")
        mark = _e(graphic, "Mark")
        _e(mark, "WellKnownName", "circle")
        _fill(mark, style.fill or (*style.rgb, 255))
        stroke = _e(mark, "Stroke")
        _param(stroke, "CssParameter", "stroke", "#232323")
        _param(stroke, "CssParameter", "stroke-width", _px(style.line_width))
        _e(graphic, "Size", _px(style.size))
    if layer.label_field:
        text = _e(rule, "TextSymbolizer")
        label = _e(text, "Label")
        _e(label, "PropertyName", layer.label_field, ns=OGC)
        font = _e(text, "Font")
        _param(font, "CssParameter", "font-family", "Sans Serif")
        _param(font, "CssParameter", "font-size", "11")
        _fill(text, (0, 0, 0, 255))


def sld_document(layer: LayerStyle) -> str:
    """The SLD text (UTF-8 XML) of one layer style."""
    root = ET.Element(f"{{{SLD}}}StyledLayerDescriptor", {
        "version": "1.0.0",
        "{http://www.w3.org/2001/XMLSchema-instance}schemaLocation":
            "http://www.opengis.net/sld http://schemas.opengis.net/sld/1.0.0/"
            "StyledLayerDescriptor.xsd"})
    named = _e(root, "NamedLayer")
    _e(named, "Name", layer.name)
    user = _e(named, "UserStyle")
    _e(user, "Name", layer.name)
    _e(user, "Title", layer.name)
    fts = _e(user, "FeatureTypeStyle")
    for k, style in enumerate(layer.styles):
        _rule(fts, layer, style, k)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") \
        + "\n"
