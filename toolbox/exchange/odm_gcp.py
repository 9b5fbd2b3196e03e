"""OpenDroneMap ``gcp_list.txt``: ground control points and their image measurements.

Layout (ODM documentation, "Ground Control Points"): the first line is the CRS of the ground
coordinates (a PROJ string, ``EPSG:<code>`` or ``WGS84 UTM <zone><N|S>``); every other line
``geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extras...]``, separated by tabs or spaces.
With a geographic CRS, ``geo_x`` is the longitude. ``im_x, im_y`` are pixels as OpenSfM reads them
(``normalized = (pixel + 0.5 - size/2) / max(w, h)``: the top-left pixel's centre is (0, 0)), so the
product's ``col_px = im_x + 0.5``, ``row_px = im_y + 0.5`` (its top-left centre is (0.5, 0.5)).
Points without a name are named ``gcp<n>`` by their distinct ground coordinates.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError


@dataclass
class ControlSet:
    """Ground points (id -> X, Y, Z in ``crs``) and image measurements (point, photo, col, row
    in the product's pixel convention)."""

    crs: Any
    points: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    measurements: list[tuple[str, str, float, float]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  # for the caller to push


def _crs_line(text: str):
    from pyproj import CRS

    text = text.strip()
    m = re.fullmatch(r"WGS84 UTM (\d{1,2})([NS])", text, re.I)
    if m:
        return CRS.from_epsg((32600 if m.group(2).upper() == "N" else 32700) + int(m.group(1)))
    return CRS.from_user_input(text)


CRS_LINE = re.compile(r"^(\+proj=|epsg:\d|wgs84 utm \d|(projcs|geogcs|projcrs|geogcrs|compd_cs)\[)",
                      re.I)


def looks_like(lines: list[str]) -> bool:
    """A CRS line (PROJ, EPSG, ODM's UTM label or WKT) then ``x y z px py image`` rows."""
    if len(lines) < 2 or not CRS_LINE.match(lines[0]):
        return False
    parts = lines[1].split()
    try:
        [float(p) for p in parts[:5]]
    except ValueError:
        return False
    return len(parts) >= 6


#: a control point's position must hold to this (metres): a datum transformation coarser than
#: it is warned about (a 4 m Helmert moves a block adjusted on the points by 4 m)
CONTROL_TOLERANCE_M = 0.1


def read_gcp_list(path: str | Path, crs: Any = None) -> ControlSet:
    """Read ``gcp_list.txt``; ground coordinates go to ``crs`` when given (else the file's CRS,
    or the UTM zone of the points when the file's CRS is geographic)."""
    from pyproj import Transformer

    from toolbox.exchange import geodesy
    from toolbox.io.text import read_text
    from toolbox.photogrammetry.readers.text import photo_id

    path = Path(path)
    lines = [(k, ln.strip()) for k, ln in enumerate(read_text(path).splitlines(), start=1)
             if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 2:
        raise InputDataError(f"{path}: a gcp_list needs a CRS line and at least one point line")
    try:
        source_crs = _crs_line(lines[0][1])
    except Exception:
        raise InputDataError(f"{path}, line {lines[0][0]}: the first line must be a CRS (PROJ "
                             f"string, EPSG:code or 'WGS84 UTM 32N'), got {lines[0][1]!r}") from None
    rows = []
    for lineno, line in lines[1:]:
        parts = line.split("\t") if "\t" in line else line.split()
        parts = [p.strip() for p in parts if p.strip()]
        try:
            values = [float(p) for p in parts[:5]]
        except ValueError:
            values = []
        if len(values) != 5 or len(parts) < 6:
            raise InputDataError(f"{path}, line {lineno}: expected geo_x geo_y geo_z im_x im_y "
                                 f"image_name [gcp_name], got {line[:80]!r}")
        rows.append((values, photo_id(parts[5]), parts[6] if len(parts) > 6 else None))
    geo = np.array([r[0][:3] for r in rows])
    target = geodesy.require_projected(crs, str(path)) if crs is not None else \
        source_crs if source_crs.is_projected else \
        geodesy.utm_crs(float(geo[:, 0].mean()), float(geo[:, 1].mean()))
    out = ControlSet(target)
    from toolbox.io.crs import one_crs

    # two definitions of one CRS (an ESRI WKT and its EPSG code) move no point: not transformed
    if not one_crs(source_crs, target, (*geo[:, :2].min(axis=0), *geo[:, :2].max(axis=0))):
        from toolbox.io.crs import transformation_check

        record, warning = transformation_check(
            source_crs, target, (*geo[:, :2].min(axis=0), *geo[:, :2].max(axis=0)),
            CONTROL_TOLERANCE_M, f"{path.name}'s ground coordinates", "a control point's "
            "tolerance")
        if warning is not None:
            out.warnings.append(warning)
        if record is not None:
            out.notes.append(f"transformation: {record['operation']}, accuracy "
                             f"{record['accuracy_m']} m")
        x, y, z = Transformer.from_crs(source_crs, target, always_xy=True).transform(
            geo[:, 0], geo[:, 1], geo[:, 2])
        geo = np.column_stack([x, y, z])
        out.notes.append(f"ground coordinates {source_crs.name} -> {target.name}")
    names: dict[tuple[float, ...], str] = {}
    for (values, photo, name), xyz in zip(rows, geo, strict=True):
        if name is None:
            name = names.setdefault(tuple(values[:3]), f"gcp{len(names) + 1}")
        xyz = tuple(float(v) for v in xyz)
        if name in out.points and np.abs(np.subtract(out.points[name], xyz)).max() > 1e-6:
            raise InputDataError(f"{path}: point {name!r} has two different ground coordinates")
        out.points[name] = xyz
        out.measurements.append((name, photo, values[3] + 0.5, values[4] + 0.5))
    out.notes.append("pixels: ODM im_x, im_y + 0.5 (top-left pixel centre (0.5, 0.5))")
    return out


def write_control(control: ControlSet, measurements: Path, points: Path) -> list[Path]:
    """The image-measurement CSV (``point_id, photo, col_px, row_px``) and the ground points
    CSV (``id, X, Y, Z``, read by orientation:resection's CONTROL)."""
    from toolbox.photogrammetry.tables import write_csv

    write_csv(measurements, ["point_id", "photo", "col_px", "row_px"],
              [(p, ph, f"{c:.3f}", f"{r:.3f}") for p, ph, c, r in control.measurements])
    write_csv(points, ["id", "X", "Y", "Z"],
              [(k, *(f"{v:.4f}" for v in xyz)) for k, xyz in control.points.items()])
    return [measurements, points]
