"""The code file and the colour file of restitution (thesis S002 §2.2.1 l.677-706, §3.6 l.3251).

Code file
---------
One code per line; ``#`` at the start of a line is a comment, blank lines are ignored; UTF-8 or
Latin-1 (read with :func:`toolbox.io.text.read_text`, so "località" survives either way).

*With a header line*, its column names decide, in any order and any case, Italian or English:

=============  ==================================================
column         names accepted
=============  ==================================================
code           code, codice, cod, id
colour         colour, color, colore, colour code, codice colore
description    description, descrizione, desc, descrizione entita
type           type, tipologia, tipo, geometry, geometria
area           area, area code, codice area, bounds, delimita
linetype       linetype, line type, tipo linea, tratto
width          width, line width, spessore
symbol         symbol, point symbol, simbolo
hatch          hatch, hatching, campitura, retino
delivered      delivered, delivery code, codice consegna, consegna
=============  ==================================================

The last five are the symbology of the map sheet and the delivered code (the working code file
is not delivered, so its codes may differ from the final file's, S002 §2.2.1 l.695): kept as
text in ``CodeEntry.symbology`` and read by :mod:`toolbox.cartography.symbols`.

The optional ``area`` column says which area code(s) the face closed by a line of this code takes
(thesis §2.4, "codifica logica" of areas): ``FAB01002; muro perimetrale; linea; 12; AREA_FAB``
means a building wall plotted closed codes the face inside it ``AREA_FAB``. Several area codes
(a kerb closing either a pavement or a flower bed) are separated by ``,`` or ``|``; the first is
the default. A code of type polygon is an area code itself. The column is read only with a
header; a point code cannot bound an area, and an area code named there cannot be declared as a
point or line code.

*Without a header*, the two layouts of the thesis:

- ``CODE COLOUR DESCRIPTION`` (§2.2.1): ``FAB01002<TAB>12<TAB>muro perimetrale di fabbricato
  civile``; the colour may be empty (``STR0200104<TAB><TAB>limite di strada``);
- ``ID; description; type; colour`` (Z-Map, §3.6): ``FAB01002; muro perimetrale; polygon; 12``.

Separators: tab, ``;``, or white space (then a description with spaces is quoted, ``"..."``, or
is the rest of the line). The file's first data line decides the separator: tab if it has one,
else ``;`` if it has one, else white space.

Types: ``point``/``punto``/``symbol``/``simbolo``/``text``/``testo`` -> point; ``line``/``linea``/
``polyline``/``polilinea``/``spline``/``curve`` -> line; ``polygon``/``poligono``/``area`` ->
polygon; empty -> any geometry. The colour is an index of the colour file, or ``#RRGGBB``.

Colour file
-----------
``INDEX %RED %GREEN %BLUE`` (the thesis' ``INDICE %ROSSO %VERDE %BLU``; the header is optional),
white space, tab or ``;`` separated, percentages 0-100, integer or decimal (point or comma).
8-bit components are ``round(p * 255 / 100)`` rounded half up (30 % -> 76.5 -> 77).

Errors (:class:`InputDataError`) name the file, the line number and the problem.
"""

from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError
from toolbox.io.text import read_text

