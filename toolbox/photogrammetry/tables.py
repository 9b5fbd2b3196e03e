"""Small helpers shared by the orientation algorithms: CSV tables in and out, the project file."""

from __future__ import annotations

import csv
import importlib
import io
import json
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError, ParameterError
from toolbox.io.text import read_text


def read_csv_table(path: Path, name: str = "INPUT") -> tuple[list[str], list[dict[str, str]]]:
    """Header and rows of a delimited text file (delimiter sniffed among , ; tab, else
    spaces, with ``"`` or ``'`` quotes as Orthority/ODM write them).

    Lines starting with ``#`` are comments. Header names are kept as written; use
    :func:`column` to find one case-insensitively.
    """
    text = read_text(path, name)
    if "\x00" in text:
        raise InputDataError(f"{name}: {path} is not a text table (binary content)")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputDataError(f"{name}: {path} holds no rows")
    from toolbox.io.text import csv_dialect

    delimiter, quote = csv_dialect(lines[0])
    if delimiter == " ":  # Orthority/ODM: space-separated, names quoted ('100_0005_0142')
        lines = [ln.strip() for ln in lines]
        dialect: Any = {"delimiter": " ", "quotechar": quote, "skipinitialspace": True}
    else:
        try:
            dialect = {"dialect": csv.Sniffer().sniff(lines[0], delimiters=",;\t")}
        except csv.Error:
            dialect = {"dialect": csv.excel}
    try:
        records = list(csv.reader(io.StringIO("\n".join(lines)), **dialect))
    except csv.Error as exc:
        raise InputDataError(f"{name}: {path} is not a readable table: {exc}") from None
    header = [h.strip() for h in records[0]]
    if len(records) < 2:
        raise InputDataError(f"{name}: {path} has a header but no rows (at least one data row "
                             "is needed)")
    rows = []
    for number_, record in enumerate(records[1:], start=2):
        if len(record) > len(header) and any(v.strip() for v in record[len(header):]):
            raise InputDataError(f"{name}: {path}, data line {number_ - 1}: {len(record)} fields "
                                 f"but the header has {len(header)} ({listed(header)})")
        values = [v.strip() for v in record] + [""] * (len(header) - len(record))
        rows.append(dict(zip(header, values, strict=False)))
    return header, rows


def listed(items: Sequence[Any], limit: int = 200) -> str:
    """``items`` as ``a, b, c`` on one line (a damaged header may hold line breaks and junk),
    cut after ``limit`` characters."""
    text = ", ".join(" ".join(str(item).split()) for item in items)
    return text if len(text) <= limit else text[:limit] + "..."


def column(header: Sequence[str], *aliases: str, required: bool = True, name: str = "INPUT",
           path: Any = "") -> str | None:
    """The header entry matching one of ``aliases`` (case-insensitive), else None or an error."""
    lower = {h.lower(): h for h in header}
    for alias in aliases:
        if alias.lower() in lower:
            return lower[alias.lower()]
    if required:
        raise InputDataError(f"{name}: {path} has no {aliases[0]!r} column (also accepted: "
                             f"{', '.join(aliases[1:]) or '-'}); columns are: {listed(header)}")
    return None


