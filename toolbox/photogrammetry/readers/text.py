"""Exterior orientations from delimited text: the native CSV and the omega-phi-kappa exports.

Formats (``format=`` name, how :func:`sniff_format` recognises it, what is accepted)
-----------------------------------------------------------------------------------
``native`` (this toolbox's CSV)
    Comma-separated, one header row, ``#`` comment lines allowed. Required columns (names
    case-insensitive): ``photo``, ``X0``, ``Y0``, ``Z0``, ``omega``, ``phi``, ``kappa``; the angle
    unit comes from an ``angle_unit`` column (rad/deg/gon, per row) or from the caller. Optional:
    ``camera``, ``image``, ``strip``; other columns are kept for filtering (``where=``) and
    otherwise ignored. ``X0_m``/``Y0_m``/``Z0_m`` are accepted for X0/Y0/Z0 (the bundled
    ``exterior_orientation.csv`` uses them). Recognised by a header naming X0 and omega.
``pix4d``
    Pix4D's ``*_calibrated_external_camera_parameters.txt``: header ``imageName X Y Z Omega Phi
    Kappa``, space-separated rows, angles in **degrees**, X/Y/Z in the project's output CRS.
``metashape``
    Agisoft Metashape "Omega Phi Kappa (*.txt)" camera export: comment lines ``# Cameras (n)``
    and ``# PhotoID, X, Y, Z, Omega, Phi, Kappa, r11, r12, r13, r21, r22, r23, r31, r32, r33``,
    then tab-separated rows, angles in **degrees**. When the nine ``r`` values are present they are
    checked against the angles: they must equal R(ω, φ, κ) or its transpose (either convention
    is accepted, the one found is reported), otherwise the row is refused.
``opk`` (generic)
    Any comma/semicolon/tab/space-separated text with rows ``id X Y Z omega phi kappa`` (7 or
    more columns, extra ones ignored), with or without a header row; header names are matched
    case-insensitively (``filename``/``image``/``name``/``id``/``photo``; ``x``/``easting``;
    ``y``/``northing``; ``z``/``altitude``/``height``; ``omega``; ``phi``; ``kappa``). The angle unit
    must be given by the caller: such files do not state it.

Every format uses the classical photogrammetric ("PATB") axes: image x right, y up, the camera
looking down its -z axis, and R(ω, φ, κ) = Rx(ω)·Ry(φ)·Rz(κ) mapping image to ground axes
(:mod:`toolbox.photogrammetry.rotation`). Photo ids are the names given, without folders and
without a common image extension (``DSC0001.JPG`` -> ``DSC0001``).
"""

from __future__ import annotations

import csv
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import PureWindowsPath
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.io.text import is_number
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.rotation import angle_unit as canonical_unit
from toolbox.photogrammetry.rotation import rotation_matrix

IMAGE_EXTENSIONS = {".tif", ".tiff", ".jpg", ".jpeg", ".png", ".jp2", ".j2k", ".ecw", ".sid",
                    ".img", ".bmp", ".dng", ".raw", ".cr2", ".nef", ".arw", ".iiq", ".webp"}
COLUMN_ALIASES: dict[str, tuple[str, ...]] = {
    "photo": ("photo", "photo_id", "photoid", "id", "image_id", "imagename", "image_name",
              "filename", "file", "name", "label"),
    "x0": ("x0", "x0_m", "x", "easting", "east", "e"),
    "y0": ("y0", "y0_m", "y", "northing", "north", "n"),
    "z0": ("z0", "z0_m", "z", "altitude", "alt", "height", "h", "elevation"),
    "omega": ("omega", "omega_deg", "omega_rad", "omega_gon", "o"),
    "phi": ("phi", "phi_deg", "phi_rad", "phi_gon", "p"),
    "kappa": ("kappa", "kappa_deg", "kappa_rad", "kappa_gon", "k"),
}
MATRIX_COLUMNS = tuple(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))
MATRIX_TOLERANCE = 1e-5  # exports print about 6-10 decimals


@dataclass
class OrientationTable:
    """Exterior orientations read from one file, in file order."""

    source: str
    format: str
    orientations: dict[str, ExteriorOrientation]
    attributes: dict[str, dict[str, str]] = field(default_factory=dict)  # photo -> extra columns
    notes: list[str] = field(default_factory=list)


def photo_id(name: str) -> str:
    """The id of a photo named ``name``: no folder, no common image extension."""
    base = PureWindowsPath(str(name).strip().strip('"').strip("'")).name
    stem, dot, ext = base.rpartition(".")
    return stem if dot and f".{ext.lower()}" in IMAGE_EXTENSIONS else base


def _norm(name: str) -> str:
    return re.sub(r"[\s\[\]()]+", "", name.strip().lstrip("#").strip().lower())


