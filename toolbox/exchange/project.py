"""The product's orientation project (:mod:`toolbox.photogrammetry.project`) to and from an
:class:`~toolbox.exchange.model.OrientationSet`.

Each camera entry written is

- ``{name, model: <the Orthority interior-parameter spec>}`` when this toolbox has camera models
  (the ``toolbox.cameras`` package: the project loader then builds the model, distortion
  included; it refuses a camera giving both ``model`` and the film fields); or
- without camera models, the classic film fields of the distortion-free pinhole part
  (``principal_distance_mm``, ``principal_point_mm``, ``image_size_px``, ``pixel_size_mm``,
  ``frame_size_mm``), with a pixel size from ``sensor_size`` or, when the spec gives none, a
  nominal ``NOMINAL_PIXEL_MM`` (the geometry depends only on the focal length in pixels); any
  distortion is then dropped and the notes say so.

Principal point: Orthority ``cx, cy`` (normalised by ``max(w, h)``, x right, y down) are
``(cx·m·s, -cy·m·s)`` mm in the product's image system (origin at the image centre, y up), with
``m = max(w, h)`` and ``s`` the pixel size.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError
from toolbox.exchange.model import OrientationSet, PhotoOrientation, dump_yaml, focal_px

NOMINAL_PIXEL_MM = 0.001
IMAGE_SUFFIXES = {".tif", ".tiff", ".jpg", ".jpeg", ".png", ".jp2", ".dng"}
log = logging.getLogger("toolbox.exchange")


def model_cameras() -> bool:
    """True when the project loader takes ``model:`` cameras (the toolbox.cameras package)."""
    import importlib.util

    return importlib.util.find_spec("toolbox.cameras") is not None


def camera_entry(name: str, spec: dict[str, Any], notes: list[str]) -> dict[str, Any]:
    """The project YAML entry of one camera (see the module docstring)."""
    if spec.get("type") == "frame":
        return {"name": name, **{k: v for k, v in spec.items() if k != "type"}}
    if model_cameras():
        return {"name": name, "model": dict(spec)}
    w, h = spec["im_size"]
    fx, fy = focal_px(spec)
    if spec.get("sensor_size"):
        sw, sh = spec["sensor_size"]
        pixel = (sw / w + sh / h) / 2.0
        if abs(sw / w - sh / h) > 1e-6 * pixel:
            notes.append(f"camera {name!r}: non-square sensor pixels; classic fields use their "
                         "mean (the model keeps both)")
    else:
        pixel = NOMINAL_PIXEL_MM
    if abs(fx - fy) > 1e-9 * fx:
        notes.append(f"camera {name!r}: fx != fy; the classic principal distance uses fy (the "
                     "model keeps both)")
    m = max(w, h)
    entry = {"name": name, "principal_distance_mm": fy * pixel,
             "principal_point_mm": [spec.get("cx", 0.0) * m * pixel,
                                    -spec.get("cy", 0.0) * m * pixel],
             "image_size_px": [int(w), int(h)], "pixel_size_mm": pixel,
             "frame_size_mm": [w * pixel, h * pixel]}
    if any(spec.get(k) for k in spec if k[0] in "kpst" and k[1:].isdigit() or k in ("tx", "ty")):
        notes.append(f"camera {name!r}: its distortion is dropped (this toolbox has no camera "
                     "models: the classic fields hold the distortion-free pinhole part)")
    return entry


def _cameras_of_photos(oset: OrientationSet, notes: list[str]) -> dict[str, str]:
    """Photo id -> camera name, every photo resolved (the only camera when photos name none)."""
    out = {}
    for p in oset.photos.values():
        cam = p.camera
        if cam is None and len(oset.cameras) == 1:
            cam = next(iter(oset.cameras))
        if cam is None or cam not in oset.cameras:
            raise InputDataError(f"photo {p.id!r} names camera {cam!r}, which the inputs do not "
                                 f"define (cameras: {', '.join(map(repr, oset.cameras)) or 'none'}"
                                 "); add the camera file (Orthority YAML, cameras.json...)")
        out[p.id] = cam
    if any(p.camera is None for p in oset.photos.values()):
        notes.append(f"photos without a camera given the only camera {next(iter(oset.cameras))!r}")
    return out


def project_document(oset: OrientationSet, base_dir: Path | None, angle_unit: str = "deg",
                     images: dict[str, Path] | None = None) -> dict[str, Any]:
    """The project YAML document (see :mod:`toolbox.photogrammetry.project`)."""
    import os

    from toolbox.io.crs import crs_authority, crs_label
    from toolbox.photogrammetry.rotation import angle_unit as canonical_unit
    from toolbox.photogrammetry.rotation import from_radians

    unit = canonical_unit(angle_unit, "ANGLE_UNIT")
    notes: list[str] = []
    cams = _cameras_of_photos(oset, notes)
    photos = []
    for p in oset.photos.values():
        entry: dict[str, Any] = {"id": p.id, "camera": cams[p.id]}
        image = (images or {}).get(p.id)
        if image is not None:
            entry["image"] = str(image) if base_dir is None else \
                os.path.relpath(Path(image).absolute(), Path(base_dir).absolute())
        elif p.image is not None and Path(p.image).suffix:
            entry["image"] = p.image
        if p.oriented:
            entry["exterior"] = dict(zip(("X0", "Y0", "Z0"), p.xyz, strict=True)) | dict(
                zip(("omega", "phi", "kappa"), (from_radians(a, unit) for a in p.opk),
                    strict=True))
        photos.append(entry)
    cameras = [camera_entry(n, s, notes) for n, s in oset.cameras.items()
               if n in set(cams.values()) or not photos]
    oset.notes.extend(n for n in notes if n not in oset.notes)
    return {"format": "orientation-project", "version": 1,
            "crs": None if oset.crs is None else crs_label(oset.crs)
            if crs_authority(oset.crs) else oset.crs.to_wkt(),
            "angle_unit": unit, "cameras": cameras, "photos": photos}


def write_project(oset: OrientationSet, path: str | Path, angle_unit: str = "deg",
                  images: str | Path | None = None) -> Path:
    """The project YAML of ``oset``, its photos' images matched by file stem in ``images``
    (default: :func:`source_image_folder`)."""
    path = Path(path)
    folder = Path(images) if images is not None else source_image_folder(oset)
    found = {k: v.absolute() for k, v in (find_images(folder) if folder else {}).items()
             if k in oset.photos}
    if images is not None and not found:
        raise InputDataError(f"IMAGES: no image file (.tif, .jpg, ...) named after a photo id "
                             f"in {folder}")
    images = found
    if images:
        oset.notes.append(f"image paths (absolute) from {folder}")
    doc = project_document(oset, None, angle_unit, images)
    path.write_text(dump_yaml(doc), encoding="utf-8")
    return path


def from_project(project: Any, models: dict[str, dict] | None = None) -> OrientationSet:
    """An :class:`OrientationSet` from a loaded product project and the cameras' ``model:``
    specs (``models``, by camera name; they win over the classic fields). Film cameras without
    a model become pinhole specs when they know image and pixel size; fiducial fits and radial
    tables are noted as not carried over."""
    from toolbox.exchange.model import check_camera

    out = OrientationSet(crs=project.crs, source=str(project.source or ""), format="project")
    for name, cam in project.cameras.items():
        if name in (models or {}):
            out.cameras[name] = check_camera(models[name], name, out.source)
            continue
        if cam.image_size_px is None or cam.pixel_size_mm is None:
            raise InputDataError(f"camera {name!r} has no image_size_px and pixel_size_mm: it "
                                 "cannot be written as a pixel camera model")
        w, h = cam.image_size_px
        s, m = cam.pixel_size_mm, max(cam.image_size_px)
        out.cameras[name] = {"type": "pinhole", "im_size": [w, h], "focal_len": cam.c,
                             "sensor_size": [w * s, h * s],
                             "cx": cam.principal_point_mm[0] / (m * s) + 0.0,
                             "cy": -cam.principal_point_mm[1] / (m * s) + 0.0}  # no -0.0
        if cam.distortion is not None:
            kind, terms = next(iter(cam.distortion.as_dict().items()))
            what = kind if kind == "table" else f"polynomial {', '.join(terms)}"
            out.notes.append(f"camera {name!r}: its lens distortion ({what}; the film camera's "
                             "correction form) has no equivalent in the pinhole spec and is "
                             "not carried over")
        if cam.fiducials_mm:
            out.notes.append(f"camera {name!r}: fiducial marks and per-photo interior fits are "
                             "not carried over (the nominal pixel grid is assumed)")
    for p in project.photos.values():
        eo = p.exterior
        out.add_photo(PhotoOrientation(
            p.id, p.camera.name, None if p.image is None else Path(p.image).name,
            None if eo is None else (eo.x0, eo.y0, eo.z0),
            None if eo is None else (eo.omega, eo.phi, eo.kappa)))
    return out


def find_images(folder: Path) -> dict[str, Path]:
    """Image files of ``folder`` by file stem (not recursive)."""
    if not folder.is_dir():
        return {}
    return {f.stem: f for f in sorted(folder.iterdir())
            if f.suffix.lower() in IMAGE_SUFFIXES and f.is_file() and not f.name.startswith(".")}


def default_image_folder(path: Path) -> Path | None:
    """Where the images of an orientation file usually are: its folder, or OpenDroneMap's
    ``images`` beside ``opensfm/``."""
    for folder in (path.parent, path.parent.parent / "images", path.parent / "images"):
        if find_images(folder):
            return folder
    return None


def source_image_folder(oset: OrientationSet) -> Path | None:
    """The first :func:`default_image_folder` of ``oset``'s source files (a merged set names
    them all, in the order given) holding an image of one of its photos. Only the first file's
    was looked in: a camera file listed before the orientations, in a folder of its own, left
    every photo without its image."""
    first = None
    for name in (oset.source.split(", ") if oset.source else []):
        source = Path(name)
        folder = default_image_folder(source) if source.exists() else None
        if folder is not None and set(find_images(folder)) & set(oset.photos):
            return folder
        first = first or folder
    return first


def project_from_orientations(oset: OrientationSet, images: str | Path | None = None,
                              base_dir: Path | None = None):
    """The product's project object for ``oset``, images matched by file stem in ``images``
    (default: :func:`default_image_folder` of the source). Images without an orientation are
    listed and skipped with a warning; photos without an image keep no image path (the photo
    algorithms then report them)."""
    from toolbox.photogrammetry.project import project_from_dict

    source = Path(oset.source.split(", ")[0]) if oset.source else None  # merged: the first
    folder = Path(images) if images is not None else source_image_folder(oset)
    found = find_images(folder) if folder is not None else {}
    if images is not None and not found:
        raise InputDataError(f"IMAGES: no image file (.tif, .jpg, ...) in {folder}")
    unmatched = sorted(set(found) - set(oset.photos))
    if unmatched:
        text = (f"{len(unmatched)} image(s) in {folder} have no orientation and are skipped: "
                + ", ".join(unmatched))
        oset.notes.append(text)
        log.warning(text)
    missing = sorted(p for p in oset.photos if p not in found)
    if found and missing:
        text = f"{len(missing)} oriented photo(s) have no image in {folder}: {', '.join(missing)}"
        oset.notes.append(text)
        log.warning(text)
    oriented = OrientationSet(oset.cameras, {k: p for k, p in oset.photos.items() if p.oriented},
                              oset.crs, oset.source, oset.format, oset.notes)
    doc = project_document(oriented, None, "rad", {k: v.absolute() for k, v in found.items()})
    base = base_dir or (source.parent if source is not None else Path.cwd())
    project = project_from_dict(doc, base, str(source) if source else "project")
    project.notes.extend(oset.notes)
    return project
