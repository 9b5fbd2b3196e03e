"""The symbology of each code, from the code file's symbology columns: what the map sheet
(:mod:`toolbox.cartography.symbols_draw`) and the QGIS/SLD styles (:mod:`.qml`, :mod:`.sld`)
draw.

The code file (:mod:`toolbox.io.code_file`) may carry, per code, ``linetype``, ``width`` (mm),
``symbol``, ``hatch`` and ``delivered``; a code without them gets the CTR 1:5000 default of
its kind (thin continuous black-ish lines 0.18 mm, area outlines 0.18 mm unfilled, points a
dot of 0.6 mm). Values:

- ``linetype``: ``continuous`` (``continua``), ``dashed`` (``tratteggiata``), ``dotted``
  (``punteggiata``), ``dashdot``, or ``scarp`` (``scarpata``: the line with ticks 1.2 mm long
  every 2 mm on its left, the side the slope falls to, as CTR scarps are drawn);
- ``width``: line width in mm at print size (``0.25`` or ``0,25``);
- ``symbol``: ``dot``, ``circle``, ``cross``, ``triangle`` (a trig point), ``square``,
  ``tree``, optionally followed by the size in mm (``tree 2.5``);
- ``hatch``: ``solid`` (filled with the code's colour, light), or ``ANGLE/SPACING`` in
  degrees and mm (``45/1.0``: lines at 45 degrees, 1 mm apart), drawn as real lines clipped to
  the area; ``none`` or empty: outline only;
- ``delivered``: the code of the delivered file this working code becomes (several working
  codes may map to one; the legend lists delivered codes once each).
"""

from __future__ import annotations

from dataclasses import dataclass

from toolbox.errors import InputDataError

LINETYPES = {"continuous": "continuous", "continua": "continuous", "solid": "continuous",
             "dashed": "dashed", "tratteggiata": "dashed", "tratteggio": "dashed",
             "dotted": "dotted", "punteggiata": "dotted", "dashdot": "dashdot",
             "tratto-punto": "dashdot", "scarp": "scarp", "scarpata": "scarp"}
SYMBOLS = {"dot": "dot", "punto": "dot", "circle": "circle", "cerchio": "circle",
           "cross": "cross", "croce": "cross", "triangle": "triangle", "triangolo": "triangle",
           "square": "square", "quadrato": "square", "tree": "tree", "albero": "tree"}
#: dash patterns in mm of paper (on, off, ...)
DASHES = {"dashed": (2.0, 1.0), "dotted": (0.3, 0.7), "dashdot": (2.5, 0.8, 0.3, 0.8)}
DEFAULT_WIDTH = {"line": 0.18, "polygon": 0.18, "point": 0.6}
SCARP_TICK_MM = (2.0, 1.2)  # spacing, length
HATCH_WIDTH_MM = 0.1  # the width of hatching lines


@dataclass(frozen=True)
class Symbol:
    """How one code is drawn on the sheet: ``linetype`` (continuous/dashed/dotted/dashdot/
    scarp), ``width`` mm, ``symbol`` (points) and its ``size`` mm, ``hatch`` (None, "solid" or
    (angle degrees, spacing mm)), ``delivered`` code (the code itself when none is given)."""

    code: str
    linetype: str = "continuous"
    width: float = 0.18
    symbol: str = "dot"
    size: float = 0.6
    hatch: str | tuple[float, float] | None = None
    delivered: str = ""


def _number(text: str, what: str, code: str, line: int, name: str) -> float:
    try:
        value = float(text.replace(",", "."))
    except ValueError:
        value = -1.0
    if not value > 0:
        raise InputDataError(f"{name}: line {line}: {what} {text!r} of code {code!r} must be a "
                             "positive number of mm")
    return value


def parse_symbol(entry, kind: str, name: str = "CODES") -> Symbol:
    """The :class:`Symbol` of a :class:`~toolbox.io.code_file.CodeEntry` drawn as ``kind``."""
    given = dict(entry.symbology)
    code, line = entry.code, entry.line
    linetype = given.get("linetype", "continuous").strip().lower()
    if linetype not in LINETYPES:
        raise InputDataError(f"{name}: line {line}: line type {linetype!r} of code {code!r} is "
                             f"not one of {', '.join(sorted(set(LINETYPES.values())))}")
    width = _number(given["width"], "width", code, line, name) if "width" in given \
        else DEFAULT_WIDTH.get(kind, 0.18)
    symbol, size = "dot", 0.6
    if "symbol" in given:
        words = given["symbol"].lower().split()
        if words[0] not in SYMBOLS:
            raise InputDataError(f"{name}: line {line}: symbol {words[0]!r} of code {code!r} is "
                                 f"not one of {', '.join(sorted(set(SYMBOLS.values())))}")
        symbol = SYMBOLS[words[0]]
        size = _number(words[1], "symbol size", code, line, name) if len(words) > 1 else 1.5
    hatch: str | tuple[float, float] | None = None
    text = given.get("hatch", "").strip().lower()
    if text in ("solid", "piena", "pieno"):
        hatch = "solid"
    elif text and text not in ("none", "nessuna"):
        angle, _, spacing = text.partition("/")
        try:
            hatch = (float(angle.replace(",", ".")), float(spacing.replace(",", ".")))
        except ValueError:
            hatch = (0.0, -1.0)
        if not hatch[1] > 0:
            raise InputDataError(f"{name}: line {line}: hatch {text!r} of code {code!r} must be "
                                 "'solid', 'none' or ANGLE/SPACING (degrees/mm, e.g. 45/1.0)")
    return Symbol(code, LINETYPES[linetype], width, symbol, size, hatch,
                  given.get("delivered", "") or code)


def has_symbology(table) -> bool:
    """Whether the code file ``table`` has symbology columns (then every code is drawn with its
    :class:`Symbol`, defaults where a cell is empty)."""
    return table is not None and any(e.symbology for e in table.entries.values())


def check_symbology(table, name: str = "CODES") -> None:
    """Parse every code's symbology (raises :class:`InputDataError` naming the line)."""
    for entry in table.entries.values():
        parse_symbol(entry, entry.kind or "line", name)


def delivered_leads(table) -> dict[str, tuple[str, str]]:
    """Delivered code -> (legend name ``"<delivered> <description>"``, lead working code): a
    delivered code has one look, that of its first working code in the file."""
    first: dict[str, tuple[str, str]] = {}
    for entry in table.entries.values():
        symbol = parse_symbol(entry, entry.kind or "line")
        first.setdefault(symbol.delivered, (f"{symbol.delivered} {entry.description}".strip(),
                                            entry.code))
    return first


def code_symbol(code: str, kind: str, table) -> tuple[Symbol, str, str]:
    """The :class:`Symbol` of ``code`` drawn as ``kind`` (its delivered code's lead's look,
    ``code`` kept), the legend name and the lead working code whose colour it takes."""
    from dataclasses import replace

    name, lead = delivered_leads(table)[parse_symbol(table[code], kind).delivered]
    return replace(parse_symbol(table[lead], kind), code=code), name, lead

