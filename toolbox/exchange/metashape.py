"""Agisoft Metashape camera XML (File > Export > Cameras, "Agisoft XML") and its omega-phi-kappa
text export.

XML (Metashape manual, appendix C "Camera models"; the export's layout):

- ``<sensor>``: ``<resolution width height>`` and a ``<calibration>`` (the ``adjusted`` one when
  several) with ``f`` (px), ``cx, cy`` (px, offsets from the image centre, y down), ``b1, b2``
  (affinity, skew), ``k1..k4``, ``p1..p4``. Frame sensors become ``brown``/``opencv`` specs with
  ``focal_len = [f + b1, f] / max(w, h)`` and OpenCV ``p1 = P2``, ``p2 = P1`` (Metashape names the
  tangential terms the other way round); fisheye sensors become ``fisheye`` (Metashape's
  equidistant model with k1..k4 is OpenCV's). A skew ``b2``, radial ``k4`` or the tangential
  terms' radial factor ``(1 + P3·r² + P4·r⁴)`` on a frame sensor have no place in the schema:
  refused when they move a corner pixel by more than 0.01 px.
- ``<camera label transform>``: the 4x4 camera -> chunk matrix, OpenCV camera axes (x right,
  y down, z forward); cameras without a transform (not aligned) are listed without orientation.
- a camera's ``component_id`` (Metashape 1.6 and later) puts its component's ``<transform>``
  between the camera and the chunk;
- the chunk ``<transform>`` (``rotation``, ``translation``, ``scale``) maps chunk coordinates to
  geocentric WGS84 (ECEF) when the chunk ``<reference>`` is a geographic or projected CRS, or to
  the local frame for ``LOCAL_CS``. Positions and rotations then go to the grid
  (:mod:`toolbox.exchange.geodesy`).

OPK text ("Omega Phi Kappa (*.txt)"): read by :mod:`toolbox.photogrammetry.readers.text`
(degrees; the r11..r33 columns checked against the angles), in the caller's CRS.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ToolboxError
from toolbox.exchange import geodesy
from toolbox.exchange.model import OrientationSet, PhotoOrientation, check_camera, opk_from_opencv

NEGLIGIBLE_PX = 0.01


def _float(node, tag: str, default: float = 0.0) -> float:
    child = node.find(tag)
    return default if child is None or child.text is None else float(child.text)


def _sensor_spec(sensor, where: str) -> tuple[str, dict[str, Any]]:
    name = sensor.get("label") or f"sensor {sensor.get('id')}"
    calibrations = sensor.findall("calibration")
    if not calibrations:
        raise InputDataError(f"{where}: sensor {name!r} has no calibration")
    cal = next((c for c in calibrations if c.get("class") == "adjusted"), calibrations[-1])
    res = cal.find("resolution") if cal.find("resolution") is not None else \
        sensor.find("resolution")
    w, h = int(res.get("width")), int(res.get("height"))
    m = max(w, h)
    f, b1, b2 = _float(cal, "f"), _float(cal, "b1"), _float(cal, "b2")
    if f <= 0:
        raise InputDataError(f"{where}: sensor {name!r} has no focal length f")
    kind = (cal.get("type") or sensor.get("type") or "frame").lower()
    k = [_float(cal, f"k{i}") for i in (1, 2, 3, 4)]
    p1, p2 = _float(cal, "p1"), _float(cal, "p2")
    p3, p4 = _float(cal, "p3"), _float(cal, "p4")
    corner = (w / 2) ** 2 + (h / 2) ** 2
    spec: dict[str, Any] = {"im_size": [w, h], "focal_len": [(f + b1) / m, f / m]
                            if b1 else f / m, "cx": _float(cal, "cx") / m,
                            "cy": _float(cal, "cy") / m}
    if kind == "fisheye":
        if p1 or p2 or p3 or p4 or b2:
            raise InputDataError(f"{where}: fisheye sensor {name!r} has p1-p4/b2 terms, which "
                                 "the fisheye model lacks")
        spec |= {"type": "fisheye", "k1": k[0], "k2": k[1], "k3": k[2], "k4": k[3]}
    elif kind == "frame":
        skew_px = abs(b2) * np.sqrt(corner) / f
        k4_px = abs(k[3]) * (corner / f ** 2) ** 4 * np.sqrt(corner)
        # Metashape: tangential (P1(r² + 2x²) + 2P2xy)(1 + P3r² + P4r⁴), likewise y
        x, y = np.array([w / 2, h / 2]) / f  # a corner, normalised (the others by symmetry)
        r2 = x * x + y * y
        tangential = max(abs(p1) * (r2 + 2 * x * x) + 2 * abs(p2 * x * y),
                         abs(p2) * (r2 + 2 * y * y) + 2 * abs(p1 * x * y))
        p34_px = tangential * (abs(p3) * r2 + abs(p4) * r2 * r2) * f
        if max(skew_px, k4_px, p34_px) > NEGLIGIBLE_PX:
            raise InputDataError(f"{where}: sensor {name!r} has skew b2 = {b2}, k4 = {k[3]} or "
                                 f"p3 = {p3}, p4 = {p4} (up to "
                                 f"{max(skew_px, k4_px, p34_px):.3g} px at the corners), which "
                                 "the Brown/OpenCV camera schema cannot hold")
        spec |= {"type": "brown", "k1": k[0], "k2": k[1], "k3": k[2], "p1": p2, "p2": p1}
    else:
        raise InputDataError(f"{where}: sensor {name!r} has type {kind!r}; supported: frame, "
                             "fisheye")
    return name, check_camera(spec, name, where)


def _chunk_transform(chunk) -> np.ndarray | None:
    node = chunk.find("transform")
    if node is None:
        return None
    rot = node.find("rotation")
    r = np.eye(3) if rot is None else np.array([float(v) for v in rot.text.split()]).reshape(3, 3)
    t = np.zeros(3) if node.find("translation") is None else \
        np.array([float(v) for v in node.find("translation").text.split()])
    s = _float(node, "scale", 1.0)
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = s * r, t
    return matrix


def read_xml(path: str | Path, crs: Any = None) -> OrientationSet:
    """Sensors and aligned cameras of a Metashape camera XML (first chunk). A value that is
    missing or not a number where the schema has one is an :class:`InputDataError`."""
    from pyproj.exceptions import CRSError

    try:
        return _read_xml(Path(path), crs)
    except (ValueError, TypeError, AttributeError, IndexError, CRSError,
            np.linalg.LinAlgError) as exc:
        if isinstance(exc, ToolboxError):  # ParameterError, InputDataError: already one line
            raise
        text = " ".join(str(exc).split())[:160]
        raise InputDataError(f"{path}: malformed Metashape camera XML ({type(exc).__name__}: "
                             f"{text})") from None


def _read_xml(path: Path, crs: Any) -> OrientationSet:
    from pyproj import CRS

    from toolbox.photogrammetry.readers.text import photo_id

    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError, LookupError) as exc:  # LookupError: an unknown encoding
        raise InputDataError(f"cannot read {path} as XML: {exc}") from None
    chunk = root.find("chunk") if root.tag == "document" else root
    if chunk is None or chunk.find("sensors") is None:
        raise InputDataError(f"{path}: not a Metashape camera XML (no chunk with sensors)")
    out = OrientationSet(source=str(path), format="metashape")
    sensors = {}
    for sensor in chunk.find("sensors"):
        name, spec = _sensor_spec(sensor, str(path))
        sensors[sensor.get("id")] = name
        out.cameras[name] = spec
    ref_node = chunk.find("reference")
    ref_text = (ref_node.text or "").strip() if ref_node is not None else ""
    ref_crs = None if not ref_text or ref_text.startswith("LOCAL_CS") else CRS.from_wkt(ref_text)
    chunk_matrix = _chunk_transform(chunk)
    components = {c.get("id"): _chunk_transform(c)
                  for c in chunk.find("components") if c.tag == "component"} \
        if chunk.find("components") is not None else {}
    rows = []
    for cam in chunk.find("cameras") or []:
        if cam.tag != "camera":
            continue
        label = cam.get("label") or cam.get("id")
        sensor = sensors.get(cam.get("sensor_id"))
        node = cam.find("transform")
        if node is None or not (node.text or "").strip():
            out.add_photo(PhotoOrientation(photo_id(label), sensor, label), str(path))
            continue
        matrix = np.array([float(v) for v in node.text.split()]).reshape(4, 4)
        if components.get(cam.get("component_id")) is not None:  # Metashape >= 1.6
            matrix = components[cam.get("component_id")] @ matrix
        if chunk_matrix is not None:
            matrix = chunk_matrix @ matrix
        r = matrix[:3, :3]
        r = r / np.cbrt(np.linalg.det(r))
        rows.append((label, sensor, matrix[:3, 3], r))
    if ref_crs is None:
        if crs is None:
            raise InputDataError(f"{path}: the chunk has a local coordinate system: give CRS to "
                                 "read its coordinates as map coordinates")
        out.crs = geodesy.require_projected(crs, str(path))
        out.notes.append("local chunk coordinates taken as grid coordinates of the given CRS")
        function = None
    else:
        if chunk_matrix is None:
            raise InputDataError(f"{path}: the chunk has a reference CRS but no transform")
        centres = np.array([r[2] for r in rows]) if rows else np.zeros((0, 3))
        if crs is not None:
            out.crs = geodesy.require_projected(crs, str(path))
        elif ref_crs.is_projected:
            out.crs = ref_crs
        else:
            lon, lat, _ = geodesy.grid_to_geographic(centres.mean(axis=0), "EPSG:4978")[0] \
                if len(centres) else (0.0, 0.0, 0.0)
            out.crs = geodesy.utm_crs(lon, lat)
            out.notes.append(f"reference CRS {ref_crs.name} is geographic: UTM zone {out.crs.name}")
        function = geodesy.ecef_function(out.crs)
        out.notes.append("chunk transform -> geocentric WGS84 -> grid (rotations with the "
                         "meridian convergence)")
    if rows:
        centres = np.array([r[2] for r in rows])
        to_grid = geodesy.frame_to_grid(function, centres) if function is not None else \
            np.repeat(np.eye(3)[None], len(rows), axis=0)
        grid = function(centres) if function is not None else centres
        for k, (label, sensor, _, r) in enumerate(rows):
            out.add_photo(PhotoOrientation(photo_id(label), sensor, label,
                                           tuple(grid[k].tolist()),
                                           opk_from_opencv(to_grid[k] @ r, label)), str(path))
    not_aligned = [p.id for p in out.photos.values() if not p.oriented]
    if not_aligned:
        out.notes.append(f"not aligned (no transform): {', '.join(not_aligned)}")
    return out


def read_opk(path: str | Path, crs: Any = None, angle_unit: str | None = None) -> OrientationSet:
    """Metashape's omega-phi-kappa text export (degrees unless said otherwise)."""
    from toolbox.exchange.geodesy import require_projected
    from toolbox.photogrammetry.readers import read_exterior_orientations

    table = read_exterior_orientations(path, "metashape", angle_unit)
    out = OrientationSet(source=str(path), format="metashape_opk",
                         crs=None if crs is None else require_projected(crs, str(path)))
    for pid, eo in table.orientations.items():
        out.add_photo(PhotoOrientation(pid, None, None, (eo.x0, eo.y0, eo.z0),
                                       (eo.omega, eo.phi, eo.kappa)))
    out.notes += table.notes + ([] if crs is not None else ["no CRS (the export states none)"])
    return out
