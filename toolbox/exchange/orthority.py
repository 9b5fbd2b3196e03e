"""Orthority's native files: interior parameters (YAML) and exterior parameters (GeoJSON).

- Interior YAML: ``{camera id: {type, im_size, focal_len, sensor_size?, cx?, cy?, k1...}}``
  (the schema of :mod:`toolbox.exchange.model`). A legacy ``simple-ortho`` config (a ``camera:``
  section with a ``name``) is read too.
- Exterior GeoJSON: a FeatureCollection with a ``world_crs`` member (WKT, PROJ or EPSG string);
  one Point feature per image with properties ``filename``, ``camera``, ``xyz`` (world CRS) and
  ``opk`` (**radians**, the PATB omega-phi-kappa convention, which is the product's); the
  geometry is the position in WGS84 longitude, latitude, height (informative, not read back).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError
from toolbox.exchange.model import OrientationSet, PhotoOrientation, check_camera, dump_yaml


def read_interior(path: str | Path) -> OrientationSet:
    """Cameras of an Orthority interior-parameter YAML (or legacy simple-ortho config)."""
    import yaml

    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InputDataError(f"cannot read {path} as YAML: {str(exc).splitlines()[0]}") from None
    if isinstance(doc, dict) and isinstance(doc.get("camera"), dict) and "name" in doc["camera"]:
        legacy = dict(doc["camera"])
        doc = {str(legacy.pop("name")): legacy}
    if not isinstance(doc, dict) or not doc or \
            not all(isinstance(v, dict) for v in doc.values()):
        raise InputDataError(f"{path}: expected a mapping of camera ids to interior parameters")
    out = OrientationSet(source=str(path), format="orthority_interior")
    for name, spec in doc.items():
        out.cameras[str(name)] = check_camera(spec, str(name), str(path))
    return out


def write_interior(oset: OrientationSet, path: str | Path) -> Path:
    if not oset.cameras:
        raise InputDataError("no camera to write: the input gives no interior parameters "
                             "(add a camera file, e.g. cameras.json or an Orthority YAML)")
    path = Path(path)
    path.write_text(dump_yaml({k: dict(v) for k, v in oset.cameras.items()}), encoding="utf-8")
    return path


def read_exterior(path: str | Path, crs: Any = None) -> OrientationSet:
    """Exterior orientations of an Orthority GeoJSON (``opk`` in radians)."""
    from toolbox.exchange.geodesy import require_projected

    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputDataError(f"cannot read {path} as JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        raise InputDataError(f"{path}: expected a GeoJSON FeatureCollection")
    if "world_crs" not in doc and crs is None:
        raise InputDataError(f"{path} has no world_crs and no CRS was given")
    out = OrientationSet(source=str(path), format="orthority_exterior")
    out.crs = require_projected(doc.get("world_crs") or crs, str(path))
    for k, feature in enumerate(doc.get("features") or [], start=1):
        props = (feature or {}).get("properties") or {}
        try:
            name = str(props["filename"])
            xyz = tuple(float(v) for v in props["xyz"])
            opk = tuple(float(v) for v in props["opk"])
        except (KeyError, TypeError, ValueError):
            raise InputDataError(f"{path}: feature {k} needs filename, xyz and opk (3 numbers "
                                 "each)") from None
        if len(xyz) != 3 or len(opk) != 3:
            raise InputDataError(f"{path}: feature {k}: xyz and opk need 3 numbers each")
        from toolbox.photogrammetry.readers.text import photo_id

        cam = props.get("camera")
        out.add_photo(PhotoOrientation(photo_id(name), None if cam is None else str(cam), name,
                                       xyz, opk), f"{path} feature {k}")
    if not out.photos:
        raise InputDataError(f"{path} holds no features")
    if crs is not None and doc.get("world_crs"):
        _check_world_crs(path, out, require_projected(crs, "CRS"))
    out.notes.append("opk in radians (Orthority GeoJSON)")
    return out


def _check_world_crs(path: Path, out: OrientationSet, given: Any) -> None:
    """The CRS parameter ``given`` used for ``out`` when the file's ``world_crs`` is the same
    CRS at its positions (:func:`toolbox.io.crs.check_one_crs`: the centroid moves by at most
    1 mm; an ESRI WKT rarely equals its EPSG code's definition), else an error naming both."""
    from toolbox.io.crs import PRJ_TOLERANCE_M, check_one_crs, crs_label

    check_one_crs(f"{path}: world_crs", out.crs, "CRS", given, out.positions_xy(),
                  advice="give CRS as the world_crs, or none")
    out.notes.append(f"CRS as given; world_crs ({crs_label(out.crs)}) is the same at the "
                     f"positions (within {PRJ_TOLERANCE_M * 1000:g} mm)")
    out.crs = given


def write_exterior(oset: OrientationSet, path: str | Path) -> Path:
    """Orthority exterior GeoJSON (``opk`` radians; geometry in WGS84 lon/lat/height)."""
    from toolbox.exchange.geodesy import grid_to_geographic

    if oset.crs is None:
        raise InputDataError("the orientations have no CRS: give CRS to write Orthority GeoJSON")
    photos = [p for p in oset.photos.values() if p.oriented]
    if not photos:
        raise InputDataError("no photo has an exterior orientation to write")
    lla = grid_to_geographic([p.xyz for p in photos], oset.crs)
    features = [{"type": "Feature",
                 "properties": {"filename": p.id, **({"camera": p.camera} if p.camera else {}),
                                "xyz": list(p.xyz), "opk": list(p.opk)},
                 "geometry": {"type": "Point", "coordinates": lla[k].tolist()}}
                for k, p in enumerate(photos)]
    doc = {"type": "FeatureCollection", "world_crs": oset.crs.to_wkt(), "features": features}
    path = Path(path)
    path.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    return path
