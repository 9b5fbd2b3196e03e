"""Which codes are area codes, from the code file (thesis S002 §2.4, "codifica logica").

A closed coded line bounds a face; whether its code says what the face *is* depends on the code
file: a code of type polygon is an area code (a building plotted closed with the building code);
a line code names the area code(s) of the face it closes in the code file's ``area`` column
(``FAB01002`` wall -> ``AREA_FAB``); any other line code (a kerb, a road edge) only bounds faces
and codes none. A label point's code is an area code unless the code file declares it a point
code (a spot height's code then contributes its attributes only). A label carrying the closed
line's own code agrees with it (the operator labelled the building with the wall's code).

Without a code file a closed line's code fills a face that no label codes, and is never taken
as disagreeing with a label (a line code and an area code cannot be told apart).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from toolbox.io.code_file import CodeTable


@dataclass(frozen=True)
class AreaCodes:
    """Area codes of a code file.

    Attributes
    ----------
    polygon : codes of type polygon (area codes).
    point : codes declared point codes (a label with one gives attributes only).
    bounds : line code -> the area codes a face closed by it may take (first = default).
    known : every code of the file.
    """

    polygon: frozenset[str] = frozenset()
    point: frozenset[str] = frozenset()
    bounds: dict[str, tuple[str, ...]] = field(default_factory=dict)
    known: frozenset[str] = frozenset()

    @classmethod
    def from_table(cls, table: CodeTable) -> AreaCodes:
        entries = table.entries.values()
        return cls(polygon=frozenset(e.code for e in entries if e.kind == "polygon"),
                   point=frozenset(e.code for e in entries if e.kind == "point"),
                   bounds={e.code: e.areas for e in entries if e.areas},
                   known=frozenset(table.entries))

    def of_outline(self, code: str) -> tuple[str, ...]:
        """The area codes a face closed by a line of ``code`` may take (empty: it codes none)."""
        if code in self.bounds:
            return self.bounds[code]
        return (code,) if code in self.polygon else ()

    def is_area_label(self, code: str) -> bool:
        """A label code that codes an area (not declared a point code)."""
        return code not in self.point
