"""The *parameter file* ("file dei parametri", thesis S002 §2.2.1 l.708-710): one reader for
every algorithm that takes a ``PARAMETERS`` file (``topology:*``, ``attribution:*``).

The thesis lists the quantities such a file holds (identification tolerance, planimetric and
height reattach - "riattacco" - tolerances, coordinate unit, number of decimals, coordinate
translation, alignment and squaring tolerances, spline step, closure tolerance, end-of-polyline
tolerance) but no syntax, which varies with the plotting software. This module reads one simple,
documented text form of it.

Format
------
UTF-8 (or Latin-1) text, one entry per line::

    # file dei parametri - foglio 1
    tolleranza di identificazione          = 0.50
    tolleranza di riattacco planimetrico   = 0.20    # metres
    tolleranza di riattacco altimetrico    = 0.10
    unità di misura delle coordinate       = m
    numero di cifre decimali               = 3
    traslazione delle coordinate           = 1688000 4799500
    tolleranza angolare di squadratura     = 1.5     # degrees
    tolleranza di chiusura                 = 0,50
    area minima                            = 1.0

- ``name = value``, ``name: value`` or ``name<TAB>value``; ``#`` starts a comment, and so does
  ``;`` at the start of a line (INI style); blank lines are ignored.
- Names are matched ignoring case, accents and repeated spaces (``unita`` = ``unità``), with an
  optional unit in brackets (``tolleranza di chiusura [m]``). English names are accepted too (see
  :data:`KEYS`). Unknown names are kept in :attr:`ParameterFile.unknown`, not refused.
- Numbers take a decimal point or an Italian decimal comma (``0,50``).
- Lengths are in the coordinate unit of the data (metres for EPSG:3003), the angular squaring
  tolerance in degrees. The unit entry is checked against the CRS, not used to rescale.
- ``traslazione delle coordinate = E N`` says the coordinates were stored relative to a false
  origin (E, N): the map coordinates are the stored ones **plus** (E, N). Every algorithm taking
  the file adds it to its inputs (:meth:`ParameterFile.translate`); ``0 0`` (or no entry) means
  the coordinates are map coordinates already.
- ``lunghezza minima dei pendenti`` (minimum dangle length) and ``area minima`` (minimum area)
  are not in the thesis' list: they are this toolbox's extension for area building.

Each algorithm declares which entries it uses; :meth:`ParameterFile.warn_unused` names every
other entry of the file, so nothing in the file is silently ignored: the entries other steps use
in an information message (the file is shared by the whole job), unknown names in a warning.
"""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError
from toolbox.io.text import read_text

# canonical key -> (kind, names accepted; the first is the thesis' Italian name)
KEYS: dict[str, tuple[str, tuple[str, ...]]] = {
    "identification_tolerance": ("length", (
        "tolleranza di identificazione", "identification tolerance", "pick tolerance")),
    "snap_tolerance": ("length", (
        "tolleranza di riattacco planimetrico", "tolleranza di riattacco", "snap tolerance",
        "planimetric snap tolerance", "reattach tolerance", "reconnection tolerance",
        "planimetric reattach tolerance")),
    "height_snap_tolerance": ("length", (
        "tolleranza di riattacco altimetrico", "height snap tolerance",
        "altimetric reattach tolerance", "height reattach tolerance")),
    "coordinate_unit": ("text", (
        "unita di misura delle coordinate", "unita di misura", "coordinate unit",
        "coordinate units", "units")),
    "decimals": ("count", (
        "numero di cifre decimali", "cifre decimali", "decimals", "number of decimals")),
    "coordinate_offset": ("pair", (
        "traslazione delle coordinate", "coordinate offset", "coordinate translation",
        "false origin")),
    "alignment_tolerance": ("length", (
        "tolleranza planimetrica di allineamento", "tolleranza di allineamento",
        "alignment tolerance")),
    "squaring_tolerance": ("length", (
        "tolleranza planimetrica di squadratura", "tolleranza di squadratura",
        "squaring tolerance", "planimetric squaring tolerance")),
    "squaring_angle_tolerance": ("angle", (
        "tolleranza angolare di squadratura", "angular squaring tolerance",
        "squaring angle tolerance")),
    "spline_step": ("length", ("passo di spline", "spline step")),
    "closure_tolerance": ("length", ("tolleranza di chiusura", "closure tolerance")),
    "polyline_end_tolerance": ("length", (
        "tolleranza di fine polilinea", "tolleranza di fine polline",  # the thesis' misprint
        "end of polyline tolerance", "polyline end tolerance")),
    "min_dangle_length": ("length", (
        "lunghezza minima dei pendenti", "lunghezza minima pendenti", "lunghezza minima pendente",
        "minimum dangle length", "min dangle length")),
    "min_area": ("length", ("area minima", "minimum area", "min area")),
}

