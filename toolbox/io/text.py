"""Text files written by other software: UTF-8 (with or without BOM), else Windows-1252 (Latin-1
with ’ “ ” – € in 0x80-0x9f, as Word and Excel save Italian text), else Latin-1."""

from __future__ import annotations

import re
from pathlib import Path

from toolbox.errors import InputDataError


def read_text(path: str | Path, name: str | None = None) -> str:
    """The file's text; an unreadable file is an :class:`InputDataError` naming ``name``
    (the parameter) when given."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        prefix = f"{name}: " if name else ""
        raise InputDataError(f"{prefix}cannot read '{path}': {exc.strerror}") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        pass
    try:  # Windows-1252: Latin-1 plus the typographic apostrophe, quotes, dashes and euro sign
        return raw.decode("cp1252")
    except UnicodeDecodeError:  # one of the five bytes cp1252 leaves undefined
        return raw.decode("latin-1")


def yaml_error_line(exc: Exception) -> str:
    """A PyYAML error on one line: ``problem at line L, column C (context)``."""
    problem = getattr(exc, "problem", None)
    mark = getattr(exc, "problem_mark", None)
    if problem is None:
        return " ".join(str(exc).split())
    text = str(problem)
    if mark is not None:
        text += f" at line {mark.line + 1}, column {mark.column + 1}"
    context = getattr(exc, "context", None)
    if context:
        text += f" ({context})"
    return text


def is_number(text: str) -> bool:
    """True when ``text`` is a number Python's ``float`` reads (a header line's test)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def csv_dialect(text: str) -> tuple[str, str]:
    """``(delimiter, quote)`` of a CSV-like table from its first non-blank line: a tab, comma
    or semicolon outside quotes, else spaces (Orthority's and ODM's space-separated files);
    single quotes when the line quotes with them only, else double."""
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    quote = "'" if re.search(r"(^|[\s,;\t])'", first) and not re.search(r'(^|[\s,;\t])"', first) \
        else '"'
    bare = re.sub(r"(['\"]).*?\1", "", first)
    for delimiter in ("\t", ",", ";"):
        if delimiter in bare:
            return delimiter, quote
    return " ", quote