def number(value: str, what: str, name: str = "INPUT") -> float:
    try:
        result = float(value)
    except (TypeError, ValueError):
        result = math.nan
    if not math.isfinite(result):
        raise InputDataError(f"{name}: {what} must be a number, got {value!r}")
    return result


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    """A CSV table; None and non-finite numbers (NaN: no value) are written empty: a ``nan``
    cell made OGR (QGIS, ogr2ogr with AUTODETECT_TYPE) read the whole column as text."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for row in rows:
            writer.writerow([_csv_cell(v) for v in row])
    return path


def _csv_cell(value: Any) -> Any:
    import numpy as np

    if value is None:
        return ""
    if isinstance(value, (float, np.floating)) and not math.isfinite(value):
        return ""
    return repr(float(value)) if isinstance(value, float) else value


def write_json(path: Path, document: Any) -> Path:
    """``document`` as JSON; a NaN or infinite number (no value: a sigma without redundancy,
    a condition number of a singular system) is written as ``null``: Python's ``NaN`` and
    ``Infinity`` are not JSON, and strict readers (JavaScript, jq, QGIS) refuse the file."""
    Path(path).write_text(json.dumps(_finite(document), indent=2, default=_json_default,
                                     allow_nan=False) + "\n", encoding="utf-8")
    return path


def _finite(value: Any) -> Any:
    """``value`` with every non-finite number replaced by None (dicts, lists, numpy arrays)."""
    import numpy as np

    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, np.ndarray):
        return _finite(value.tolist())
    return value


def _json_default(value: Any) -> Any:
    import numpy as np

    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def finite_or_none(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def read_table(path: Path, layer: str | None = None, name: str = "INPUT"
               ) -> tuple[list[str], list[dict[str, str]]]:
    """Header and rows (values as text) of a CSV/TXT file or of a GeoPackage layer's attributes
    (``layer``, default the first)."""
    if Path(path).suffix.lower() not in (".gpkg", ".sqlite"):
        return read_csv_table(path, name)
    import pyogrio

    try:
        frame = pyogrio.read_dataframe(path, layer=layer, read_geometry=False)
    except Exception as exc:  # pyogrio raises DataSourceError and friends
        raise InputDataError(f"{name}: cannot read {path}"
                             f"{'|layername=' + layer if layer else ''}: "
                             f"{str(exc).splitlines()[0]}") from None
    header = [str(c) for c in frame.columns]
    rows = [{h: "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v)
             for h, v in zip(header, values, strict=True)}
            for values in frame.itertuples(index=False, name=None)]
    if not rows:
        raise InputDataError(f"{name}: {path} holds no rows")
    _point_coordinates(path, layer, header, rows)
    return header, rows


def _point_coordinates(path: Path, layer: str | None, header: list[str],
                       rows: list[dict[str, str]]) -> None:
    """A point layer's geometry as ``X``, ``Y``, ``Z`` (blank for a 2D point) columns
    where no attribute gives that coordinate (:data:`XYZ_COLUMNS`), so that the PointZ layers
    the toolbox writes (tie points, intersected, monoplotted points) serve as CONTROL or GNSS
    as they are: without this their coordinates, held only by the geometry, were not seen."""
    import pyogrio

    try:
        info = pyogrio.read_info(path, layer=layer)
    except Exception:  # the attributes were read: nothing more to add
        return
    geometry_type = str(info.get("geometry_type") or "")
    if not geometry_type.startswith("Point"):
        return
    lower = {h.lower() for h in header}
    missing = [k for k, aliases in enumerate(XYZ_COLUMNS)
               if not any(a.lower() in lower for a in aliases)]
    if not missing:
        return
    import shapely

    _, _, wkb, _ = pyogrio.raw.read(path, layer=layer, columns=[])
    points = shapely.from_wkb(wkb)
    coords = shapely.get_coordinates(points, include_z=True)
    if len(coords) != len(rows) or shapely.is_empty(points).any():
        raise InputDataError(f"{path}{'|layername=' + layer if layer else ''}: a feature has "
                             f"an empty point geometry (give X, Y, Z columns or a point)")
    has_z = shapely.has_z(points)  # a 2D point's Z is blank: planimetric where allowed
    for k in missing:
        label = XYZ_COLUMNS[k][0]
        header.append(label)
        for row, value, z in zip(rows, coords[:, k], has_z, strict=True):
            row[label] = "" if (k == 2 and not z) or not math.isfinite(value) else repr(
                float(value))


def image_measurements(path: Path, layer: str | None, coordinates: str, name: str = "INPUT"):
    """Measured image points: ``(ids, photos, xy (M, 2), kind)`` from a table with ``photo``,
    optionally ``point_id``, and ``col_px``/``row_px`` (kind "pixel") or ``x_mm``/``y_mm``
    (kind "image"). ``coordinates`` is "auto", "pixel" or "image"."""
    import numpy as np

    header, rows = read_table(path, layer, name)
    c_photo = column(header, "photo", "photo_id", "image", name=name, path=path)
    c_id = column(header, "point_id", "point", "id", "name", required=False)
    pixel = column(header, "col_px", required=False) and column(header, "row_px", required=False)
    image = column(header, "x_mm", required=False) and column(header, "y_mm", required=False)
    kind = coordinates
    if kind == "auto":
        kind = "pixel" if pixel else "image" if image else ""
    if kind == "pixel" and not pixel or kind == "image" and not image or not kind:
        wanted = {"pixel": "col_px and row_px", "image": "x_mm and y_mm"}.get(
            kind, "col_px/row_px or x_mm/y_mm")
        raise InputDataError(f"{name}: {path} needs columns {wanted}; columns are: "
                             f"{listed(header)}")
    cu, cv = (column(header, "col_px"), column(header, "row_px")) if kind == "pixel" else \
        (column(header, "x_mm"), column(header, "y_mm"))
    ids = [r[c_id] if c_id else str(k + 1) for k, r in enumerate(rows)]
    photos = [r[c_photo] for r in rows]
    xy = np.array([[number(r[cu], f"row {k + 1} {cu}", name), number(r[cv], f"row {k + 1} {cv}",
                                                                       name)]
                   for k, r in enumerate(rows)])
    return ids, photos, xy, kind


#: what a PROJECT parameter accepts: the project YAML and other programs' orientation files,
#: read by the loaders registered in PROJECT_READERS (toolbox.exchange registers its own)
PROJECT_EXTENSIONS = [".yaml", ".yml", ".json", ".geojson", ".csv", ".txt", ".xml", ".ori"]
PROJECT_READERS: dict[str, Any] = {}


def load_project_parameter(path: Path, name: str = "PROJECT"):
    """Load a project file given as an algorithm parameter; errors name the parameter."""
    from toolbox.io.crs import crs_label, not_metric
    from toolbox.photogrammetry.project import load_project

    try:
        if Path(path).suffix.lower() not in (".yaml", ".yml"):  # another program's file
            if "exchange" not in PROJECT_READERS:  # a plugin: it imports this module
                importlib.import_module("toolbox.exchange")
            project = PROJECT_READERS["exchange"](path)
        else:
            project = load_project(path)
    except InputDataError as exc:
        raise InputDataError(f"{name}: {exc}") from None
    problem = None if project.crs is None else not_metric(project.crs)
    if problem:
        raise ParameterError(name, f"'{path}' is in {crs_label(project.crs)} "
                             f"({project.crs.name}), {problem}: the toolbox works in metres, x "
                             "east and y north; convert the project to a metric CRS first")
    return project


ROLES = ("control", "check")


XYZ_COLUMNS = (("X", "E", "easting", "X_m"), ("Y", "N", "northing", "Y_m"),
               ("Z", "H", "height", "Z_m"))


def known_point_rows(path: Path, layer: str | None = None, name: str = "CONTROL"):
    """The rows of a ground-point table, ids and roles checked: ``(header, (cx, cy, cz),
    [(row number, row, id, role), ...])``. ``id`` (or point_id/point/name) must be non-empty and
    unique; ``role`` (or type) is control (default) or check; X/Y/Z (or E/N/H...) columns."""
    header, rows = read_table(path, layer, name)
    c_id = column(header, "point_id", "id", "point", "name", name=name, path=path)
    cols = tuple(column(header, *aliases, name=name, path=path) for aliases in XYZ_COLUMNS)
    c_role = column(header, "role", "type", required=False)
    out, seen = [], set()
    for k, r in enumerate(rows, start=1):
        pid = r[c_id]
        if not pid:
            raise InputDataError(f"{name}: {path} row {k} has an empty {c_id}")
        if pid in seen:
            raise InputDataError(f"{name}: {path} lists point {pid!r} twice (duplicate id)")
        role = (r[c_role].lower() if c_role and r[c_role] else "control")
        if role not in ROLES:
            raise InputDataError(f"{name}: {path} row {k}: {c_role} must be control or check, "
                                 f"got {r[c_role]!r}")
        seen.add(pid)
        out.append((k, r, pid, role))
    return header, cols, out


def table_crs(path: Path, layer: str | None = None) -> Any:
    """The CRS (pyproj) of a GeoPackage table's layer, None for a CSV/TXT table or a layer
    without one."""
    if Path(path).suffix.lower() not in (".gpkg", ".sqlite"):
        return None
    import pyogrio
    from pyproj import CRS

    try:
        crs = pyogrio.read_info(path, layer=layer).get("crs")
    except Exception:  # unreadable: read_table says why
        return None
    return CRS.from_user_input(crs) if crs else None


def control_crs(path: Path, crs: Any = None, layer: str | None = None,
                name: str = "CONTROL", horizontal: bool = False) -> Any:
    """The CRS of a table of ground coordinates: ``crs`` (the CRS parameter) and the table's
    own (a GeoPackage layer's, a CSV/TXT's ``.prj`` beside it), whichever is known; both
    known and different: an InputDataError naming both (:func:`toolbox.io.crs.common_crs`:
    the X/Y/Z columns are read as they are, never as if in the other CRS). A ``.prj`` and
    ``crs`` are one CRS when the table's points move by at most
    :data:`toolbox.io.crs.PRJ_TOLERANCE_M` from one to the other (:func:`check_prj_crs`).
    ``horizontal``: the table's horizontal CRS only is compared (its heights are not used as a
    datum)."""
    from toolbox.io.crs import common_crs, crs_label, horizontal_part, parse_crs, shift_phrase

    own = table_crs(path, layer)
    if own is None:
        own = prj_crs(path, name)
        if own is not None and crs is not None:
            return check_prj_crs(path, crs, layer, name, horizontal)
    elif crs is not None:
        own, shift, centre = layer_crs_as(path, layer, name, own, parse_crs(crs, "CRS"))
        if shift is not None:
            raise InputDataError(f"{name} is in {crs_label(own)} but CRS is in "
                                 f"{crs_label(parse_crs(crs))}: {shift_phrase(shift, centre)}; "
                                 "reproject the inputs to one CRS first")
    if horizontal and own is not None:
        own = horizontal_part(own)
    return common_crs({name: own}, crs)


def layer_crs_as(path: Path, layer: str | None, name: str, own: Any, crs: Any
                 ) -> tuple[Any, float | None, tuple[float, float]]:
    """A GeoPackage layer's CRS ``own`` against ``crs`` at the layer's points: two horizontal
    CRSs whose definitions differ but that move the points' centroid by at most
    :data:`toolbox.io.crs.PRJ_TOLERANCE_M` (:func:`toolbox.io.crs.centroid_shift`; a layer
    written from an ESRI ``.prj`` of EPSG:6707 does not equal EPSG:6707's definition) are one:
    ``(own with crs's horizontal part and its own height datum, None, centre)``; a larger shift
    gives ``(own, shift, centre)``; equal definitions ``(own, None, (nan, nan))``."""
    import math

    from pyproj.crs import CompoundCRS

    from toolbox.io.crs import (
        PRJ_TOLERANCE_M,
        centroid_shift,
        horizontal_part,
        same_crs,
        vertical_part,
    )

    ours, theirs = horizontal_part(own), horizontal_part(crs)
    if same_crs(ours, theirs):
        return own, None, (math.nan, math.nan)
    shift, centre = centroid_shift(ours, theirs, _known_xy(path, layer, name))
    if not shift <= PRJ_TOLERANCE_M:
        return own, shift, centre
    heights = vertical_part(own)
    return (theirs if heights is None else
            CompoundCRS(f"{theirs.name} + {heights.name}", [theirs, heights])), None, centre


def prj_crs(path: Path, name: str = "CONTROL") -> Any:
    """The CRS (pyproj) of the ``.prj`` beside a CSV/TXT table
    (:func:`toolbox.io.crs.read_prj`), None without one (or for a GeoPackage: its layer has
    its own)."""
    from toolbox.io.crs import read_prj

    path = Path(path)
    prj = path.with_suffix(".prj")
    if path.suffix.lower() in (".gpkg", ".sqlite") or not prj.is_file():
        return None
    return read_prj(prj, name)


def _known_xy(path: Path, layer: str | None, name: str) -> Any:
    """``(n, 2)`` X, Y of the table's known points, NaN where empty (Z-only points)."""
    import numpy as np

    _, cols, rows = known_point_rows(path, layer, name)
    return np.array([[_or_nan(r[cols[0]]), _or_nan(r[cols[1]])] for _, r, _, _ in rows]
                    ).reshape(-1, 2)


def _or_nan(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def check_prj_crs(path: Path, crs: Any, layer: str | None = None, name: str = "CONTROL",
                  horizontal: bool = False) -> Any:
    """``crs`` (the CRS parameter), checked against the ``.prj`` beside the table ``path``: the
    centroid of its X, Y is transformed from the ``.prj``'s horizontal CRS to ``crs``'s
    (pyproj, :func:`toolbox.io.crs.centroid_shift`); a shift over
    :data:`toolbox.io.crs.PRJ_TOLERANCE_M` (measured on the ellipsoid, so in metres whatever
    the units) is an InputDataError naming both CRSs and the shift. Definitions are
    not compared: an ESRI ``.prj`` written for EPSG:6707 does not equal EPSG:6707 but moves
    no point. Without ``horizontal``, two different height datums stated one on each side are
    refused too (:func:`toolbox.io.crs.check_same_heights`)."""
    from toolbox.io.crs import (
        PRJ_TOLERANCE_M,
        centroid_shift,
        check_same_heights,
        crs_label,
        parse_crs,
        shift_phrase,
    )

    crs = parse_crs(crs, "CRS")
    own = prj_crs(path, name)
    prj = Path(path).with_suffix(".prj").name
    shift, centre = centroid_shift(own, crs, _known_xy(path, layer, name))
    if not shift <= PRJ_TOLERANCE_M:
        raise InputDataError(
            f"{name}: {path}'s {prj} is {crs_label(own)} but CRS is {crs_label(crs)}: "
            f"{shift_phrase(shift, centre)}; the X/Y/Z columns are read as they are, in one "
            f"CRS: give CRS as the {prj}'s, or the coordinates in CRS (and a matching {prj})")
    if not horizontal:
        check_same_heights(name, own, "CRS", crs)
    return crs


def ground_points(path: Path, layer: str | None = None, name: str = "CONTROL",
                  crs: Any = None):
    """Ground points with known coordinates: ``(ids, xyz (n, 3), roles)`` from a table with
    ``id`` (or point_id/name), ``X``/``Y``/``Z`` (or E/N/H, x/y/z) and an optional ``role``
    column (``control`` or ``check``; default control). Ids must be unique. With ``crs`` (the
    project's), a GeoPackage layer in another CRS is refused: its X/Y/Z columns are read as
    they are, in the project's CRS."""
    import numpy as np

    if crs is not None:
        from toolbox.io.crs import crs_label, parse_crs, same_crs, shift_phrase

        own = table_crs(path, layer)
        if own is not None:
            crs = parse_crs(crs)
            own, shift, centre = layer_crs_as(path, layer, name, own, crs)
            if shift is not None or not same_crs(own, crs):
                moved = "" if shift is None else f" ({shift_phrase(shift, centre)})"
                raise InputDataError(f"{name}: {path} is a layer in {crs_label(own)} but the "
                                     f"project is in {crs_label(crs)}{moved}; its X/Y/Z "
                                     "columns are read as they are: give them in the "
                                     "project's CRS")
    _, cols, rows = known_point_rows(path, layer, name)
    ids = [pid for _, _, pid, _ in rows]
    roles = [role for _, _, _, role in rows]
    xyz = [[number(r[c], f"row {k} {c}", name) for c in cols] for k, r, _, _ in rows]
    return ids, np.array(xyz, dtype=float).reshape(-1, 3), roles