#: the value of an entry when neither a parameter nor the file gives it (the one table of the
#: file-backed defaults: topology, attribution and the editing tools read it through resolve())
DEFAULTS: dict[str, float] = {
    "snap_tolerance": 0.2, "height_snap_tolerance": 0.1, "closure_tolerance": 0.5,
    "min_dangle_length": 1.0, "min_area": 1.0, "decimals": 3, "alignment_tolerance": 0.1,
    "squaring_tolerance": 0.2, "squaring_angle_tolerance": 3.0, "spline_step": 1.0,
}

_SPLIT_RE = re.compile(r"^(?P<name>[^=:\t]+?)\s*(?:=|:|\t)\s*(?P<value>.*)$")
_UNIT_RE = re.compile(r"\s*[\[(][^\])]*[\])]\s*$")
_METRE = {"m", "metre", "metres", "meter", "meters", "metro", "metri"}


def normalise_name(name: str) -> str:
    """Lowercase, accents removed, one space between words, unit in brackets dropped."""
    text = unicodedata.normalize("NFKD", name)
    text = "".join(ch for ch in text if not unicodedata.combining(ch))
    text = _UNIT_RE.sub("", text.lower())
    return " ".join(text.replace("_", " ").replace("-", " ").split())


_LOOKUP = {normalise_name(alias): key for key, (_, aliases) in KEYS.items() for alias in aliases}


@dataclass
class ParameterFile:
    """What :func:`read_parameter_file` found.

    Attributes
    ----------
    path : Path
    values : dict
        Canonical key (see :data:`KEYS`) -> value: float for lengths and angles (degrees), int
        for ``decimals``, str for ``coordinate_unit``, (east, north) floats for
        ``coordinate_offset``.
    line_numbers : dict
        Canonical key -> line of the file it came from (1-based).
    names : dict
        Canonical key -> the name as written in the file.
    unknown : list of (line number, name)
        Entries whose name is not in :data:`KEYS` (kept for the caller to report).
    """

    path: Path
    values: dict[str, Any] = field(default_factory=dict)
    line_numbers: dict[str, int] = field(default_factory=dict)
    names: dict[str, str] = field(default_factory=dict)
    unknown: list[tuple[int, str]] = field(default_factory=list)

    def get(self, key: str, default: Any = None) -> Any:
        return self.values.get(key, default)

    @property
    def offset(self) -> tuple[float, float]:
        """The coordinate translation (east, north) to add to stored coordinates; (0, 0)."""
        return tuple(self.values.get("coordinate_offset", (0.0, 0.0)))  # type: ignore[return-value]

    def translate(self, geoms: Any) -> Any:
        """Geometries (array or sequence of shapely objects) with the translation added to X and
        Y (Z unchanged); the input itself when there is no translation."""
        import numpy as np
        import shapely

        de, dn = self.offset
        if de == 0 and dn == 0:
            return geoms
        arr = np.asarray(geoms, dtype=object)

        def add(coords: np.ndarray) -> np.ndarray:
            out = coords.copy()
            out[:, 0] += de
            out[:, 1] += dn
            return out

        return shapely.transform(arr, add, include_z=True)

    def unused(self, used: Iterable[str]) -> list[str]:
        """``'name' (line N)`` of every entry the caller does not use, in file order."""
        used = set(used)
        rows = [(self.line_numbers[k], self.names[k]) for k in self.values if k not in used]
        rows += self.unknown
        return [f"{name!r} (line {line})" for line, name in sorted(rows)]

    def warn_unused(self, used: Iterable[str], feedback: Any, who: str) -> list[str]:
        """Name every entry ``who`` (e.g. "attribution:square") does not use; returns the names
        (empty when all are used).

        The file is shared by every step of a job (the plotting software's one "file dei
        parametri"), so known entries other steps use are only an information message; a
        warning names the entries no step knows (a misspelt name is not silently ignored).
        """
        names = self.unused(used)
        if not names or feedback is None:
            return names
        unknown = [f"{name!r} (line {line})" for line, name in sorted(self.unknown)]
        known = [n for n in names if n not in unknown]
        where = f"PARAMETERS '{self.path.name}'"
        if unknown:
            feedback.push_warning(f"{where}: {len(unknown)} entries not recognised (not a known "
                                  f"'file dei parametri' entry: misspelt?): {', '.join(unknown)}")
        if known:
            feedback.push_info(f"{where}: {len(known)} entries for other steps, not used by "
                               f"{who}: {', '.join(known)}")
        return names

    def check_unit(self, crs: Any, feedback: Any) -> None:
        """Warn when the coordinate unit entry does not match the CRS's axis unit."""
        unit = self.get("coordinate_unit")
        if unit is None or crs is None or feedback is None or not crs.axis_info:
            return
        crs_unit = crs.axis_info[0].unit_name.lower()
        if (unit.lower() in _METRE) != (crs_unit in _METRE):
            feedback.push_warning(f"PARAMETERS gives coordinates in {unit!r} but the CRS unit is "
                                  f"{crs_unit!r}: tolerances are used in CRS units")