KINDS = ("point", "line", "polygon")
TYPE_WORDS: dict[str, str] = {
    **dict.fromkeys(("point", "punto", "punti", "points", "symbol", "simbolo", "text", "testo",
                     "label", "etichetta"), "point"),
    **dict.fromkeys(("line", "linea", "lines", "linee", "polyline", "polilinea", "polylines",
                     "polilinee", "spline", "curve", "curva"), "line"),
    **dict.fromkeys(("polygon", "poligono", "polygons", "poligoni", "area", "aree", "areas",
                     "superficie", "surface"), "polygon"),
}
COLUMN_NAMES: dict[str, tuple[str, ...]] = {
    "code": ("code", "codice", "cod", "id", "codes", "codici"),
    "colour": ("colour", "color", "colore", "colour code", "color code", "codice colore",
               "colour index", "indice colore", "col"),
    "description": ("description", "descrizione", "desc", "descrizione entita",
                    "entity description", "nome", "name"),
    "type": ("type", "tipologia", "tipo", "geometry", "geometria", "geometry type", "kind"),
    "area": ("area", "areas", "area code", "area codes", "codice area", "codici area", "bounds",
             "delimita", "area delimitata"),
    # symbology and delivery (read by toolbox.cartography.symbols; kept as text here)
    "linetype": ("linetype", "line type", "line style", "tipo linea", "stile linea", "tratto"),
    "width": ("width", "line width", "spessore", "spessore linea"),
    "symbol": ("symbol", "point symbol", "simbolo", "stile punto"),
    "hatch": ("hatch", "hatching", "campitura", "retino"),
    "delivered": ("delivered", "delivery code", "delivered code", "final code",
                  "codice consegna", "consegna", "codice finale"),
}
SYMBOLOGY_COLUMNS = ("linetype", "width", "symbol", "hatch", "delivered")
_COLUMN_LOOKUP = {name: col for col, names in COLUMN_NAMES.items() for name in names}
_HEX = re.compile(r"^#?([0-9a-fA-F]{6})$")


def _plain(text: str) -> str:
    """Lowercase, accents removed, one space between words (for names and type words)."""
    text = unicodedata.normalize("NFKD", text)
    text = "".join(ch for ch in text if not unicodedata.combining(ch)).lower()
    return " ".join(text.replace("_", " ").replace("%", " ").split())


@dataclass(frozen=True)
class CodeEntry:
    """One code of the code file.

    ``kind`` is point/line/polygon or None (any geometry); ``colour`` the colour-file index or
    ``#rrggbb`` text as written (None when empty); ``line`` the line of the file (1-based);
    ``areas`` the area codes of the face a closed line of this code bounds (``area`` column).
    """

    code: str
    description: str = ""
    kind: str | None = None
    colour: str | None = None
    line: int = 0
    areas: tuple[str, ...] = ()
    symbology: tuple[tuple[str, str], ...] = ()  # (column, text) of SYMBOLOGY_COLUMNS given


@dataclass
class CodeTable:
    """The code file: ``entries`` by code (file order), the ``layout`` found."""

    path: Path | None
    entries: dict[str, CodeEntry] = field(default_factory=dict)
    layout: str = "header"  # "header", "code colour description", "id; description; type; colour"

    def __contains__(self, code: object) -> bool:
        return code in self.entries

    def __getitem__(self, code: str) -> CodeEntry:
        return self.entries[code]

    def __len__(self) -> int:
        return len(self.entries)


def _fail(path: Path, number: int, problem: str, name: str) -> InputDataError:
    return InputDataError(f"{name}: '{path}' line {number}: {problem}")


def _data_lines(text: str) -> list[tuple[int, str]]:
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        if line.strip() and not line.lstrip().startswith("#"):
            rows.append((number, line.rstrip("\r\n")))
    return rows


def _separator(line: str) -> str | None:
    if "\t" in line:
        return "\t"
    if ";" in line:
        return ";"
    return None  # white space


def _unquote(text: str) -> str:
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
        return text[1:-1]
    return text


def _split(line: str, sep: str | None) -> list[str]:
    if sep is not None:
        return [_unquote(part) for part in line.split(sep)]
    tokens = re.findall(r'"[^"]*"|\'[^\']*\'|\S+', line)
    return [_unquote(t) for t in tokens]


def _kind(word: str) -> str | None:
    return TYPE_WORDS.get(_plain(word))


def _is_colour(value: str) -> bool:
    value = value.strip()
    return value == "" or value.isdigit() or bool(_HEX.match(value))


def _header(fields: list[str]) -> dict[str, int] | None:
    columns = {}
    for i, name in enumerate(fields):
        col = _COLUMN_LOOKUP.get(_plain(name))
        if col is None or col in columns:
            return None
        columns[col] = i
    return columns if "code" in columns else None