def _match_columns(header: list[str], required: tuple[str, ...]) -> dict[str, int]:
    names = [_norm(h) for h in header]
    found: dict[str, int] = {}
    for key in required:
        for alias in COLUMN_ALIASES[key]:
            if alias in names:
                found[key] = names.index(alias)
                break
    return found


def sniff_format(text: str) -> str:
    """``zmap_log``, ``metashape``, ``pix4d``, ``native`` or ``opk`` from the first lines."""
    head = text[:4000]
    if "COMPENSAZIONE A STELLE PROIETTIVE" in head:
        return "zmap_log"
    lines = [ln.strip() for ln in head.splitlines() if ln.strip()]
    if any(re.match(r"#\s*PhotoID\s*,\s*X\s*,\s*Y\s*,\s*Z\s*,\s*Omega", ln, re.I) for ln in lines):
        return "metashape"
    if lines and re.match(r"imageName\s+X\s+Y\s+Z\s+Omega\s+Phi\s+Kappa", lines[0], re.I):
        return "pix4d"
    first = next((ln for ln in lines if not ln.startswith("#")), "")
    cols = [_norm(c) for c in first.split(",")]
    if len(cols) > 1 and any(c in ("x0", "x0_m") for c in cols) and "omega" in cols:
        return "native"
    return "opk"


def _float(value: str, photo: str, column: str, source: str, lineno: int) -> float:
    try:
        number = float(str(value).strip())
    except ValueError:
        number = float("nan")
    if not np.isfinite(number):
        raise InputDataError(f"{source}, line {lineno}: photo {photo!r} has no valid {column} "
                             f"(got {value!r})")
    return number


def _add(table: OrientationTable, eo: ExteriorOrientation, lineno: int) -> None:
    if eo.photo in table.orientations:
        raise InputDataError(f"{table.source}, line {lineno}: photo {eo.photo!r} appears twice "
                             "(filter the rows, e.g. by run and stage)")
    table.orientations[eo.photo] = eo


def read_native_csv(text: str, source: str = "<text>", angle_unit: str | None = None,
                    crs: Any = None, where: Mapping[str, str] | None = None) -> OrientationTable:
    """The native CSV (see the module docstring). ``where`` keeps rows whose columns equal the
    given values, e.g. ``{"run": "block", "stage": "final"}``."""
    rows = [(i, ln) for i, ln in enumerate(text.splitlines(), start=1)
            if ln.strip() and not ln.lstrip().startswith("#")]
    if not rows:
        raise InputDataError(f"{source} holds no rows")
    header = [h.strip() for h in next(csv.reader([rows[0][1]]), [])]
    cols = _match_columns(header, ("photo", "x0", "y0", "z0", "omega", "phi", "kappa"))
    missing = [k for k in ("photo", "x0", "y0", "z0", "omega", "phi", "kappa") if k not in cols]
    if missing:
        raise InputDataError(f"{source}: the header lacks column(s) {', '.join(missing)} "
                             f"(found: {', '.join(header)})")
    lower = [h.lower() for h in header]
    unit_col = lower.index("angle_unit") if "angle_unit" in lower else None
    if unit_col is None and angle_unit is None:
        raise ParameterError("ANGLE_UNIT", f"is required: {source} has no angle_unit column "
                             "(expected rad, deg or gon)")
    filters = {k.lower(): str(v) for k, v in (where or {}).items()}
    for key in filters:
        if key not in lower:
            raise ParameterError("WHERE", f"names column {key!r}, which {source} does not have "
                                 f"(columns: {', '.join(header)})")
    table = OrientationTable(source, "native", {})
    needed = 1 + max(cols[k] for k in ("photo", "x0", "y0", "z0", "omega", "phi", "kappa"))
    used_units: set[str] = set()
    for lineno, line in rows[1:]:
        values = next(csv.reader([line]), [])  # one record per line (no quoted line breaks)
        if len(values) < needed:
            raise InputDataError(f"{source} line {lineno}: {len(values)} fields, expected at "
                                 f"least {needed} (photo, x0 .. kappa; header: "
                                 f"{', '.join(header)})")
        record = dict(zip(lower, (v.strip() for v in values), strict=False))
        if any(record.get(k, "") != v for k, v in filters.items()):
            continue
        pid = photo_id(values[cols["photo"]])
        unit = angle_unit if unit_col is None or not record.get("angle_unit") else \
            record["angle_unit"]
        unit = canonical_unit(unit, f"{source} line {lineno}: angle_unit")
        used_units.add(unit)
        numbers = [_float(values[cols[k]], pid, header[cols[k]], source, lineno)
                   for k in ("x0", "y0", "z0", "omega", "phi", "kappa")]
        _add(table, ExteriorOrientation.from_angles(pid, *numbers, unit=unit, crs=crs), lineno)
        table.attributes[pid] = {h: record.get(h.lower(), "") for h in header}
    if not table.orientations:
        raise InputDataError(f"{source}: no row left" + (f" after filtering on {filters}"
                                                         if filters else ""))
    table.notes.append(f"angle unit(s): {', '.join(sorted(used_units))}")
    return table