def _number(text: str) -> float:
    text = text.strip()
    if "," in text and "." not in text and text.count(",") == 1:
        text = text.replace(",", ".")  # Italian decimal comma
    value = float(text)
    if value != value or value in (float("inf"), float("-inf")):
        raise ValueError(text)
    return value


def _convert(kind: str, raw: str) -> Any:
    if kind == "text":
        if not raw:
            raise ValueError(raw)
        return raw
    if kind == "pair":
        parts = [p for p in re.split(r"[;\s]+|,(?=\s)", raw) if p]
        if len(parts) != 2:
            raise ValueError(raw)
        return (_number(parts[0]), _number(parts[1]))
    value = _number(raw)
    if value < 0 or (kind == "angle" and value >= 45):
        raise ValueError(raw)
    if kind == "count":
        if value != int(value):
            raise ValueError(raw)
        return int(value)
    return value


_EXPECTED = {"length": "a number >= 0", "count": "a whole number >= 0", "text": "a text",
             "pair": "two numbers (east north)", "angle": "an angle in degrees, 0 <= a < 45"}


def read_parameter_file(path: str | Path, name: str = "PARAMETERS") -> ParameterFile:
    """Read a parameter file (format in the module docstring).

    Parameters
    ----------
    path : str or Path
        The text file.
    name : str
        Parameter name used in error messages.

    Raises
    ------
    InputDataError
        Unreadable file, a line that is not ``name = value``, a bad value (the message names
        the file, the line, the entry and what was expected) or an entry given twice.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "parametri.txt"
    >>> _ = p.write_text("tolleranza di chiusura = 0,5\\nnumero di cifre decimali: 3\\n")
    >>> read_parameter_file(p).values
    {'closure_tolerance': 0.5, 'decimals': 3}
    """
    path = Path(path)
    text = read_text(path, name)
    if "\x00" in text:
        raise InputDataError(f"{name}: '{path}' is not a text file (binary content)")
    result = ParameterFile(path)
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.split("#", 1)[0].strip()
        if not content or content.startswith(";"):
            continue
        match = _SPLIT_RE.match(content)
        if not match:
            raise InputDataError(f"{name}: '{path}' line {number}: expected 'name = value', got "
                                 f"{content!r}")
        raw_name, raw_value = match.group("name").strip(), match.group("value").strip()
        key = _LOOKUP.get(normalise_name(raw_name))
        if key is None:
            result.unknown.append((number, raw_name))
            continue
        kind = KEYS[key][0]
        try:
            value = _convert(kind, raw_value)
        except ValueError:
            raise InputDataError(f"{name}: '{path}' line {number}: {raw_name!r} must be "
                                 f"{_EXPECTED[kind]}, got {raw_value!r}") from None
        if key in result.values:
            raise InputDataError(f"{name}: '{path}' line {number}: {raw_name!r} is given twice "
                                 f"(first on line {result.line_numbers[key]})")
        result.values[key] = value
        result.line_numbers[key] = number
        result.names[key] = raw_name
    if not result.values and not result.unknown:
        raise InputDataError(f"{name}: '{path}' holds no 'name = value' line (empty file?)")
    return result


def optional_parameter_file(path: Any, name: str = "PARAMETERS") -> ParameterFile | None:
    """The parsed parameter file at ``path`` (messages call it ``name``), or None when not
    given."""
    return None if path is None else read_parameter_file(path, name)


def resolve(explicit: Any, file: ParameterFile | None, key: str, default: Any = None
            ) -> tuple[Any, str]:
    """An explicit value, else the file's entry ``key``, else ``default`` (None: the table
    :data:`DEFAULTS`); with its source (``"parameter"``, ``"file"``, ``"default"``).

    ``key = "decimals"`` resolves a precision (CRS units): an explicit value is one, the
    file's number of decimals d gives 10^-d, and so does the default."""
    if explicit is not None:
        return explicit, "parameter"
    if file is not None and key in file.values:
        value = file.values[key]
        return (10.0 ** -value if key == "decimals" else value), "file"
    value = DEFAULTS.get(key) if default is None else default
    if key == "decimals" and default is None:
        value = 10.0 ** -value
    return value, "default"
