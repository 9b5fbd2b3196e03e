"""The in-memory orientation set that every exchange format reads into and writes from.

Conventions (declared once, for every format)
---------------------------------------------
- Positions ``X0, Y0, Z0``: the projection centre in ``OrientationSet.crs`` (a projected CRS;
  Z a height in metres, as the source gives it).
- Angles ``omega, phi, kappa``: **radians** in memory, the product's photogrammetric convention
  (:mod:`toolbox.photogrammetry.rotation`): ``R = Rx(omega)·Ry(phi)·Rz(kappa)`` maps camera
  axes (x right, y up, z backward: the camera looks down -z) onto the map grid axes (X east,
  Y north, Z up). Readers convert every other convention (OpenCV/OpenSfM angle-axis, roll-pitch-
  yaw, Metashape matrices) into this one; writers convert out of it.
- Cameras: Orthority interior-parameter dicts (``type``, ``im_size``, ``focal_len``, ``sensor_size``,
  ``cx``, ``cy``, distortion coefficients; ``cx``/``cy`` are principal point offsets normalised by
  ``max(w, h)``, x right, y down), keyed by camera name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

CAMERA_TYPES = ("pinhole", "brown", "opencv", "fisheye", "frame")
#: distortion coefficients allowed per camera type (as Orthority's schema)
COEFFICIENTS = {
    "pinhole": (),
    "brown": ("k1", "k2", "p1", "p2", "k3"),
    "opencv": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx",
               "ty"),
    "fisheye": ("k1", "k2", "k3", "k4"),
    "frame": (),
}
#: camera axes: OpenCV/OpenSfM/Metashape (x right, y down, z forward) -> photogrammetric (x right,
#: y up, z backward) is a half turn about x: ``R_photogrammetric = R_opencv @ FLIP``
FLIP = np.diag([1.0, -1.0, -1.0])


@dataclass
class PhotoOrientation:
    """One photo: id (the image file stem), camera name, image file name, exterior orientation
    (None when the source gives none), angles in radians (see the module docstring)."""

    id: str
    camera: str | None = None
    image: str | None = None
    xyz: tuple[float, float, float] | None = None
    opk: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        for name in ("xyz", "opk"):
            value = getattr(self, name)
            if value is None:
                continue
            try:
                value = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                value = ()
            if len(value) != 3 or not np.isfinite(value).all():
                raise InputDataError(f"photo {self.id!r}: {name} must be 3 finite numbers, got "
                                     f"{getattr(self, name)!r}")
            setattr(self, name, value)

    @property
    def oriented(self) -> bool:
        return self.xyz is not None and self.opk is not None

    @property
    def rotation(self) -> np.ndarray:
        """``R(omega, phi, kappa)``: camera (x right, y up, z back) -> grid axes."""
        if self.opk is None:
            raise InputDataError(f"photo {self.id!r} has no orientation")
        return rotation_matrix(*self.opk)


@dataclass
class OrientationSet:
    """Cameras and photo orientations of one block, with their CRS and what the reader noted."""

    cameras: dict[str, dict[str, Any]] = field(default_factory=dict)
    photos: dict[str, PhotoOrientation] = field(default_factory=dict)
    crs: Any = None
    source: str = ""
    format: str = ""
    notes: list[str] = field(default_factory=list)

    def add_photo(self, photo: PhotoOrientation, where: str = "") -> None:
        if photo.id in self.photos:
            raise InputDataError(f"{where or self.source}: photo {photo.id!r} appears twice")
        self.photos[photo.id] = photo

    def positions_xy(self) -> np.ndarray:
        """``(n, 2)`` X, Y of the photos that have a position, in :attr:`crs`."""
        return np.array([p.xyz[:2] for p in self.photos.values() if p.xyz is not None],
                        dtype="float64").reshape(-1, 2)

    def summary(self) -> dict[str, Any]:
        """What was understood: counts, CRS, conventions and the reader's notes."""
        from toolbox.io.crs import crs_label

        return {"format": self.format, "source": self.source,
                "cameras": {k: v.get("type") for k, v in self.cameras.items()},
                "photos": len(self.photos),
                "oriented": sum(p.oriented for p in self.photos.values()),
                "crs": None if self.crs is None else crs_label(self.crs),
                "convention": "omega-phi-kappa, R = Rx·Ry·Rz, camera x right, y up, z back",
                "notes": list(self.notes)}