def _split(line: str) -> list[str]:
    if "\t" in line:
        parts = line.split("\t")
    elif "," in line:
        parts = line.split(",")
    elif ";" in line:
        parts = line.split(";")
    else:
        parts = line.split()
    return [p.strip() for p in parts if p.strip() != ""]


def read_opk_text(text: str, source: str = "<text>", angle_unit: str | None = None,
                  crs: Any = None, fmt: str = "opk") -> OrientationTable:
    """Pix4D, Metashape or generic omega-phi-kappa text (see the module docstring)."""
    if fmt in ("pix4d", "metashape"):
        unit = canonical_unit(angle_unit or "deg", "ANGLE_UNIT")
    elif angle_unit is None:
        raise ParameterError("ANGLE_UNIT", f"is required for {source}: omega-phi-kappa text "
                             "files do not state their angle unit (expected rad, deg or gon)")
    else:
        unit = canonical_unit(angle_unit, "ANGLE_UNIT")
    table = OrientationTable(source, fmt, {})
    order = (0, 1, 2, 3, 4, 5, 6)
    matrix_cols: tuple[int, ...] | None = (7, 8, 9, 10, 11, 12, 13, 14, 15) \
        if fmt == "metashape" else None
    conventions: set[str] = set()
    header_seen = False
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if re.match(r"#\s*PhotoID", line, re.I):
                header = _split(line.lstrip("#"))
                cols = _match_columns(header, ("photo", "x0", "y0", "z0", "omega", "phi", "kappa"))
                if len(cols) == 7:
                    order = tuple(cols[k] for k in ("photo", "x0", "y0", "z0", "omega", "phi",
                                                    "kappa"))
                names = [_norm(h) for h in header]
                if all(r in names for r in MATRIX_COLUMNS):
                    matrix_cols = tuple(names.index(r) for r in MATRIX_COLUMNS)
            continue
        parts = _split(line)
        if not header_seen:
            header_seen = True
            if not is_number(parts[1] if len(parts) > 1 else ""):
                cols = _match_columns(parts, ("photo", "x0", "y0", "z0", "omega", "phi", "kappa"))
                missing = [k for k in ("photo", "x0", "y0", "z0", "omega", "phi", "kappa")
                           if k not in cols]
                if missing:
                    raise InputDataError(f"{source}, line {lineno}: header lacks column(s) "
                                         f"{', '.join(missing)} (found: {', '.join(parts)})")
                order = tuple(cols[k] for k in ("photo", "x0", "y0", "z0", "omega", "phi",
                                                "kappa"))
                continue
        if len(parts) <= max(order):
            raise InputDataError(f"{source}, line {lineno}: expected id X Y Z omega phi kappa, "
                                 f"got {len(parts)} value(s): {line[:80]!r}")
        pid = photo_id(parts[order[0]])
        numbers = [_float(parts[order[k]], pid, name, source, lineno)
                   for k, name in enumerate(("X", "Y", "Z", "omega", "phi", "kappa"), start=1)]
        eo = ExteriorOrientation.from_angles(pid, *numbers, unit=unit, crs=crs)
        if matrix_cols is not None and len(parts) > max(matrix_cols):
            given = np.array([_float(parts[c], pid, f"r{c}", source, lineno)
                              for c in matrix_cols]).reshape(3, 3)
            conventions.add(_matrix_convention(given, eo, source, lineno))
        _add(table, eo, lineno)
    if not table.orientations:
        raise InputDataError(f"{source} holds no orientation rows")
    table.notes.append(f"angle unit: {unit}")
    if conventions:
        table.notes.append("rotation matrix columns: " + ", ".join(sorted(conventions)))
    return table


def _matrix_convention(given: np.ndarray, eo: ExteriorOrientation, source: str,
                       lineno: int) -> str:
    r = rotation_matrix(eo.omega, eo.phi, eo.kappa)
    if np.abs(given - r).max() <= MATRIX_TOLERANCE:
        return "R (image -> ground)"
    if np.abs(given - r.T).max() <= MATRIX_TOLERANCE:
        return "R transposed (ground -> image)"
    raise InputDataError(f"{source}, line {lineno}: photo {eo.photo!r}: the r11..r33 values do not "
                         f"match R(omega, phi, kappa) nor its transpose (max difference "
                         f"{min(np.abs(given - r).max(), np.abs(given - r.T).max()):.2g}); check "
                         "the angle unit and convention")
