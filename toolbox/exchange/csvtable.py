"""Orthority-style CSV of exterior orientations (and this package's OPK CSV), with ``.prj``.

Reading: delimiter (comma, semicolon, tab or spaces) and quote character (``"`` or ``'``) found
from the text; fields located by header name in any order (case-insensitive): ``filename``
(or ``photo``/``image``/``id``), the position as ``x, y, z`` (world CRS) or ``latitude,
longitude, altitude`` (WGS84 degrees, ellipsoidal metres), the attitude as ``omega, phi,
kappa`` or ``roll, pitch, yaw`` (Pix4D/Orthority body angles), optional ``camera``; other columns
are ignored. Without a header, the legacy order ``filename x y z omega phi kappa``.

Angle units: a column name may state its unit (``omega_deg``, ``kappa [rad]``, ``phi_gon``); the
three angle columns must agree, and a unit given by the caller must agree with them (mixed or
contradicting units are an error). With no unit stated anywhere the angles are **degrees**,
Orthority's documented default, and the summary says so.

CRS: the ``.prj`` sidecar (same path, ``.prj`` extension: WKT, ESRI WKT, PROJ or EPSG text) or
the caller's CRS for ``x, y, z``; both given, the positions' centroid is transformed from one
to the other (:func:`toolbox.io.crs.centroid_shift`): moved by over 1 mm, an error naming both
CRSs and the shift (an ESRI ``.prj`` of the caller's CRS moves nothing); ``latitude...``
positions go to the caller's CRS or to the UTM zone of their mean (said in the notes).
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.exchange import geodesy
from toolbox.exchange.model import OrientationSet, PhotoOrientation, opk_from_matrix
from toolbox.io.text import csv_dialect, read_text
from toolbox.photogrammetry.rotation import angle_unit as canonical_unit
from toolbox.photogrammetry.rotation import check_within_turn, from_radians, to_radians

ALIASES = {
    "filename": ("filename", "photo", "photo_id", "image", "image_name", "imagename", "id",
                 "name", "label"),
    "x": ("x", "x0", "easting"), "y": ("y", "y0", "northing"), "z": ("z", "z0", "height"),
    "latitude": ("latitude", "lat"), "longitude": ("longitude", "lon", "lng", "long"),
    "altitude": ("altitude", "alt"),
    "omega": ("omega",), "phi": ("phi",), "kappa": ("kappa",),
    "roll": ("roll",), "pitch": ("pitch",), "yaw": ("yaw",), "camera": ("camera", "camera_id"),
}
LEGACY = ("filename", "x", "y", "z", "omega", "phi", "kappa")
_UNIT = re.compile(r"^(?P<name>[a-z0-9_]+?)[\s_]*(?:[\[(](?P<u1>[a-z°]+)[\])]|_(?P<u2>deg|degrees|"
                   r"rad|radians|gon|grad))?$")


def _number(cell: str, delimiter: str) -> float:
    """A cell's number; in a ``;``-separated file a decimal comma (``1681000,5``, as a
    spreadsheet in an Italian locale saves it) too. A thousands dot (``1.681.000,5``) is not a
    number (ValueError)."""
    if delimiter == ";" and cell.count(",") == 1 and "." not in cell:
        cell = cell.replace(",", ".")
    return float(cell)


def _fields(header: list[str], path: Path) -> tuple[dict[str, int], str | None]:
    """Field -> column index, and the angle unit the header states (or None)."""
    found: dict[str, int] = {}
    units: dict[str, str] = {}
    for k, raw in enumerate(header):
        m = _UNIT.match(raw.strip().lower().replace("-", "_"))
        if not m:
            continue
        name = m.group("name").rstrip("_")
        for field, aliases in ALIASES.items():
            if name in aliases and field not in found:
                found[field] = k
                unit = m.group("u1") or m.group("u2")
                if unit and field in ("omega", "phi", "kappa", "roll", "pitch", "yaw"):
                    units[raw] = canonical_unit(unit, f"{path} column {raw!r}")
    if len(set(units.values())) > 1:
        raise InputDataError(f"{path}: mixed angle units in the header: "
                             + ", ".join(f"{k} in {v}" for k, v in units.items()))
    return found, next(iter(units.values()), None)


def looks_like(text: str) -> bool:
    """A header naming a file and a position and attitude, or a legacy row of
    ``name`` + 6 numbers."""
    delimiter, quote = csv_dialect(text)
    try:
        first = next(csv.reader(io.StringIO(text), delimiter=delimiter, quotechar=quote,
                                skipinitialspace=delimiter == " "), [])
    except csv.Error:
        return False
    first = [c.strip() for c in first if c.strip()]
    try:
        fields, _ = _fields(first, Path("<text>"))
    except (InputDataError, ParameterError):
        return True  # angle columns with mixed or unknown units: the reader says which
    if "filename" in fields and ({"x", "y", "z"} <= set(fields) or
                                 {"latitude", "longitude", "altitude"} <= set(fields)):
        return True
    try:
        [_number(v, delimiter) for v in first[1:7]]
    except ValueError:
        return False
    return len(first) >= 7


def read_csv(path: str | Path, crs: Any = None, angle_unit: str | None = None) -> OrientationSet:
    """Exterior orientations of an Orthority-style CSV (see the module docstring)."""
    from toolbox.io.crs import PRJ_TOLERANCE_M, crs_label, read_prj
    from toolbox.photogrammetry.readers.text import photo_id
    from toolbox.photogrammetry.tables import listed

    path = Path(path)
    text = read_text(path)  # UTF-8 (BOM or not), else Windows/Latin-1 (foto_città_001.tif)
    delimiter, quote = csv_dialect(text)
    try:
        rows = [r for r in csv.reader(io.StringIO(text), delimiter=delimiter, quotechar=quote,
                                      skipinitialspace=delimiter == " ")
                if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    except csv.Error as exc:  # a lone carriage return inside a field, ...
        raise InputDataError(f"{path} is not a readable table: {exc}") from None
    rows = [[c.strip() for c in r if not (delimiter == " " and c == "")] for r in rows]
    if not rows:
        raise InputDataError(f"{path} holds no rows")
    fields, header_unit = _fields(rows[0], path)
    if "filename" in fields and len(fields) >= 4:
        body = rows[1:]
    else:
        fields, header_unit, body = {k: i for i, k in enumerate(LEGACY)}, None, rows
    position = "xyz" if all(k in fields for k in "xyz") else \
        "lla" if all(k in fields for k in ("latitude", "longitude", "altitude")) else None
    attitude = "opk" if all(k in fields for k in ("omega", "phi", "kappa")) else \
        "rpy" if all(k in fields for k in ("roll", "pitch", "yaw")) else None
    if "filename" not in fields or position is None or attitude is None:
        raise InputDataError(f"{path}: the header needs filename, x/y/z or latitude/longitude/"
                             "altitude, and omega/phi/kappa or roll/pitch/yaw; found: "
                             f"{listed(rows[0])}")
    if angle_unit is not None:
        given = canonical_unit(angle_unit, "ANGLE_UNIT")
        if header_unit is not None and given != header_unit:
            raise ParameterError("ANGLE_UNIT", f"is {given} but {path} states {header_unit} in "
                                 "its header (contradicting angle units)")
        header_unit = given
    unit = header_unit or "deg"
    out = OrientationSet(source=str(path), format="csv")
    out.notes.append(f"angles ({attitude}) in {unit}" + ("" if header_unit else
                     " (not stated: Orthority's CSV default, degrees)"))
    names = [k for k in ("x", "y", "z") if position == "xyz"] or \
        ["longitude", "latitude", "altitude"]
    angles = ["omega", "phi", "kappa"] if attitude == "opk" else ["roll", "pitch", "yaw"]
    ids, cams, values = [], [], []
    for lineno, row in enumerate(body, start=2 if body is not rows else 1):
        try:
            values.append([_number(row[fields[k]], delimiter) for k in names + angles])
        except (IndexError, ValueError):
            raise InputDataError(f"{path}, row {lineno}: expected numbers in "
                                 f"{', '.join(names + angles)}, got {row!r}") from None
        ids.append(row[fields["filename"]])
        cams.append(row[fields["camera"]] if "camera" in fields and
                    len(row) > fields["camera"] else None)
    if not values:
        raise InputDataError(f"{path} holds a header but no orientation row")
    values = np.array(values)
    if not np.isfinite(values).all():
        raise InputDataError(f"{path}: a position or angle is NaN or infinite")
    prj = path.with_suffix(".prj")
    prj_crs = read_prj(prj) if prj.is_file() else None
    if position == "xyz":
        if prj_crs is None and crs is None:
            raise InputDataError(f"{path}: x, y, z positions need a CRS: give CRS or put a "
                                 f"{prj.name} beside the file")
        if prj_crs is not None and crs is not None:
            out.crs = _check_prj(prj, prj_crs, crs, values[:, :2])
            out.notes.append(f"CRS as given; {prj.name}'s ({crs_label(prj_crs)}) is the same "
                             f"at the positions (within {PRJ_TOLERANCE_M * 1000:g} mm)")
        else:
            out.crs = geodesy.require_projected(prj_crs or crs, str(path))
            out.notes.append(f"CRS from {prj.name}" if prj_crs is not None else "CRS as given")
        xyz = values[:, :3]
    else:
        lon, lat = values[:, 0], values[:, 1]
        out.crs = geodesy.require_projected(crs, str(path)) if crs is not None else \
            geodesy.utm_crs(float(lon.mean()), float(lat.mean()))
        out.notes.append("latitude/longitude/altitude on WGS84 -> " + out.crs.name)
        xyz = geodesy.geographic_to_grid(lon, lat, values[:, 2], out.crs)
        from toolbox.ortho.vertical import vertical_part

        if vertical_part(out.crs) is None:  # the heights stay ellipsoidal, the CRS says nothing
            out.notes.append(f"{path.name}: the altitudes' datum (WGS84 ellipsoidal) is not "
                             f"carried over by {out.crs.name}, which states no height datum: "
                             "give HEIGHTS ellipsoidal to ortho:photo/ortho:batch (a DEM of "
                             "orthometric heights is otherwise taken as the same datum, ~50 m "
                             "off in Italy), or a compound CRS to have them converted")
    check_within_turn(values[:, 3:], unit, "ANGLE_UNIT" if angle_unit is not None or
                      header_unit is None else f"{path}'s header unit", str(path))
    rad = to_radians(values[:, 3:], unit)
    for k, name in enumerate(ids):
        if attitude == "opk":
            opk = tuple(float(a) for a in rad[k])
        else:
            r = geodesy.rpy_to_grid_rotation(*rad[k], values[k, 0], values[k, 1], values[k, 2],
                                             out.crs)
            opk = opk_from_matrix(r, name)
        out.add_photo(PhotoOrientation(photo_id(name), cams[k], name, tuple(xyz[k].tolist()), opk),
                      str(path))
    if attitude == "rpy":
        out.notes.append("roll/pitch/yaw: body x front, y right, z down; camera x = body y, "
                         "y = body x (nadir camera, top forward); with the meridian convergence")
    return out


def _check_prj(prj: Path, prj_crs: Any, crs: Any, xy: np.ndarray) -> Any:
    """The CRS parameter ``crs`` when the ``.prj``'s CRS is the same CRS at the positions
    ``xy``: the centroid moves by at most :data:`toolbox.io.crs.PRJ_TOLERANCE_M` from one to
    the other (an ESRI ``.prj`` rarely equals its EPSG code's definition), and no two
    different height datums are stated; else an error naming both and the shift."""
    from toolbox.io.crs import (
        PRJ_TOLERANCE_M,
        centroid_shift,
        check_same_heights,
        crs_label,
        parse_crs,
        shift_phrase,
    )

    given = geodesy.require_projected(parse_crs(crs, "CRS"), "CRS")
    shift, centre = centroid_shift(prj_crs, given, xy)
    if not shift <= PRJ_TOLERANCE_M:
        raise ParameterError("CRS", f"{crs_label(given)} contradicts {prj.name} "
                             f"({crs_label(prj_crs)}): {shift_phrase(shift, centre)}; the "
                             f"x, y, z positions are in one CRS: give CRS as the {prj.name}'s, "
                             "or none")
    check_same_heights(prj.name, prj_crs, "CRS", given)
    return given


def write_csv(oset: OrientationSet, path: str | Path, angle_unit: str = "deg") -> Path:
    """``filename,x,y,z,omega,phi,kappa,camera`` (angles in ``angle_unit``; the column names
    carry the unit unless it is degrees, Orthority's default) and a ``.prj`` with the CRS."""
    unit = canonical_unit(angle_unit, "ANGLE_UNIT")
    photos = [p for p in oset.photos.values() if p.oriented]
    if not photos:
        raise InputDataError("no photo has an exterior orientation to write")
    suffix = "" if unit == "deg" else f"_{unit}"
    path = Path(path)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["filename", "x", "y", "z", f"omega{suffix}", f"phi{suffix}",
                     f"kappa{suffix}", "camera"])
    for p in photos:
        writer.writerow([p.id, *(f"{v:.4f}" for v in p.xyz),
                         *(f"{from_radians(a, unit) + 0.0:.10f}".replace("-0.0000000000", "0.0000000000")
                           for a in p.opk), p.camera or ""])
    path.write_text(buffer.getvalue(), encoding="utf-8")
    if oset.crs is not None:
        path.with_suffix(".prj").write_text(oset.crs.to_wkt(), encoding="utf-8")
    return path
