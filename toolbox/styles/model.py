"""The renderer-neutral style model: what each code looks like.

Widths and sizes are in millimetres on the map (QGIS "MM" units, SLD pixels at 96 dpi are
derived from them). A code without a colour is drawn grey (128, 128, 128).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from toolbox.io.code_file import CodeTable, hex_colour

GREY = (128, 128, 128)
LINE_WIDTH_MM = 0.35
OUTLINE_WIDTH_MM = 0.30
MARKER_SIZE_MM = 2.0
FILL_ALPHA = 96  # of 255: fills show the photo or DEM below


@dataclass(frozen=True)
class CodeStyle:
    """How one code is drawn.

    Attributes
    ----------
    code, label : the code and its description (the legend text and the label).
    kind : "point", "line" or "polygon".
    rgb : (R, G, B) 0-255, the stroke (and marker) colour.
    line_width : stroke width, mm (outline width for polygons, 0: none; marker outline for
        points).
    fill : (R, G, B, A) 0-255 of polygon fills and point markers, None for lines.
    size : marker size, mm (points only).
    symbol : the code file's symbology (a :class:`~toolbox.styles.symbology.Symbol`: line
        type, hatching, point symbol, as the map sheet draws it) or None (simple style).
    legend : the legend text ("<delivered code> <description>" with symbology, else "").
    """

    code: str
    kind: str
    rgb: tuple[int, int, int]
    line_width: float
    fill: tuple[int, int, int, int] | None
    label: str
    size: float = MARKER_SIZE_MM
    symbol: Any = None
    legend: str = ""

    @property
    def hex(self) -> str:
        return hex_colour(self.rgb)


@dataclass
class LayerStyle:
    """The style of one output layer: its kind, its codes' styles (one = single symbol, several
    = categorised by ``field``; with ``ranges``, ``styles[k]`` draws the features whose
    ``field`` is in ``ranges[k]`` = (lower, upper), upper included: graduated), and the field
    labelled (None: no labels)."""

    name: str
    kind: str
    styles: list[CodeStyle]
    field: str = "code"
    label_field: str | None = None
    label_expression: str | None = None  # a QGIS expression labelling instead (QML only)
    ranges: list[tuple[float, float]] | None = None

    @property
    def categorised(self) -> bool:
        return len(self.styles) > 1 and self.ranges is None

    @property
    def graduated(self) -> bool:
        return self.ranges is not None


def code_style(code: str, kind: str, table: CodeTable | None,
               colours: dict[str, tuple[int, int, int]] | None) -> CodeStyle:
    """The style of one code drawn as ``kind``: the code file's symbology (widths, line
    types, hatching, point symbols, delivered codes; :mod:`.symbology`) when the file has
    symbology columns, else a simple style (lines 0.35 mm, areas filled light, dots)."""
    from toolbox.io.code_file import code_colour
    from toolbox.styles.symbology import code_symbol, has_symbology

    rgb = None
    label = code
    if table is not None and code in table:
        rgb, _ = code_colour(code, table, colours)
        label = table[code].description or code
        if has_symbology(table):
            symbol, legend, lead = code_symbol(code, kind, table)
            rgb = code_colour(lead, table, colours)[0] or GREY
            fill = {"polygon": (*rgb, FILL_ALPHA) if symbol.hatch == "solid" else None,
                    "point": (*rgb, 255)}.get(kind)
            return CodeStyle(code, kind, rgb, symbol.width, fill, label, symbol.size, symbol,
                             legend)
    rgb = rgb or GREY
    if kind == "line":
        return CodeStyle(code, kind, rgb, LINE_WIDTH_MM, None, label)
    if kind == "polygon":
        return CodeStyle(code, kind, rgb, OUTLINE_WIDTH_MM, (*rgb, FILL_ALPHA), label)
    return CodeStyle(code, "point", rgb, 0.2, (*rgb, 255), label)


def style_model(table: CodeTable, colours: dict[str, tuple[int, int, int]] | None,
                kinds: dict[str, str] | None = None) -> dict[str, CodeStyle]:
    """Style of every code of the table; ``kinds`` gives the kind of codes the table declares
    none for (else "line")."""
    kinds = kinds or {}
    return {code: code_style(code, entry.kind or kinds.get(code, "line"), table, colours)
            for code, entry in table.entries.items()}


#: layer kinds that get labels from the description
LABELLED_KINDS = ("point", "polygon")


def layer_style(name: str, kind: str, codes: list[str], table: CodeTable | None,
                colours: dict[str, tuple[int, int, int]] | None,
                label_field: str | None = "auto") -> LayerStyle:
    """The style of a layer holding ``codes`` drawn as ``kind``; labels from ``description`` on
    point and polygon layers unless ``label_field`` says otherwise (None: none)."""
    if label_field == "auto":
        label_field = "description" if kind in LABELLED_KINDS else None
    styles = [code_style(c, kind, table, colours) for c in codes]
    return LayerStyle(name, kind, styles, label_field=label_field,
                      label_expression=_height_labels(styles, table) if label_field else None)


#: a spot height's label: its height (the point's Z), one decimal, as the map sheet prints it
HEIGHT_EXPRESSION = "format_number(z($geometry), 1)"


def _height_labels(styles: list[CodeStyle], table: CodeTable | None) -> str | None:
    """The QGIS label expression of a point layer whose codes include spot heights (a ``dot``
    in the code file's symbol column): their height, the description for the other codes;
    None without."""
    dots = [s.code for s in styles if s.kind == "point" and s.symbol is not None
            and s.symbol.symbol == "dot" and table is not None and s.code in table
            and dict(table[s.code].symbology).get("symbol")]
    if not dots:
        return None
    if len(dots) == len(styles):
        return HEIGHT_EXPRESSION
    quoted = ", ".join("'" + code.replace("'", "''") + "'" for code in dots)
    return f'CASE WHEN "code" IN ({quoted}) THEN {HEIGHT_EXPRESSION} ELSE "description" END'


MM_TO_POINTS = 72.0 / 25.4


def matplotlib_kwargs(style: CodeStyle) -> dict:
    """Keyword arguments drawing ``style`` with matplotlib (widths in points, colours as 0-1
    RGBA): ``plot`` for lines, a patch for polygons, ``scatter`` for points."""
    stroke = tuple(c / 255 for c in style.rgb) + (1.0,)
    if style.kind == "line":
        return {"color": stroke, "linewidth": style.line_width * MM_TO_POINTS}
    fill = tuple(c / 255 for c in (style.fill or (*style.rgb, 255)))
    if style.kind == "polygon":
        return {"facecolor": fill, "edgecolor": stroke,
                "linewidth": style.line_width * MM_TO_POINTS}
    return {"color": fill, "edgecolors": (35 / 255, 35 / 255, 35 / 255, 1.0),
            "s": (style.size * MM_TO_POINTS) ** 2, "linewidths": style.line_width * MM_TO_POINTS}
