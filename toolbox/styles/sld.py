"""OGC Styled Layer Descriptor 1.0 (SLD) of a :class:`~toolbox.styles.model.LayerStyle`: one
rule per code (filtered on the code field when the layer holds several), Point/Line/Polygon
symbolizers, a TextSymbolizer for labels. Millimetres become pixels at 0.28 mm per pixel (the
OGC standard rendering pixel)."""

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
    stroke = _e(parent, "Stroke")
    _param(stroke, "CssParameter", "stroke", style.hex)
    _param(stroke, "CssParameter", "stroke-width", _px(style.line_width))


def _fill(parent: ET.Element, rgba: tuple[int, int, int, int]) -> None:
    fill = _e(parent, "Fill")
    _param(fill, "CssParameter", "fill", "#{:02x}{:02x}{:02x}".format(*rgba[:3]))
    _param(fill, "CssParameter", "fill-opacity", f"{rgba[3] / 255:.2f}")


def _rule(parent: ET.Element, layer: LayerStyle, style: CodeStyle) -> None:
    rule = _e(parent, "Rule")
    _e(rule, "Name", style.code)
    _e(rule, "Title", style.label)
    if layer.categorised:
        flt = _e(rule, "Filter", ns=OGC)
        eq = _e(flt, "PropertyIsEqualTo", ns=OGC)
        _e(eq, "PropertyName", layer.field, ns=OGC)
        _e(eq, "Literal", style.code, ns=OGC)
    if style.kind == "polygon":
        sym = _e(rule, "PolygonSymbolizer")
        _fill(sym, style.fill or (*style.rgb, 255))
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
    for style in layer.styles:
        _rule(fts, layer, style)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") \
        + "\n"
