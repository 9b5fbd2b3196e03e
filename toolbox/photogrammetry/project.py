"""The orientation project file: cameras, photos (image paths), interior and exterior orientations
and the CRS, in one YAML document.

Format (``version: 1``; keys in lowercase; relative paths are relative to the project file)::

    format: orientation-project        # optional marker
    version: 1
    crs: EPSG:3003                     # ground CRS of X0/Y0/Z0 and of every product (projected)
    angle_unit: rad                    # unit of omega/phi/kappa written below (rad, deg, gon)
    cameras:
      - name: wild 303.55
        principal_distance_mm: 303.55
        principal_point_mm: [0.0, 0.0]            # optional, default (0, 0)
        fiducials_mm: {"01": [-106.0, 106.0], ...} # optional: calibrated marks
        image_size_px: [16644, 16644]             # optional
        pixel_size_mm: 0.014                      # optional (scan or sensor pixel)
        frame_size_mm: [230, 230]                 # optional (image format, for footprints)
        distortion:                               # optional, one of:
          table: {r_mm: [10, 20, ...], dr_um: [0.0, 0.1, ...]}
          # polynomial: {k1: -1.2e-8, k2: 0.0, k3: 0.0, p1: 0.0, p2: 0.0}
          #   correction form on measured u = x - x0, v = y - y0 (mm), r² = u² + v²:
          #   x̄ = u - u·dr/r - [p1 (r² + 2u²) + 2 p2 u v], dr = k1 r³ + k2 r⁵ + k3 r⁷ (mm);
          #   ȳ likewise with u <-> v and p1 <-> p2; k2, k3, p1, p2 optional (0)
      - name: drone                               # or a camera model instead of the film fields
        model: {type: brown, im_size: [4000, 3000], focal_len: 0.78, cx: 0.0, cy: 0.0,
                k1: -0.26, k2: 0.10, k3: -0.03, p1: 0.0007, p2: 0.0003}
        # type: pinhole | brown | opencv | fisheye; the spec of toolbox.cameras.factory
        # (Orthority's interior schema: focal_len normalised by max(w, h) unless sensor_size
        # gives its units; cx, cy offsets normalised by max(w, h)). Such a camera's photos have
        # no 'interior' (no fiducials): pixels go through the model.
    photos:
      - id: 1_7150
        camera: wild 303.55
        image: images/1_7150.tif                  # optional; need not exist
        strip: "1"                                # optional; orders stereo pairs
        interior:                                 # optional
          transformation: affine                  # affine | homography | similarity
          fiducials_px: {"01": [815.770348, 622.505490], ...}   # fitted when loading
          # pixel_to_fiducial: [[a, b, c], [d, e, f], [g, h, 1]] # or a given matrix
        exterior: {X0: ..., Y0: ..., Z0: ..., omega: ..., phi: ..., kappa: ...}  # optional
    exterior_orientations:             # optional: read exterior orientations from files,
      - path: zmap_strip2.log          # applied in order (later files override earlier ones)
        format: zmap_log               # auto | native | pix4d | metashape | opk | zmap_log
        angle_unit: rad                # when the file does not state it
        run: str_2                     # zmap_log: which run; stage: final | initial
        where: {run: block}            # native CSV: row filter
        default_camera: wild 303.55    # camera of photos that the file lists but 'photos' lacks

A photo listed in an orientation file but not under ``photos`` is an error unless that file's
entry gives a ``default_camera``: a photo is never used without a camera.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.cameras import Intrinsics, create_intrinsics
from toolbox.errors import InputDataError, ToolboxError
from toolbox.photogrammetry.camera import Camera, RadialDistortion
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.fiducials import InteriorOrientation
from toolbox.photogrammetry.photo import Photo
from toolbox.photogrammetry.readers import read_exterior_orientations
from toolbox.photogrammetry.rotation import angle_unit as canonical_unit

FORMAT_MARKER = "orientation-project"


def along_strip(photos: list[Photo]) -> list[Photo]:
    """The photos of one strip in their order along it: by the position of their projection
    centres on the line fitted through them (least squares), in the direction the list mostly
    runs; a list already in flight order (either way) comes back unchanged. A project whose
    photos are listed by name (``IMG_10`` before ``IMG_2``) or by another tool's order would
    otherwise pair photos that are not neighbours (a base of 2 or 3 photo spacings, even
    photos that do not overlap)."""
    if len(photos) < 3:
        return list(photos)
    xy = np.array([p.require_exterior().centre[:2] for p in photos], dtype="float64")
    xy -= xy.mean(axis=0)
    t = xy @ np.linalg.svd(xy, full_matrices=False)[2][0]
    runs = float(np.dot(np.arange(len(t)) - (len(t) - 1) / 2.0, t))
    if runs < 0 or (runs == 0 and t[-1] < t[0]):
        t = -t  # the direction the list runs in (on a tie, from its first photo to its last)
    return [photos[k] for k in np.argsort(t, kind="stable")]


#: a flight line turning by more than this between consecutive photos starts a new strip
STRIP_TURN_DEG = 60.0
#: a spacing more than this times the median one between consecutive photos starts one too
STRIP_JUMP = 2.5


def infer_strips(photos: list[Photo]) -> list[list[Photo]]:
    """Photos without strip ids, in project order, split into strips where the flight turns:
    where the heading between consecutive projection centres turns by more than
    :data:`STRIP_TURN_DEG` from its strip's, or their spacing exceeds :data:`STRIP_JUMP` times
    the median one (a serpentine list from Metashape or an EXIF converter runs up one strip
    and down the next: the photos across a turn are not a stereo pair). A split leaving a
    strip of fewer than 3 photos is no flight pattern (a few photos of a drone block listed
    in any order): the photos then stay one run in project order."""
    if len(photos) < 3:
        return [list(photos)]
    xy = np.array([p.require_exterior().centre[:2] for p in photos], dtype="float64")
    step = np.diff(xy, axis=0)
    spacing = np.hypot(step[:, 0], step[:, 1])
    heading = np.arctan2(step[:, 1], step[:, 0])
    median = float(np.median(spacing))
    strips, current, along = [], [photos[0]], None
    for k in range(len(step)):
        turn = 0.0 if along is None else abs(math.degrees(
            (heading[k] - along + math.pi) % (2 * math.pi) - math.pi))
        if turn > STRIP_TURN_DEG or (median > 0 and spacing[k] > STRIP_JUMP * median):
            strips.append(current)
            current, along = [photos[k + 1]], None
            continue
        current.append(photos[k + 1])
        along = heading[k]
    strips.append(current)
    return strips if min(len(s) for s in strips) >= 3 else [list(photos)]


@dataclass
class Project:
    """Cameras and photos of one block, with their CRS."""

    crs: Any
    cameras: dict[str, Camera | Intrinsics]
    photos: dict[str, Photo]
    source: Path | None = None
    notes: list[str] = field(default_factory=list)

    def photo(self, photo_id: str) -> Photo:
        if photo_id not in self.photos:
            raise InputDataError(f"photo {photo_id!r} is not in the project "
                                 f"{self.source or ''} (photos: {', '.join(self.photos)})")
        return self.photos[photo_id]

    def oriented(self) -> list[Photo]:
        """Photos that have an exterior orientation, in project order."""
        return [p for p in self.photos.values() if p.exterior is not None]

    def strips(self) -> dict[str, list[Photo]]:
        """Oriented photos grouped by strip (photos without one form the strip ``""``), in order."""
        groups: dict[str, list[Photo]] = {}
        for p in self.oriented():
            groups.setdefault(p.strip or "", []).append(p)
        return groups

    def consecutive_pairs(self) -> list[tuple[Photo, Photo]]:
        """Consecutive oriented photos of each strip: the stereo pairs of the flight. A named
        strip's photos follow one another along the strip (:func:`along_strip`), whatever
        order the project lists them in; photos without a strip go in project order, split into
        strips where the flight turns (:func:`infer_strips`, with a warning)."""
        pairs: list[tuple[Photo, Photo]] = []
        for name, photos in self.strips().items():
            runs = [along_strip(photos)] if name else infer_strips(photos)
            if len(runs) > 1:
                import logging

                logging.getLogger("toolbox").warning(
                    f"{len(photos)} photos without a strip id: {len(runs)} strips inferred "
                    f"where the flight turns by more than {STRIP_TURN_DEG:g} degrees or the "
                    f"spacing jumps over {STRIP_JUMP:g} times the median (strips of "
                    f"{', '.join(str(len(r)) for r in runs)} photos, first photos "
                    f"{', '.join(r[0].id for r in runs[:6])}{', ...' if len(runs) > 6 else ''}"
                    "); no pair across them. Give strip ids in the project to set them")
            for run in runs:
                pairs.extend(zip(run[:-1], run[1:], strict=True))
        return pairs

    def with_exteriors(self, orientations: Mapping[str, ExteriorOrientation]) -> Project:
        """A copy with exterior orientations replaced for the photos named (which must exist)."""
        photos = dict(self.photos)
        for pid, eo in orientations.items():
            photos[pid] = replace(self.photo(pid), exterior=eo.with_crs(self.crs))
        return Project(self.crs, dict(self.cameras), photos, self.source, list(self.notes))

    def as_dict(self, angle_unit: str = "rad", base_dir: Path | None = None) -> dict[str, Any]:
        """A YAML-ready document (interior orientations as matrices; image paths relative to
        ``base_dir`` when given)."""
        import os

        from toolbox.io.crs import crs_label

        photos = []
        for p in self.photos.values():
            entry: dict[str, Any] = {"id": p.id, "camera": p.camera.name}
            if p.image is not None:
                entry["image"] = str(Path(p.image).absolute()) if base_dir is None else \
                    os.path.relpath(Path(p.image).absolute(), Path(base_dir).absolute())
            if p.strip is not None:
                entry["strip"] = p.strip
            if p.interior is not None:
                entry["interior"] = {"transformation": p.interior.transformation,
                                     "pixel_to_fiducial": p.interior.pixel_to_fiducial.tolist()}
            if p.exterior is not None:
                eo = p.exterior.as_dict(angle_unit)
                entry["exterior"] = {k: eo[k] for k in ("X0", "Y0", "Z0", "omega", "phi",
                                                         "kappa")}
            photos.append(entry)
        return {"format": FORMAT_MARKER, "version": 1,
                # a CRS without an authority code (a PROJ string) is written as WKT: its
                # name ("unknown") would not read back
                "crs": None if self.crs is None else crs_label(self.crs)
                if self.crs.to_authority(min_confidence=90) else self.crs.to_wkt(),
                "angle_unit": canonical_unit(angle_unit),
                "cameras": [c.as_dict() for c in self.cameras.values()], "photos": photos}


def _pair(value: Any, what: str, where: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputDataError(f"{where}: {what} must be two numbers, got {value!r}") from None
    return a, b


def _camera(spec: Any, where: str) -> Camera | Intrinsics:
    if isinstance(spec, Mapping) and "name" in spec and "model" in spec:
        film = sorted(set(spec) - {"name", "model"})
        if film:
            raise InputDataError(f"{where} camera {spec['name']!r}: give either 'model' or the "
                                 f"film camera's fields, not both (also: {', '.join(film)})")
        model = spec["model"]
        if isinstance(model, Mapping) and str(model.get("type", "")).lower() == "rpc":
            raise InputDataError(f"{where} camera {spec['name']!r}: an rpc camera takes no "
                                 "project (the RPCs come with each image): give the images to "
                                 "ortho:batch as IMAGES (a folder or a list) without PROJECT, "
                                 "or one to ortho:photo as INPUT")
        return create_intrinsics(model, str(spec["name"]))
    if not isinstance(spec, Mapping) or "name" not in spec or "principal_distance_mm" not in spec:
        raise InputDataError(f"{where}: a camera needs at least 'name' and "
                             f"'principal_distance_mm' (or 'model'), got {spec!r}")
    name = str(spec["name"])
    here = f"{where} camera {name!r}"
    try:
        c = float(spec["principal_distance_mm"])
    except (TypeError, ValueError):
        raise InputDataError(f"{here}: principal_distance_mm must be a number") from None
    marks = {str(k): _pair(v, f"fiducial {k}", here)
             for k, v in (spec.get("fiducials_mm") or {}).items()}
    size = spec.get("image_size_px")
    frame = spec.get("frame_size_mm")
    pixel = spec.get("pixel_size_mm")
    distortion = spec.get("distortion")
    return Camera(
        name, c, _pair(spec.get("principal_point_mm", (0.0, 0.0)), "principal_point_mm", here),
        marks,
        None if size is None else tuple(int(v) for v in _pair(size, "image_size_px", here)),
        None if pixel is None else float(pixel),
        None if frame is None else _pair(frame, "frame_size_mm", here),
        None if distortion is None else RadialDistortion.from_dict(distortion, f"{here} distortion"))


def _interior(spec: Any, camera: Camera | Intrinsics, pid: str, where: str
              ) -> InteriorOrientation:
    if isinstance(camera, Intrinsics):
        raise InputDataError(f"{where} photo {pid!r}: its camera {camera.name!r} is a "
                             f"{camera.kind} model: it has no 'interior' (fiducial) orientation")
    if not isinstance(spec, Mapping):
        raise InputDataError(f"{where} photo {pid!r}: interior must be a mapping, got {spec!r}")
    kind = spec.get("transformation", "affine")
    if "pixel_to_fiducial" in spec:
        return InteriorOrientation(spec["pixel_to_fiducial"], str(kind).lower())
    if "fiducials_px" in spec:
        measured = {str(k): _pair(v, f"fiducial {k}", f"{where} photo {pid!r}")
                    for k, v in spec["fiducials_px"].items()}
        return InteriorOrientation.fit(camera.fiducials_mm, measured, kind, pid)
    raise InputDataError(f"{where} photo {pid!r}: interior needs 'fiducials_px' or "
                         "'pixel_to_fiducial'")


def _exterior(spec: Any, pid: str, unit: str, crs: Any, where: str) -> ExteriorOrientation:
    keys = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    if not isinstance(spec, Mapping) or any(k not in spec for k in keys):
        raise InputDataError(f"{where} photo {pid!r}: exterior needs {', '.join(keys)}; "
                             f"got {spec!r}")
    try:
        values = [float(spec[k]) for k in keys]
    except (TypeError, ValueError):
        raise InputDataError(f"{where} photo {pid!r}: exterior values must be numbers") from None
    return ExteriorOrientation.from_angles(pid, *values, unit=spec.get("angle_unit", unit),
                                           crs=crs, name=f"{where} photo {pid} angle_unit")


def project_from_dict(doc: Any, base_dir: Path, source: str = "project") -> Project:
    """Build a :class:`Project` from a parsed YAML document (see the module docstring)."""
    from toolbox.io.crs import parse_crs

    if not isinstance(doc, Mapping):
        raise InputDataError(f"{source}: expected a YAML mapping with cameras and photos")
    if doc.get("format", FORMAT_MARKER) != FORMAT_MARKER or doc.get("version", 1) != 1:
        raise InputDataError(f"{source}: not an orientation project (format "
                             f"{doc.get('format')!r}, version {doc.get('version')!r}); "
                             f"expected format {FORMAT_MARKER!r}, version 1")
    crs = None
    if doc.get("crs") is not None:
        try:
            crs = parse_crs(doc["crs"], "crs")
        except ToolboxError as exc:
            raise InputDataError(f"{source}: {exc}") from None
        if not crs.is_projected:
            raise InputDataError(f"{source}: crs {doc['crs']!r} is not a projected CRS; the "
                                 "collinearity equations need Cartesian ground coordinates (metres)")
    unit = canonical_unit(doc.get("angle_unit", "rad"), f"{source} angle_unit")
    cameras: dict[str, Camera | Intrinsics] = {}
    for spec in doc.get("cameras") or []:
        cam = _camera(spec, source)
        if cam.name in cameras:
            raise InputDataError(f"{source}: camera {cam.name!r} is defined twice")
        cameras[cam.name] = cam
    photos: dict[str, Photo] = {}
    for spec in doc.get("photos") or []:
        if not isinstance(spec, Mapping) or "id" not in spec:
            raise InputDataError(f"{source}: every photo needs an 'id', got {spec!r}")
        pid = str(spec["id"])
        if pid in photos:
            raise InputDataError(f"{source}: photo {pid!r} is listed twice")
        cam_name = spec.get("camera")
        if cam_name is None or str(cam_name) not in cameras:
            raise InputDataError(f"{source}: photo {pid!r} names camera {cam_name!r}, which the "
                                 f"project does not define (cameras: "
                                 f"{', '.join(map(repr, cameras)) or 'none'})")
        cam = cameras[str(cam_name)]
        image = spec.get("image")
        photos[pid] = Photo(
            pid, cam,
            None if spec.get("exterior") is None else _exterior(spec["exterior"], pid, unit, crs,
                                                                source),
            None if spec.get("interior") is None else _interior(spec["interior"], cam, pid, source),
            None if image is None else (base_dir / str(image)),
            None if spec.get("strip") is None else str(spec["strip"]))
    project = Project(crs, cameras, photos, Path(source) if source != "project" else None)
    sources = doc.get("exterior_orientations") or []
    if isinstance(sources, Mapping):
        sources = [sources]
    for entry in sources:
        _apply_orientation_file(project, entry, base_dir, source)
    return project


def _apply_orientation_file(project: Project, entry: Any, base_dir: Path, source: str) -> None:
    if not isinstance(entry, Mapping) or "path" not in entry:
        raise InputDataError(f"{source}: each exterior_orientations entry needs a 'path', got "
                             f"{entry!r}")
    path = base_dir / str(entry["path"])
    table = read_exterior_orientations(path, entry.get("format", "auto"), entry.get("angle_unit"),
                                       project.crs, entry.get("where"), entry.get("run"),
                                       entry.get("stage", "final"))
    default = entry.get("default_camera")
    if default is not None and str(default) not in project.cameras:
        raise InputDataError(f"{source}: default_camera {default!r} of {path.name} is not a camera "
                             f"of the project")
    for pid, eo in table.orientations.items():
        if pid not in project.photos:
            if default is None:
                raise InputDataError(f"photo {pid!r} in {path} has no camera: it is not listed "
                                     f"under 'photos' in {source} and the entry gives no "
                                     "default_camera")
            project.photos[pid] = Photo(pid, project.cameras[str(default)])
        project.photos[pid] = replace(project.photos[pid], exterior=eo.with_crs(project.crs))
    project.notes.append(f"exterior orientations from {path.name}: {', '.join(table.orientations)}"
                         + (f" ({'; '.join(table.notes)})" if table.notes else ""))


def _yaml_loader():
    """A safe YAML loader with YAML 1.2 numbers: ``1_7150`` (a Siena photo id) stays a string
    instead of PyYAML's YAML 1.1 integer 17150, and ``1:20`` is not sexagesimal."""
    import re

    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.yaml_implicit_resolvers = {
        key: [(tag, regexp) for tag, regexp in resolvers
              if tag not in ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")]
        for key, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
    Loader.add_implicit_resolver("tag:yaml.org,2002:int", re.compile(r"^[-+]?[0-9]+$"),
                                 list("-+0123456789"))
    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^(?:[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
                   r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
        list("-+0123456789."))
    return Loader


def load_project(path: str | Path) -> Project:
    """Read a project YAML file. Problems raise :class:`InputDataError` naming the file.

    Numbers follow YAML 1.2 (``1_7150`` is the string "1_7150", not 17150).
    """
    import yaml

    from toolbox.io.text import read_text, yaml_error_line

    path = Path(path)
    text = read_text(path, "project")
    if "\x00" in text:
        raise InputDataError(f"project {path} is not a text file (binary content)")
    try:
        doc = yaml.load(text, Loader=_yaml_loader())  # noqa: S506
    except yaml.YAMLError as exc:
        raise InputDataError(f"project {path} is not valid YAML: {yaml_error_line(exc)}") from None
    try:
        return project_from_dict(doc, path.parent, str(path))
    except (TypeError, ValueError, KeyError, AttributeError, IndexError) as exc:
        if isinstance(exc, ToolboxError):
            raise
        # a value of the wrong shape deep in the document (a list for a mapping, text for a
        # number, a ragged matrix): one line naming the file, never a traceback
        raise InputDataError(f"project {path}: malformed value ({type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else 'wrong type'})") from None


def save_project(project: Project, path: str | Path, angle_unit: str = "rad",
                 relative_images: bool = True) -> Path:
    """Write ``project`` as YAML; image paths relative to the file's folder, or absolute with
    ``relative_images=False`` (for staged outputs whose final folder differs)."""
    import yaml

    path = Path(path)
    document = project.as_dict(angle_unit, path.parent if relative_images else None)
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path