def opk_from_matrix(matrix: np.ndarray, photo: str = "") -> tuple[float, float, float]:
    """``(omega, phi, kappa)`` radians of a camera(photogrammetric) -> grid rotation matrix."""
    try:
        return tuple(float(a) for a in angles_from_matrix(matrix, 1e-5))
    except InputDataError as exc:
        raise InputDataError(f"photo {photo!r}: {exc}") from None


def opk_from_opencv(camera_to_world: np.ndarray, photo: str = "") -> tuple[float, float, float]:
    """Angles from an OpenCV-axes camera -> world rotation (x right, y down, z forward)."""
    return opk_from_matrix(np.asarray(camera_to_world) @ FLIP, photo)


def opencv_from_opk(opk: tuple[float, float, float]) -> np.ndarray:
    """The OpenCV-axes camera -> world rotation of ``opk`` (radians)."""
    return rotation_matrix(*opk) @ FLIP


def check_camera(spec: Any, name: str, where: str) -> dict[str, Any]:
    """Validate an Orthority interior-parameter dict (types, sizes, known keys); a copy."""
    if not isinstance(spec, dict):
        raise InputDataError(f"{where}: camera {name!r} must be a mapping, got {spec!r}")
    spec = dict(spec)
    kind = str(spec.get("type", "")).lower()
    if kind not in CAMERA_TYPES:
        raise InputDataError(f"{where}: camera {name!r} has type {spec.get('type')!r}; expected "
                             f"one of {', '.join(CAMERA_TYPES)}")
    spec["type"] = kind
    known = {"type", "im_size", "focal_len", "sensor_size", "cx", "cy", *COEFFICIENTS[kind]}
    if kind == "frame":
        known |= {"principal_distance_mm", "pixel_size_mm", "fiducials_mm", "distortion"}
    unknown = sorted(set(spec) - known)
    if unknown:
        raise InputDataError(f"{where}: camera {name!r} ({kind}) has unknown parameter(s) "
                             f"{', '.join(unknown)}; allowed: {', '.join(sorted(known))}")
    try:
        w, h = (int(v) for v in spec["im_size"])
        focal = spec["focal_len"]
        focal = [float(v) for v in focal] if isinstance(focal, (list, tuple)) else float(focal)
        if "sensor_size" in spec and spec["sensor_size"] is not None:
            spec["sensor_size"] = [float(v) for v in spec["sensor_size"]]
        for key in ("cx", "cy", *COEFFICIENTS[kind]):
            if key in spec:
                spec[key] = float(spec[key])
    except KeyError as exc:
        raise InputDataError(f"{where}: camera {name!r} lacks {exc.args[0]!r}") from None
    except (TypeError, ValueError):
        raise InputDataError(f"{where}: camera {name!r} has a malformed im_size, focal_len, "
                             "sensor_size or coefficient (expected numbers)") from None
    if w <= 0 or h <= 0 or np.any(np.asarray(focal) <= 0):
        raise InputDataError(f"{where}: camera {name!r}: im_size and focal_len must be > 0")
    spec["im_size"], spec["focal_len"] = [w, h], focal
    return spec


def focal_px(spec: dict[str, Any]) -> tuple[float, float]:
    """``(fx, fy)`` in pixels of a camera spec (focal_len in the sensor's unit when sensor_size is
    given, else normalised by ``max(w, h)``)."""
    w, h = spec["im_size"]
    f = spec["focal_len"]
    fx, fy = (f, f) if not isinstance(f, (list, tuple)) else f
    if spec.get("sensor_size"):
        sw, sh = spec["sensor_size"]
        return fx * w / sw, fy * h / sh
    return fx * max(w, h), fy * max(w, h)


def dump_yaml(document: Any) -> str:
    """YAML text with short lists of numbers in flow style (``im_size: [4000, 3000]``)."""
    import yaml

    class Dumper(yaml.SafeDumper):
        pass

    def represent_list(dumper, data):
        flow = len(data) <= 16 and all(isinstance(v, (int, float)) for v in data)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)

    Dumper.add_representer(list, represent_list)
    return yaml.dump(document, Dumper=Dumper, sort_keys=False, allow_unicode=True)
