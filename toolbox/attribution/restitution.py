"""Readers of restitution entities: what the stereo plotter delivers (thesis S002 §2.2.2, §2.2.4).

Every reader returns an *entity table*: a GeoDataFrame with one row per plotted entity and the
columns of :data:`ENTITY_COLUMNS` (``entity`` 1-based number in the file, ``code``, ``colour`` the
entity's colour index as plotted, ``source`` the provenance code, ``file`` and ``line`` where it
was read, ``kind`` what the reader saw: point, line, polygon, symbol or label; for symbols
``block``, ``rotation`` (degrees), ``scale_x``, ``scale_y``; for labels ``text``, ``text_height``,
``rotation``). Geometries keep Z. An entity with one vertex is a Point, with none a None geometry:
nothing is dropped here; :mod:`toolbox.attribution.coding` decides what is usable.

Formats
-------
*ASCII export* (one file)::

    # restitution export, model 12
    CODE FAB01002 12 1          <- CODE <code> [colour] [source]
    1688230.000 4799620.000 331.20
    1688250.000 4799620.000 331.20
    ...
    END

  ``#`` starts a comment (to the end of the line), blank lines are ignored, keywords in any case;
  ``E N Z`` separated by white space or ``;`` (a decimal comma accepted: ``331,20``), or by ``,``.

*Two tables* (§2.2.4, as delimited text, separator ``;``, tab, ``,`` or white space, optional
header line): a *descriptions* file, one record per entity::

    record; code; vertices; colour; source; xmin; ymin; xmax; ymax; first

  and a *coordinates* file, one record per vertex: ``colour; E; N; Z``; ``first`` is the 1-based
  record of the entity's first vertex in the coordinates file. A bounding box that does not hold
  the vertices is reported (``bbox_mismatches``), not refused.

*DXF* (ezdxf): the layer is the code; POINT -> point, LINE / LWPOLYLINE / POLYLINE (2D and 3D)
/ ARC / CIRCLE / ELLIPSE / SPLINE -> line (closed polylines and circles closed), INSERT -> symbol
at its insertion point (block name, rotation, scale kept), TEXT / MTEXT -> label point (text,
height, rotation). Curves (ARC, CIRCLE, ELLIPSE, SPLINE, the bulged segments of 2D polylines)
are replaced by chords at most :data:`DXF_ARC_TOLERANCE` drawing units from the curve. Entities
drawn in an object coordinate system (extrusion other than 0,0,1, as a mirrored copy is) are put
in world coordinates; a mirrored INSERT or TEXT gets the world direction of its x axis as
rotation and, for an INSERT, a negative ``scale_y``. The ACI colour is the entity's colour
(BYLAYER resolved). Other entity types are counted and named in a warning; entities on a
frozen or switched-off layer (not drawn: construction lines) are left out, counted per layer.

*Any OGR layer* with a code field (``code``/``codice``/``cod`` or given): multi-part features
and geometry collections are split into one entity per part.

Errors (:class:`InputDataError`) name the file, the line and the problem.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.io.text import is_number, read_text

ENTITY_COLUMNS = ("entity", "code", "colour", "source", "file", "line", "kind", "block",
                  "rotation", "scale_x", "scale_y", "text", "text_height")
_NUMBER_SPLIT = re.compile(r"[;,\s]+")
_FIELD_SPLIT = re.compile(r"[;\s]+")
_DECIMAL_COMMA = re.compile(r"^[+-]?(\d+,\d*|,\d+)$")
#: largest distance, in drawing units, between a DXF arc (ARC, CIRCLE, bulged polyline segment)
#: and the chords that replace it
DXF_ARC_TOLERANCE = 0.01


def _decimal_commas(fields: list[str]) -> list[str]:
    """``fields`` with a decimal comma (``300,5``, as an Italian export writes it) as a point;
    for fields split on ``;``, tab or white space only (where a comma cannot be the separator)."""
    return [f.replace(",", ".") if _DECIMAL_COMMA.match(f) else f for f in fields]


def _ascii_fields(line: str) -> list[str]:
    """The numbers of a coordinate line: split on ``;`` or white space (a comma in a number is
    then its decimal comma), else on ``,``. A comma was always a separator, so that
    ``1688230,5 4799620`` was read as E 1688230, N 5, Z 4799620."""
    fields = [f for f in _FIELD_SPLIT.split(line) if f]
    if len(fields) > 1:
        return _decimal_commas(fields)
    return [f for f in _NUMBER_SPLIT.split(line) if f]


def entity_frame(rows: list[dict[str, Any]], geoms: list[Any], crs: Any = None):
    """The entity table of ``rows`` (dicts with some of :data:`ENTITY_COLUMNS`) and geometries."""
    import geopandas as gpd
    import pandas as pd

    data = {}
    for col in ENTITY_COLUMNS:
        values = [row.get(col) for row in rows]
        if col in ("entity", "line"):
            data[col] = pd.array(values, dtype="Int64") if values else pd.array([], "Int64")
        elif col in ("rotation", "scale_x", "scale_y", "text_height"):
            data[col] = np.array([np.nan if v is None else float(v) for v in values], float)
        else:
            data[col] = pd.Series(values, dtype=object)
    return gpd.GeoDataFrame(data, geometry=gpd.GeoSeries(geoms, crs=crs), crs=crs)


def vertex_geometry(coords: np.ndarray):
    """A Point for one vertex, a LineString for more, None for none."""
    import shapely

    if len(coords) == 0:
        return None
    if len(coords) == 1:
        return shapely.Point(coords[0])
    return shapely.LineString(coords)


def _fail(path: Path, number: int, problem: str, name: str) -> InputDataError:
    return InputDataError(f"{name}: '{path}' line {number}: {problem}")


def _floats(fields: list[str]) -> list[float]:
    values = [float(f) for f in fields]
    if not all(np.isfinite(values)):
        raise ValueError(fields)
    return values


def read_ascii(path: str | Path, name: str = "INPUT", crs: Any = None):
    """Read the ASCII restitution export (``CODE`` / ``E N Z`` / ``END``)."""
    path = Path(path)
    rows: list[dict[str, Any]] = []
    geoms: list[Any] = []
    current: dict[str, Any] | None = None
    coords: list[list[float]] = []
    for number, raw in enumerate(read_text(path, name).splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        words = line.split()
        keyword = words[0].upper()
        if keyword == "CODE":
            if current is not None:
                raise _fail(path, number, f"CODE before the END of the entity started on line "
                            f"{current['line']}", name)
            if len(words) < 2:
                raise _fail(path, number, "CODE without a code", name)
            current = {"entity": len(rows) + 1, "code": words[1],
                       "colour": words[2] if len(words) > 2 else None,
                       "source": " ".join(words[3:]) or None, "file": path.name, "line": number}
            coords = []
        elif keyword == "END":
            if current is None:
                raise _fail(path, number, "END without a CODE", name)
            current["kind"] = "point" if len(coords) == 1 else "line"
            rows.append(current)
            geoms.append(vertex_geometry(np.array(coords, dtype=float).reshape(-1, 3)))
            current = None
        else:
            if current is None:
                raise _fail(path, number, f"coordinates outside an entity (expected CODE), got "
                            f"{line!r}", name)
            fields = _ascii_fields(line)
            try:
                if len(fields) != 3:
                    raise ValueError(fields)
                coords.append(_floats(fields))
            except ValueError:
                raise _fail(path, number, f"expected 'E N Z' (three numbers), got {line!r}",
                            name) from None
    if current is not None:
        raise InputDataError(f"{name}: '{path}': the entity started on line {current['line']} "
                             "(CODE " + str(current["code"]) + ") has no END")
    return entity_frame(rows, geoms, crs)


def _table_rows(path: Path, name: str, width: int, what: str
                ) -> Iterator[tuple[int, list[str]]]:
    """(line number, fields) of each record of a delimited table, one at a time (a header line
    skipped; a record of another width is an error)."""
    header = True
    for number, raw in enumerate(read_text(path, name).splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        sep = ";" if ";" in line else "\t" if "\t" in line else "," if "," in line else None
        fields = [f.strip() for f in (line.split(sep) if sep else line.split())]
        if sep != ",":
            fields = _decimal_commas(fields)
        if header and not is_number(fields[-1]):
            continue  # header line
        header = False
        if len(fields) != width:
            raise _fail(path, number, f"expected {width} fields ({what}), got {len(fields)}",
                        name)
        yield number, fields


def _coordinates(path: Path, name: str, chunk: int = 1 << 16) -> np.ndarray:
    """E N Z of every record of the coordinates table, (N, 3): parsed as read, ``chunk`` records
    at a time (the records' fields are not all kept as strings first)."""
    chunks, buf, k = [], np.empty((chunk, 3)), 0
    for number, fields in _table_rows(path, name, 4, "colour; E; N; Z"):
        try:
            buf[k] = _floats(fields[1:])
        except ValueError:
            raise _fail(path, number, f"E N Z must be numbers, got {fields[1:]}", name) from None
        k += 1
        if k == chunk:
            chunks.append(buf)
            buf, k = np.empty((chunk, 3)), 0
    chunks.append(buf[:k])
    return np.concatenate(chunks)


DESCRIPTION_FIELDS = "record; code; vertices; colour; source; xmin; ymin; xmax; ymax; first"


def read_two_tables(descriptions: str | Path, coordinates: str | Path, name: str = "INPUT",
                    coordinates_name: str = "COORDINATES", crs: Any = None,
                    tolerance: float = 1e-6):
    """Read the two-table form (descriptions + coordinates files). Returns (entities, report)."""
    descriptions, coordinates = Path(descriptions), Path(coordinates)
    xyz = _coordinates(coordinates, coordinates_name)
    rows, geoms, mismatches = [], [], []
    for number, fields in _table_rows(descriptions, name, 10, DESCRIPTION_FIELDS):
        try:
            record, count, first = int(fields[0]), int(fields[2]), int(fields[9])
            bbox = _floats(fields[5:9])
        except ValueError:
            raise _fail(descriptions, number, "record, vertices and first must be whole numbers "
                        "and the bounding box four numbers", name) from None
        if not -2 ** 63 <= record < 2 ** 63:
            raise _fail(descriptions, number, f"record {fields[0]} is too large for a record "
                        "number (at most 19 digits)", name)
        if count < 0 or first < 1 or first + count - 1 > len(xyz):
            raise _fail(descriptions, number, f"vertices {first}..{first + count - 1} are not in "
                        f"'{coordinates.name}' ({len(xyz)} records)", name)
        pts = xyz[first - 1:first - 1 + count]
        if count and (pts[:, 0].min() < bbox[0] - tolerance or pts[:, 1].min() < bbox[1] -
                      tolerance or pts[:, 0].max() > bbox[2] + tolerance or
                      pts[:, 1].max() > bbox[3] + tolerance):
            mismatches.append(record)
        rows.append({"entity": record, "code": fields[1], "colour": fields[3] or None,
                     "source": fields[4] or None, "file": descriptions.name, "line": number,
                     "kind": "point" if count == 1 else "line"})
        geoms.append(vertex_geometry(pts))
    return entity_frame(rows, geoms, crs), {"bbox_mismatches": mismatches}


def read_dxf(path: str | Path, name: str = "INPUT", crs: Any = None):
    """Read a DXF drawing (layers as codes). Returns (entities, report)."""
    import ezdxf
    import shapely
    from ezdxf import colors as dxf_colors

    path = Path(path)
    try:
        doc = ezdxf.readfile(str(path))
        layer_colour = {layer.dxf.name: abs(layer.color) for layer in doc.layers}
        # a frozen or switched-off layer is not drawn (a restitution's construction lines)
        hidden_state = {layer.dxf.name: "frozen" if layer.is_frozen() else "off"
                        for layer in doc.layers if layer.is_frozen() or layer.is_off()}
        entities = list(doc.modelspace())
    except (ezdxf.DXFError, *DXF_DAMAGE) as exc:  # malformed group codes, values, structure
        raise InputDataError(f"{name}: cannot read '{path}' as DXF: {_why(exc)}") from None
    rows: list[dict[str, Any]] = []
    geoms: list[Any] = []
    skipped: dict[str, int] = {}
    hidden: dict[str, list] = {}  # layer -> [entities left out, "frozen" or "off"]

    def add(entity, kind: str, geom, **extra) -> None:
        colour = entity.dxf.get("color", dxf_colors.BYLAYER)
        if colour in (dxf_colors.BYLAYER, dxf_colors.BYBLOCK):
            colour = layer_colour.get(entity.dxf.layer)
        rows.append({"entity": len(rows) + 1, "code": entity.dxf.layer,
                     "colour": None if colour is None else str(colour), "source": "dxf",
                     "file": path.name, "line": None, "kind": kind, **extra})
        geoms.append(geom)

    for number, entity in enumerate(entities, start=1):
        try:
            layer = entity.dxf.get("layer", "0")
            if layer in hidden_state:
                hidden.setdefault(layer, [0, hidden_state[layer]])[0] += 1
                continue
            _add_dxf_entity(entity, add, skipped)
        except (ezdxf.DXFError, *DXF_DAMAGE) as exc:
            raise InputDataError(f"{name}: '{path}': DXF entity {number} "
                                 f"({_entity_label(entity)}) is malformed: {_why(exc)}") from None
        if geoms and geoms[-1] is not None and not np.isfinite(
                shapely.get_coordinates(geoms[-1], include_z=True)).all():
            raise InputDataError(f"{name}: '{path}': DXF entity {number} "
                                 f"({_entity_label(entity)}) has a coordinate that is not a "
                                 "finite number (inf or nan)")
    return entity_frame(rows, geoms, crs), {"skipped_dxf_entities": skipped,
                                            "hidden_dxf_layers": hidden}


# what ezdxf raises on damaged files besides its own errors (a value of the wrong type where a
# number or a handle is expected, a file ending after a group code...)
DXF_DAMAGE = (OSError, ValueError, TypeError, KeyError, IndexError, AttributeError,
              StopIteration, OverflowError, LookupError, ArithmeticError)


def _why(exc: BaseException) -> str:
    text = " ".join(str(exc).split())[:160]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__ + " (damaged file)"


def _entity_label(entity) -> str:
    try:
        return f"{entity.dxftype()} handle {entity.dxf.handle}, layer {entity.dxf.layer!r}"
    except Exception:  # noqa: BLE001 - a label for a message, from a damaged entity
        return "unreadable"


def _arc_steps(radius: float, sweep: float, tolerance: float = DXF_ARC_TOLERANCE) -> int:
    """Chords replacing an arc of ``radius`` and ``sweep`` (radians) within ``tolerance`` of it
    (sagitta ``r (1 - cos(a / 2))`` of each chord's angle ``a``), at least one per 45 degrees."""
    import math

    sweep = abs(sweep)
    steps = math.ceil(sweep / (math.pi / 4))
    if radius > tolerance:
        steps = max(steps, math.ceil(sweep / (2.0 * math.acos(1.0 - tolerance / radius))))
    return max(1, min(steps, 100_000))


def _arc_points(center, radius: float, start: float, sweep: float) -> np.ndarray:
    """The vertices (x, y) of an arc from angle ``start`` turning by ``sweep`` (radians,
    counter-clockwise when positive), both ends included."""
    angles = start + np.linspace(0.0, sweep, _arc_steps(radius, sweep) + 1)
    return np.column_stack([center[0] + radius * np.cos(angles),
                            center[1] + radius * np.sin(angles)])


def _bulged_vertices(points: list[tuple[float, float, float, float]],
                     closed: bool) -> np.ndarray:
    """The (x, y, z) vertices of a 2D polyline given as ``(x, y, z, bulge)`` (OCS), each bulged
    segment replaced by its arc's chords (bulge = tan(included angle / 4), positive
    counter-clockwise; z varies linearly along the arc); a closed polyline ends on its first
    vertex (once: a last vertex already on the first is not repeated)."""
    import math

    if not points:
        return np.zeros((0, 3))
    xyz = np.array([p[:3] for p in points], float)
    out = [xyz[:1]]
    count = len(points) if closed else len(points) - 1
    for i in range(count):
        p0, p1, bulge = xyz[i], xyz[(i + 1) % len(points)], float(points[i][3] or 0.0)
        chord = float(np.hypot(*(p1[:2] - p0[:2])))
        if i == len(points) - 1 and chord == 0.0:  # closing segment of a closed-on-itself line
            break
        if bulge == 0.0 or chord == 0.0:
            out.append(p1[None])
            continue
        sweep = 4.0 * math.atan(bulge)
        radius = chord / (2.0 * abs(math.sin(sweep / 2.0)))
        offset = chord * (1.0 - bulge * bulge) / (4.0 * bulge)  # midpoint -> centre, leftwards
        left = np.array([p0[1] - p1[1], p1[0] - p0[0]]) / chord
        center = (p0[:2] + p1[:2]) / 2.0 + offset * left
        start = math.atan2(p0[1] - center[1], p0[0] - center[0])
        arc = _arc_points(center, radius, start, sweep)
        z = np.linspace(p0[2], p1[2], len(arc))
        arc = np.column_stack([arc, z])
        arc[-1] = p1  # the next vertex exactly
        out.append(arc[1:])
    return np.concatenate(out)


def _to_wcs(entity, xyz: np.ndarray) -> np.ndarray:
    """(n, 3) world coordinates of the OCS vertices ``xyz`` of a 2D entity."""
    ocs = entity.ocs()
    if not ocs.transform:
        return xyz
    return np.array([tuple(v) for v in ocs.points_to_wcs(xyz.tolist())], float).reshape(-1, 3)


def _wcs_direction(entity, rotation: float) -> tuple[float, float]:
    """``(rotation, handedness)`` in world coordinates of an OCS entity turned by ``rotation``
    degrees: the world direction of its x axis (degrees) and -1 when its OCS is mirrored."""
    import math

    ocs = entity.ocs()
    if not ocs.transform:
        return rotation, 1.0
    a = math.radians(rotation)
    ux = ocs.to_wcs((math.cos(a), math.sin(a), 0.0))
    uy = ocs.to_wcs((-math.sin(a), math.cos(a), 0.0))
    hand = 1.0 if ux.x * uy.y - ux.y * uy.x >= 0 else -1.0
    return math.degrees(math.atan2(ux.y, ux.x)) % 360.0, hand


def _add_dxf_entity(entity, add, skipped: dict[str, int]) -> None:
    import math

    import shapely

    kind = entity.dxftype()
    if kind == "POINT":
        add(entity, "point", shapely.Point(tuple(entity.dxf.location)))
    elif kind == "LINE":
        add(entity, "line", shapely.LineString([tuple(entity.dxf.start),
                                                tuple(entity.dxf.end)]))
    elif kind == "LWPOLYLINE":
        z = float(entity.dxf.get("elevation", 0.0) or 0.0)
        xyz = _bulged_vertices([(x, y, z, b) for x, y, b in entity.get_points("xyb")],
                               bool(entity.closed))
        add(entity, "line", vertex_geometry(_to_wcs(entity, xyz)))
    elif kind == "POLYLINE" and entity.is_2d_polyline:
        elevation = float(entity.dxf.get("elevation", (0.0, 0.0, 0.0))[2])
        xyz = _bulged_vertices([(x, y, elevation or z, v.dxf.get("bulge", 0.0))
                                for v in entity.vertices
                                for x, y, z in [tuple(v.dxf.location)]],
                               bool(entity.is_closed))
        add(entity, "line", vertex_geometry(_to_wcs(entity, xyz)))
    elif kind == "POLYLINE" and not (entity.is_polygon_mesh or entity.is_poly_face_mesh):
        pts = [tuple(v) for v in entity.points()]
        if entity.is_closed and pts and pts[0] != pts[-1]:
            pts.append(pts[0])
        add(entity, "line", vertex_geometry(np.array(pts, float).reshape(-1, 3)))
    elif kind in ("ARC", "CIRCLE"):
        center = tuple(entity.dxf.center)  # OCS, its z the elevation
        radius = abs(float(entity.dxf.radius))
        if kind == "CIRCLE":
            start, sweep = 0.0, 2.0 * math.pi
        else:
            start = math.radians(entity.dxf.start_angle)
            sweep = math.radians((entity.dxf.end_angle - entity.dxf.start_angle) % 360.0)
            sweep = sweep or 2.0 * math.pi  # start = end: the whole circle
        xy = _arc_points(center, radius, start, sweep)
        if sweep == 2.0 * math.pi:
            xy[-1] = xy[0]
        xyz = np.column_stack([xy, np.full(len(xy), center[2])])
        add(entity, "line", vertex_geometry(_to_wcs(entity, xyz)))
    elif kind in ("ELLIPSE", "SPLINE"):  # world coordinates, within the tolerance of the curve
        add(entity, "line", vertex_geometry(np.array(
            [tuple(v) for v in entity.flattening(DXF_ARC_TOLERANCE)], float).reshape(-1, 3)))
    elif kind == "INSERT":
        rotation, hand = _wcs_direction(entity, entity.dxf.get("rotation", 0.0))
        insert = _to_wcs(entity, np.array([tuple(entity.dxf.insert)], float))[0]
        add(entity, "symbol", shapely.Point(tuple(insert)),
            block=entity.dxf.name, rotation=rotation,
            scale_x=entity.dxf.get("xscale", 1.0), scale_y=hand * entity.dxf.get("yscale", 1.0))
    elif kind == "TEXT":
        rotation, _ = _wcs_direction(entity, entity.dxf.get("rotation", 0.0))
        insert = _to_wcs(entity, np.array([tuple(entity.dxf.insert)], float))[0]
        add(entity, "label", shapely.Point(tuple(insert)), text=entity.dxf.text,
            text_height=entity.dxf.get("height", None), rotation=rotation)
    elif kind == "MTEXT":  # insertion point in world coordinates
        add(entity, "label", shapely.Point(tuple(entity.dxf.insert)), text=entity.plain_text(),
            text_height=entity.dxf.get("char_height", None),
            rotation=entity.dxf.get("rotation", 0.0))
    else:
        skipped[kind] = skipped.get(kind, 0) + 1


CODE_FIELD_NAMES = ("code", "codice", "cod", "codes", "layer")


def read_ogr(source: Any, code_field: str | None = None, name: str = "INPUT"):
    """Read any OGR layer with a code field (multi-parts split). Returns (entities, report)."""
    import shapely

    from toolbox.io.vector import read_vector

    frame = read_vector(source, name=name)
    fields = [c for c in frame.columns if c != frame.geometry.name]
    if code_field is None:
        lower = {f.lower(): f for f in fields}
        code_field = next((lower[n] for n in CODE_FIELD_NAMES if n in lower), None)
        if code_field is None:
            raise InputDataError(f"{name}: {source} has no code field (no field named "
                                 f"{', '.join(CODE_FIELD_NAMES)}; give CODE_FIELD)")
    elif code_field not in fields:
        raise InputDataError(f"{name}: field {code_field!r} is not in {source}; fields are: "
                             f"{', '.join(fields)}")
    lower = {f.lower(): f for f in fields}
    colour_field = next((lower[n] for n in ("colour", "color", "colore") if n in lower), None)
    source_field = next((lower[n] for n in ("source", "fonte", "provenienza") if n in lower),
                        None)
    label = Path(str(getattr(source, "path", source) or "<GeoDataFrame>")).name
    rows, geoms, split = [], [], 0
    for i, (geom, code) in enumerate(zip(frame.geometry.values, frame[code_field], strict=True)):
        parts = [None] if geom is None or geom.is_empty else _single_parts(geom)
        split += len(parts) - 1
        for part in parts:
            kind = None if part is None else {0: "point", 1: "line", 2: "line",
                                              3: "polygon"}.get(shapely.get_type_id(part))
            blank = code is None or (isinstance(code, float) and np.isnan(code))
            rows.append({"entity": i + 1, "code": None if blank else str(code).strip(),
                         "colour": None if colour_field is None or frame[colour_field].iloc[i]
                         is None else str(frame[colour_field].iloc[i]),
                         "source": None if source_field is None else frame[source_field].iloc[i],
                         "file": label, "line": None, "kind": kind})
            geoms.append(part)
    return entity_frame(rows, geoms, frame.crs), {"code_field": code_field,
                                                   "multipart_split": split}


def _single_parts(geom) -> list:
    """The single geometries of ``geom``: multi-parts and geometry collections (nested ones
    too) opened, empty parts dropped."""
    import shapely

    parts = [geom]
    while any(shapely.get_type_id(g) in (4, 5, 6, 7) for g in parts):
        parts = [q for g in parts for q in (shapely.get_parts(g) if shapely.get_type_id(g) in
                                            (4, 5, 6, 7) else [g])]
    return [g for g in parts if not g.is_empty] or [None]


def looks_like_ascii_export(path: Path) -> bool:
    """True when the first non-comment line of ``path`` starts with ``CODE``."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(4096).decode("latin-1")
    except OSError:
        return False
    for line in head.splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            return line.upper().startswith("CODE")
    return False


def read_restitution(source: Any, code_field: str | None = None, name: str = "INPUT",
                     crs: Any = None):
    """Any supported restitution file: ASCII export, DXF, or an OGR layer. Returns
    (entities, report). ``crs`` is given to formats that carry none (ASCII, DXF)."""
    text = str(source)
    path = Path(text.split("|", 1)[0]) if isinstance(source, (str, Path)) else None
    if path is not None and path.suffix.lower() == ".dxf":
        return read_dxf(path, name, crs)
    if path is not None and path.suffix.lower() not in (".gpkg", ".shp", ".geojson", ".json",
                                                        ".csv", ".gml", ".fgb") \
            and looks_like_ascii_export(path):
        return read_ascii(path, name, crs), {}
    frame, report = read_ogr(source, code_field, name)
    if frame.crs is None and crs is not None:
        frame = frame.set_crs(crs)
    return frame, report
