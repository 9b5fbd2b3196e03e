"""OpenSfM / OpenDroneMap ``reconstruction.json`` and ``cameras.json``.

Conventions (OpenSfM's documentation, "Geometric models" and "Reconstruction file format"):

- a shot's ``rotation`` is an angle-axis vector and ``translation`` a vector such that a world
  point ``X`` (topocentric east-north-up metres around ``reference_lla``) is at
  ``x_cam = R(rotation)·X + translation`` in OpenCV camera axes (x right, y down, z forward):
  the centre is ``-Rᵀ·t`` and ``Rᵀ`` carries camera axes onto the topocentric ones;
- cameras: focal lengths and the principal point offsets ``c_x``, ``c_y`` normalised by
  ``max(width, height)`` (Orthority's ``focal_len``/``cx``/``cy`` without ``sensor_size``);
  ``perspective``, ``simple_radial``, ``radial`` and ``brown`` are Brown-Conrady models,
  ``fisheye`` and ``fisheye_opencv`` the OpenCV fisheye model;
- ``reference_lla`` (or a ``reference_lla.json`` beside the file): latitude, longitude (degrees),
  altitude (metres) of the topocentric origin on WGS84.

Two frames are found in the wild, and told apart from the file itself (``frame="auto"``):

- ``topocentric`` (OpenSfM's own output): shot poses in the east-north-up frame at
  ``reference_lla``; positions and rotations go to the target CRS exactly
  (:mod:`toolbox.exchange.geodesy`), with the meridian convergence;
- ``utm_offset`` (OpenDroneMap's ``reconstruction.json``, rewritten by ``opensfm export_geocoords``
  after the alignment; the original stays as ``reconstruction.topocentric.json``): shot poses in
  the UTM zone of ``reference_lla`` minus the UTM coordinates of that point (ODM's whole-metre
  offset), with grid axes.

``auto`` compares the shot centres with the shots' ``gps_position`` (always topocentric): the
frame whose reading of the GPS positions lies closer to the centres wins when it is at least
twice as close; else a ``reconstruction.topocentric.json`` beside the file says ``utm_offset``;
else OpenSfM's documented ``topocentric``. The choice and its evidence go to the notes.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.exchange import geodesy
from toolbox.exchange.model import OrientationSet, PhotoOrientation, check_camera, opk_from_opencv

BROWN = ("perspective", "simple_radial", "radial", "brown")
FISHEYE = ("fisheye", "fisheye_opencv")


def _load_json(path: Path) -> Any:
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputDataError(f"cannot read {path}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputDataError(f"{path} is not valid JSON: {exc.msg} (line {exc.lineno})") from None


def camera_name(camera_id: str) -> str:
    """OpenSfM camera ids carry a ``v2 `` version prefix; the name drops it."""
    return camera_id[3:] if camera_id.startswith("v2 ") else camera_id


def camera_spec(params: Any, name: str, where: str) -> dict[str, Any]:
    """An Orthority interior-parameter dict from one OpenSfM camera entry."""
    if not isinstance(params, dict):
        raise InputDataError(f"{where}: camera {name!r} must be a mapping")
    kind = str(params.get("projection_type", "")).lower()
    if kind not in BROWN + FISHEYE:
        raise InputDataError(f"{where}: camera {name!r} has projection_type {kind or None!r}, "
                             f"which cannot be converted; supported: {', '.join(BROWN + FISHEYE)}")
    try:
        spec: dict[str, Any] = {"type": "brown" if kind in BROWN else "fisheye",
                                "im_size": [int(params["width"]), int(params["height"])]}
        if "focal" in params:
            spec["focal_len"] = float(params["focal"])
        else:
            fx, fy = float(params["focal_x"]), float(params["focal_y"])
            spec["focal_len"] = fx if fx == fy else [fx, fy]
        spec["cx"], spec["cy"] = float(params.get("c_x", 0.0)), float(params.get("c_y", 0.0))
        keys = ("k1", "k2", "p1", "p2", "k3") if kind in BROWN else ("k1", "k2", "k3", "k4")
        for key in keys:
            if key in params:
                spec[key] = float(params[key])
    except KeyError as exc:
        raise InputDataError(f"{where}: camera {name!r} lacks {exc.args[0]!r}") from None
    except (TypeError, ValueError):
        raise InputDataError(f"{where}: camera {name!r} has a non-numeric parameter") from None
    return check_camera(spec, name, where)


def read_cameras_json(path: str | Path) -> OrientationSet:
    """Cameras only, from OpenSfM/ODM ``cameras.json`` (``{camera id: parameters}``)."""
    path = Path(path)
    doc = _load_json(path)
    if not isinstance(doc, dict) or not doc:
        raise InputDataError(f"{path}: expected a JSON object of cameras")
    out = OrientationSet(source=str(path), format="opensfm_cameras")
    for cid, params in doc.items():
        out.cameras[camera_name(cid)] = camera_spec(params, camera_name(cid), str(path))
    return out


def _reference(doc: dict[str, Any], path: Path) -> tuple[float, float, float] | None:
    ref = doc.get("reference_lla")
    if ref is None and (path.parent / "reference_lla.json").exists():
        ref = _load_json(path.parent / "reference_lla.json")
    if ref is None:
        return None
    try:
        return float(ref["latitude"]), float(ref["longitude"]), float(ref["altitude"])
    except (KeyError, TypeError, ValueError):
        raise InputDataError(f"{path}: reference_lla must hold latitude, longitude and altitude, "
                             f"got {ref!r}") from None


FRAMES = ("auto", "topocentric", "utm_offset")


def _frame_function(frame: str, lat: float, lon: float, alt: float, crs) -> Any:
    """``f(reconstruction xyz) -> target grid xyz`` for one frame reading."""
    if frame == "topocentric":
        return geodesy.topocentric_function(lat, lon, alt, crs)
    from pyproj import Transformer

    utm = geodesy.utm_crs(lon, lat)
    (ox, oy, _), = geodesy.geographic_to_grid(lon, lat, alt, utm)
    from toolbox.io.crs import one_crs

    # another definition of the UTM zone (an ESRI WKT of it) moves no point: not transformed
    to_target = None if one_crs(utm, crs, (ox, oy, ox, oy)) else \
        Transformer.from_crs(utm, crs, always_xy=True)

    def f(xyz):
        xyz = np.atleast_2d(np.asarray(xyz, dtype="float64")) + [ox, oy, alt]
        if to_target is None:
            return xyz
        return np.column_stack(to_target.transform(xyz[:, 0], xyz[:, 1], xyz[:, 2]))

    return f


def _choose_frame(frame: str, centres: np.ndarray, gps: np.ndarray, ref, path: Path,
                  notes: list[str]) -> str:
    if frame != "auto":
        notes.append(f"frame {frame} (as given)")
        return frame
    lat, lon, alt = ref
    ok = np.isfinite(gps).all(axis=1)
    if ok.sum() >= 1:
        topo = np.median(np.linalg.norm(centres[ok] - gps[ok], axis=1))
        utm = geodesy.utm_crs(lon, lat)
        grid = geodesy.topocentric_function(lat, lon, alt, utm)(gps[ok])
        offset = _frame_function("utm_offset", lat, lon, alt, utm)(np.zeros(3))[0]
        off = np.median(np.linalg.norm(centres[ok] - (grid - offset), axis=1))
        if max(topo, off) > 2 * min(topo, off):
            chosen = "topocentric" if topo < off else "utm_offset"
            notes.append(f"frame {chosen}: shot centres lie {min(topo, off):.3g} m (median) from "
                         f"the GPS positions read that way, {max(topo, off):.3g} m the other way")
            return chosen
    if (path.parent / "reconstruction.topocentric.json").exists():
        notes.append("frame utm_offset: a reconstruction.topocentric.json lies beside the file "
                     "(OpenDroneMap)")
        return "utm_offset"
    notes.append("frame topocentric (OpenSfM's documented frame; the GPS positions do not "
                 "decide)")
    return "topocentric"


def read_reconstruction(path: str | Path, crs: Any = None, frame: str = "auto"
                        ) -> OrientationSet:
    """Cameras and shots of ``reconstruction.json`` (every reconstruction in the list), in
    ``crs`` (default: the UTM zone of ``reference_lla``); ``frame`` is ``auto``,
    ``topocentric`` or ``utm_offset`` (see the module docstring)."""
    import cv2

    path = Path(path)
    doc = _load_json(path)
    parts = doc if isinstance(doc, list) else [doc]
    if not parts or not all(isinstance(p, dict) and "shots" in p for p in parts):
        raise InputDataError(f"{path}: not an OpenSfM reconstruction (expected a list of objects "
                             "with 'cameras' and 'shots')")
    out = OrientationSet(source=str(path), format="opensfm")
    refs = {_reference(p, path) for p in parts}
    if len(refs) > 1:
        raise InputDataError(f"{path}: the reconstructions have different reference_lla values")
    ref = refs.pop()
    if ref is None and crs is None:
        raise InputDataError(f"{path} has no reference_lla (nor a reference_lla.json beside it) "
                             "and no CRS was given: its topocentric positions cannot be placed")
    if ref is None:
        out.crs = geodesy.require_projected(crs, str(path))
        out.notes.append("no reference_lla: positions and axes taken as already in the given CRS")
        function = None
    else:
        lat, lon, alt = ref
        if crs is None:
            out.crs = geodesy.utm_crs(lon, lat)
            out.notes.append(f"no CRS given: UTM zone {out.crs.name} from reference_lla")
        else:
            out.crs = geodesy.require_projected(crs, str(path))
        out.notes.append(f"reference_lla: lat {lat}, lon {lon}, h {alt} (WGS84)")
    for part in parts:
        for cid, params in (part.get("cameras") or {}).items():
            out.cameras[camera_name(cid)] = camera_spec(params, camera_name(cid), str(path))
    if frame not in FRAMES:
        raise InputDataError(f"reconstruction frame must be one of {', '.join(FRAMES)}, got "
                             f"{frame!r}")
    ids, centres, rotations, cams, gps = [], [], [], [], []
    for name, shot in (p for part in parts for p in part["shots"].items()):
        try:
            r_w2c = cv2.Rodrigues(np.asarray(shot["rotation"], dtype="float64").reshape(3, 1))[0]
            t = np.asarray(shot["translation"], dtype="float64").reshape(3)
        except (KeyError, TypeError, ValueError):
            raise InputDataError(f"{path}: shot {name!r} needs rotation and translation "
                                 "(3 numbers each)") from None
        cam = camera_name(str(shot.get("camera", "")))
        if cam not in out.cameras:
            raise InputDataError(f"{path}: shot {name!r} names camera {cam!r}, which is not in "
                                 "the cameras section")
        ids.append(str(name))
        centres.append(-r_w2c.T @ t)
        rotations.append(r_w2c.T)  # OpenCV camera axes -> topocentric
        cams.append(cam)
        gps.append(shot.get("gps_position") or [np.nan] * 3)
    if not ids:
        raise InputDataError(f"{path} holds no shots")
    centres = np.array(centres)
    if ref is not None:
        chosen = _choose_frame(frame, centres, np.array(gps, dtype="float64").reshape(-1, 3), ref,
                               path, out.notes)
        function = _frame_function(chosen, *ref, out.crs)
        out.notes.append("positions and rotations to the grid through pyproj (rotations with "
                         "the meridian convergence between the frame and the grid)")
        from toolbox.io.crs import note_transformation

        lat, lon = ref[0], ref[1]
        record = note_transformation(None, "EPSG:4326", out.crs, (lon, lat, lon, lat),
                                     what=f"{path.name}'s positions (WGS 84)")
        if record is not None:  # the datum change to the grid, e.g. WGS 84 -> Monte Mario: 4 m
            out.notes.append(f"WGS 84 -> {record['to']}: {record['operation']}, accuracy "
                             f"{record['accuracy_m']} m")
    if function is not None:
        to_grid = geodesy.frame_to_grid(function, centres)
        centres = function(centres)
    else:
        to_grid = np.repeat(np.eye(3)[None], len(ids), axis=0)
    from toolbox.photogrammetry.readers.text import photo_id

    for k, name in enumerate(ids):
        out.add_photo(PhotoOrientation(photo_id(name), cams[k], name, tuple(centres[k].tolist()),
                                       opk_from_opencv(to_grid[k] @ rotations[k], name)), str(path))
    return out