def read_code_file(path: str | Path, name: str = "CODES") -> CodeTable:
    """Read a code file (grammar in the module docstring).

    Raises
    ------
    InputDataError
        Unreadable or empty file, a line with no code, a type word that is not a known type, a
        colour that is not an index or ``#rrggbb``, a code given twice.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "codici.txt"
    >>> _ = p.write_text("FAB01002\\t12\\tmuro perimetrale di fabbricato civile\\n"
    ...                  "STR0200104\\t\\tlimite di strada\\n")
    >>> table = read_code_file(p)
    >>> table["FAB01002"].colour, table["STR0200104"].colour, table.layout
    ('12', None, 'code colour description')
    """
    path = Path(path)
    rows = _data_lines(read_text(path, name))
    if not rows:
        raise InputDataError(f"{name}: '{path}' has no codes")
    sep = _separator(rows[0][1])
    columns = _header(_split(rows[0][1], sep))
    table = CodeTable(path)
    if columns is not None:
        rows = rows[1:]
    for number, line in rows:
        fields = _split(line, sep)
        code, colour, description, kind_word = _fields(fields, columns, sep, line)
        areas = _area_codes(fields, columns)
        if columns is None and table.layout == "header":
            table.layout = ("id; description; type; colour" if kind_word is not None
                            else "code colour description")
        if not code:
            raise _fail(path, number, f"no code in {line.strip()!r}", name)
        kind = None
        if kind_word:
            kind = _kind(kind_word)
            if kind is None:
                raise _fail(path, number, f"type {kind_word!r} of code {code!r} is not one of "
                            "point, line, polyline, polygon (or punto, linea, polilinea, "
                            "poligono)", name)
        colour = colour.strip() or None if colour is not None else None
        if colour is not None and not (colour.isdigit() or _HEX.match(colour)):
            raise _fail(path, number, f"colour {colour!r} of code {code!r} must be a colour-file "
                        "index (a whole number) or #RRGGBB", name)
        if code in table.entries:
            raise _fail(path, number, f"code {code!r} given twice (first on line "
                        f"{table.entries[code].line})", name)
        if areas and kind == "point":
            raise _fail(path, number, f"code {code!r} is a point code: it cannot bound area "
                        f"{', '.join(areas)}", name)
        symbology = tuple((c, fields[columns[c]].strip()) for c in SYMBOLOGY_COLUMNS
                          if columns is not None and c in columns and columns[c] < len(fields)
                          and fields[columns[c]].strip())
        table.entries[code] = CodeEntry(code, description.strip(), kind, colour, number, areas,
                                        symbology)
    if not table.entries:
        raise InputDataError(f"{name}: '{path}' has a header but no codes")
    for entry in table.entries.values():
        for area in entry.areas:
            declared = table.entries.get(area)
            if declared is not None and declared.kind in ("point", "line"):
                raise _fail(path, entry.line, f"code {entry.code!r} bounds area {area!r}, but "
                            f"line {declared.line} declares {area!r} a {declared.kind} code",
                            name)
    return table


def _area_codes(fields: list[str], columns: dict[str, int] | None) -> tuple[str, ...]:
    """The ``area`` column of one data line: codes split on ``,`` or ``|``."""
    if columns is None or "area" not in columns or columns["area"] >= len(fields):
        return ()
    parts = re.split(r"[,|]", fields[columns["area"]])
    return tuple(dict.fromkeys(p.strip() for p in parts if p.strip()))


def _fields(fields: list[str], columns: dict[str, int] | None, sep: str | None, line: str
            ) -> tuple[str, str | None, str, str | None]:
    """(code, colour, description, type word) of one data line."""
    def at(i: int | None) -> str:
        return fields[i] if i is not None and i < len(fields) else ""

    if columns is not None:
        if sep is None and "description" in columns and columns["description"] == max(
                columns.values()):  # white space: an unquoted description is the rest
            i = columns["description"]
            fields = fields[:i] + [" ".join(fields[i:])]
        kind = at(columns.get("type")) if "type" in columns else None
        return (at(columns["code"]).strip(), at(columns.get("colour")),
                at(columns.get("description")), kind)
    code = fields[0].strip() if fields else ""
    if len(fields) >= 3 and (sep is not None or _kind(fields[2]) is not None) and not \
            _is_colour(fields[1]):
        # ID; description; type; colour (Z-Map): the second field is not a colour
        return code, at(3), fields[1], fields[2]
    if sep is None:  # CODE [COLOUR] DESCRIPTION, description quoted or the rest of the line
        rest = re.match(r"\s*\S+\s*(.*)$", line).group(1)  # type: ignore[union-attr]
        match = re.match(r"(\d+|#[0-9a-fA-F]{6})(?:\s+(.*))?$", rest)
        if match and not rest.startswith(("'", '"')):
            return code, match.group(1), _unquote(match.group(2) or ""), None
        return code, None, _unquote(rest), None
    return code, at(1), sep.join(fields[2:]) if len(fields) > 2 else "", None


# -- colour file ------------------------------------------------------------------------------------
def percent_to_byte(percent: float) -> int:
    """8-bit component of a percentage: round(p * 255 / 100), half up."""
    import math

    return int(math.floor(percent * 255.0 / 100.0 + 0.5))


def _percent(text: str) -> float:
    text = text.strip().rstrip("%")
    if "," in text and "." not in text:
        text = text.replace(",", ".")
    value = float(text)
    if not 0 <= value <= 100:
        raise ValueError(text)
    return value


def read_colour_file(path: str | Path, name: str = "COLOURS") -> dict[str, tuple[int, int, int]]:
    """Read a colour file: index (text) -> (R, G, B) 0-255.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "colori.txt"
    >>> _ = p.write_text("INDICE %ROSSO %VERDE %BLU\\n1 20 80 0\\n2 10 65 65\\n3 100 0 0\\n")
    >>> read_colour_file(p)
    {'1': (51, 204, 0), '2': (26, 166, 166), '3': (255, 0, 0)}
    """
    path = Path(path)
    colours: dict[str, tuple[int, int, int]] = {}
    lines: dict[str, int] = {}
    rows = _data_lines(read_text(path, name))
    for k, (number, line) in enumerate(rows):
        fields = [f for f in re.split(r"[;\t ]+", line.strip()) if f]
        if k == 0 and fields and not fields[0].isdigit() and not _looks_numeric(fields[1:]):
            continue  # header
        if len(fields) != 4:
            raise _fail(path, number, f"expected 'INDEX %RED %GREEN %BLUE', got {line.strip()!r}",
                        name)
        index = fields[0]
        if not index.isdigit():
            raise _fail(path, number, f"colour index {index!r} must be a whole number", name)
        index = str(int(index))
        try:
            rgb = tuple(percent_to_byte(_percent(f)) for f in fields[1:])
        except ValueError:
            raise _fail(path, number, f"colour {index}: components must be percentages 0-100, "
                        f"got {' '.join(fields[1:])!r}", name) from None
        if index in colours:
            raise _fail(path, number, f"colour index {index} given twice (first on line "
                        f"{lines[index]})", name)
        colours[index] = rgb  # type: ignore[assignment]
        lines[index] = number
    if not colours:
        raise InputDataError(f"{name}: '{path}' has no colours")
    return colours


def _looks_numeric(fields: list[str]) -> bool:
    try:
        [float(f.replace(",", ".").rstrip("%")) for f in fields]
    except ValueError:
        return False
    return bool(fields)


def hex_colour(rgb: tuple[int, int, int]) -> str:
    """``#rrggbb`` of an (R, G, B) triple."""
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def parse_hex(text: str) -> tuple[int, int, int]:
    value = _HEX.match(text.strip())
    if not value:
        raise ValueError(text)
    h = value.group(1)
    return int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16)

def code_colour(code: str, table: CodeTable, colours: dict[str, tuple[int, int, int]] | None,
                entity_colour: Any = None) -> tuple[tuple[int, int, int] | None, str | None]:
    """(RGB or None, colour index used): the code's colour, else the entity's own."""
    entry = table.entries.get(code)
    index = entry.colour if entry is not None and entry.colour else None
    if index is None and entity_colour is not None and str(entity_colour).strip():
        index = str(entity_colour).strip()
    if index is None:
        return None, None
    if index.startswith("#"):
        return parse_hex(index), index
    key = str(int(index)) if index.isdigit() else index
    if colours is not None and key in colours:
        return colours[key], key
    return None, key
