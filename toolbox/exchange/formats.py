"""Format detection, reading several inputs into one :class:`OrientationSet`, and writing.

Readable (``READERS``): ``opensfm`` (reconstruction.json), ``opensfm_cameras`` (cameras.json),
``orthority_interior`` (YAML), ``orthority_exterior`` (GeoJSON), ``csv`` (Orthority-style CSV),
``project`` (the product's YAML), ``metashape`` (camera XML), ``metashape_opk`` (OPK text
export), ``patb`` (PAT-B .ori: centres and rotation matrices), ``exif`` (drone JPEG/TIFF tags).
ODM ``gcp_list.txt`` is control, not orientation: :mod:`toolbox.exchange.odm_gcp`.

Writable (``WRITERS``): ``project``, ``orthority`` (GeoJSON + interior YAML beside it, or the
YAML alone), ``csv``, ``patb``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError, ParameterError
from toolbox.exchange.model import OrientationSet

READERS = ("opensfm", "opensfm_cameras", "orthority_interior", "orthority_exterior", "csv",
           "project", "metashape", "metashape_opk", "patb", "exif")
WRITERS = ("project", "orthority", "csv", "patb")
ORIENTATION_SUFFIXES = {".json", ".geojson", ".yaml", ".yml", ".csv", ".txt", ".xml", ".ori"}
EXIF_SUFFIXES = {".jpg", ".jpeg", ".tif", ".tiff"}


def _head(path: Path, size: int = 4000) -> str:
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            return f.read(size)
    except OSError as exc:
        raise InputDataError(f"cannot read {path}: {exc}") from None


def detect(path: Path) -> str:
    """The format of one file, from its extension and first characters; or ``gcp`` for an ODM
    control list."""
    suffix = path.suffix.lower()
    if suffix in EXIF_SUFFIXES:
        return "exif"
    head = _head(path)
    if suffix in (".json", ".geojson"):
        if '"FeatureCollection"' in head:
            return "orthority_exterior"
        if head.lstrip().startswith("[") or '"shots"' in head:
            return "opensfm"
        if '"projection_type"' in head:
            return "opensfm_cameras"
    elif suffix in (".yaml", ".yml"):
        if "orientation-project" in head or "\nphotos:" in f"\n{head}":
            return "project"
        return "orthority_interior"
    elif suffix == ".xml":
        if "<document" in head and "<chunk" in head or "<sensors" in head:
            return "metashape"
    elif suffix in (".csv", ".txt", ".ori"):
        from toolbox.exchange import odm_gcp, patb

        lines = [ln.strip() for ln in head.splitlines() if ln.strip()]
        if lines and any(line.lstrip("# ").lower().startswith("photoid") for line in lines[:3]):
            return "metashape_opk"
        if patb.looks_like(lines):
            return "patb"
        if odm_gcp.looks_like(lines):
            return "gcp"
        from toolbox.exchange.csvtable import looks_like

        if looks_like("\n".join(ln for ln in lines if not ln.startswith("#"))):
            return "csv"
    raise InputDataError(f"cannot tell the format of {path}: not a readable orientation file "
                         f"({', '.join(READERS)}; orientation:convert can be given its FORMAT)")


def _recognised(path: Path) -> bool:
    try:
        return detect(path) != "gcp"
    except InputDataError:
        return False


def expand(paths: Sequence[str | Path], notes: list[str] | None = None) -> list[Path]:
    """Files of the inputs: a folder stands for the orientation files it holds whose format is
    recognised (the others listed in ``notes``; OpenDroneMap's ``reconstruction.topocentric.json``
    left out when ``reconstruction.json`` is there), or for its images (EXIF) when it holds
    none."""
    out: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            files = sorted(f for f in path.iterdir() if f.is_file() and not f.name.startswith("."))
            candidates = [f for f in files if f.suffix.lower() in ORIENTATION_SUFFIXES]
            if (path / "reconstruction.json").exists():
                candidates = [f for f in candidates if f.name != "reconstruction.topocentric.json"]
            chosen = [f for f in candidates if _recognised(f)]
            skipped = sorted(f.name for f in set(candidates) - set(chosen))
            if skipped and notes is not None:
                notes.append(f"{path}: not orientation files, left out: {', '.join(skipped)}")
            chosen = chosen or [f for f in files if f.suffix.lower() in EXIF_SUFFIXES]
            if not chosen:
                raise InputDataError(f"folder {path} holds no orientation file nor image")
            out += chosen
        elif path.exists():
            out.append(path)
        else:
            raise InputDataError(f"{path} does not exist")
    return out


def read_one(path: Path, fmt: str, crs: Any = None, angle_unit: str | None = None,
             frame: str = "auto") -> OrientationSet:
    from toolbox.exchange import csvtable, metashape, opensfm, orthority, patb

    if fmt == "opensfm":
        return opensfm.read_reconstruction(path, crs, frame)
    if fmt == "opensfm_cameras":
        return opensfm.read_cameras_json(path)
    if fmt == "orthority_interior":
        return orthority.read_interior(path)
    if fmt == "orthority_exterior":
        return orthority.read_exterior(path, crs)
    if fmt == "csv":
        return csvtable.read_csv(path, crs, angle_unit)
    if fmt == "metashape":
        return metashape.read_xml(path, crs)
    if fmt == "metashape_opk":
        return metashape.read_opk(path, crs, angle_unit)
    if fmt == "patb":
        return patb.read_patb(path, crs, angle_unit)
    if fmt == "project":
        import yaml

        from toolbox.exchange.project import from_project
        from toolbox.photogrammetry.project import load_project

        doc = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
        models = {str(c.get("name")): c["model"] for c in doc.get("cameras") or []
                  if isinstance(c, dict) and isinstance(c.get("model"), dict)}
        return from_project(load_project(path), models)
    if fmt == "gcp":
        raise InputDataError(f"{path} is an ODM gcp_list (control points, not "
                             "orientations): convert it alone, to an image-measurement CSV")
    raise ParameterError("FORMAT", f"must be one of auto, {', '.join(READERS)}; got {fmt!r}")


def _check_same_crs(part: OrientationSet, out: OrientationSet) -> None:
    """``part``'s CRS taken as the earlier inputs' (``out.crs``, kept) when it is the same CRS
    at ``part``'s positions (or, without any, the earlier ones'): the centroid moves by at most
    1 mm (:func:`toolbox.io.crs.check_one_crs`; an ESRI ``.prj`` rarely equals its EPSG
    code's definition), else an error naming both CRSs and the shift."""
    from toolbox.io.crs import PRJ_TOLERANCE_M, check_one_crs, crs_label, same_crs

    if same_crs(part.crs, out.crs):
        return
    name = Path(part.source).name
    advice = "give the inputs in one CRS"
    if len(mine := part.positions_xy()):
        check_one_crs(name, part.crs, "an earlier input", out.crs, mine, advice)
    else:
        check_one_crs("an earlier input", out.crs, name, part.crs, out.positions_xy(), advice)
    out.notes.append(f"{name}: its CRS ({crs_label(part.crs)}) taken as the earlier inputs' "
                     f"({crs_label(out.crs)}): the same at the positions (within "
                     f"{PRJ_TOLERANCE_M * 1000:g} mm)")


def merge(parts: list[OrientationSet]) -> OrientationSet:
    """One set from several: cameras and photos united; the same camera or photo defined twice
    differently, or two different CRSs, is an error."""
    out = OrientationSet(source=", ".join(p.source for p in parts),
                         format="+".join(dict.fromkeys(p.format for p in parts)))
    for part in parts:
        if part.crs is not None:
            if out.crs is None:
                out.crs = part.crs
            else:
                _check_same_crs(part, out)
        for name, spec in part.cameras.items():
            if name in out.cameras and out.cameras[name] != spec:
                raise InputDataError(f"camera {name!r} is defined differently in "
                                     f"{part.source} and an earlier input")
            out.cameras[name] = spec
        for pid, photo in part.photos.items():
            old = out.photos.get(pid)
            if old is not None and old.oriented and photo.oriented and \
                    (old.xyz, old.opk) != (photo.xyz, photo.opk):
                raise InputDataError(f"photo {pid!r} has two different orientations "
                                     f"({part.source} and an earlier input)")
            if old is None or photo.oriented:
                photo.camera = photo.camera or (old.camera if old else None)
                out.photos[pid] = photo
        out.notes += [f"{Path(part.source).name}: {n}" for n in part.notes]
    return out


def read_orientations(paths: Sequence[str | Path], fmt: str = "auto", crs: Any = None,
                      angle_unit: str | None = None, frame: str = "auto") -> OrientationSet:
    """Every input read (format detected per file unless given) and merged."""
    if fmt != "auto" and fmt not in READERS:
        raise ParameterError("FORMAT", f"must be one of auto, {', '.join(READERS)}; got {fmt!r}")
    notes: list[str] = []
    files = expand(paths, notes)
    formats = [detect(f) if fmt == "auto" else fmt for f in files]
    exif = [f for f, k in zip(files, formats, strict=True) if k == "exif"]
    parts = [read_one(f, k, crs, angle_unit, frame)
             for f, k in zip(files, formats, strict=True) if k != "exif"]
    if exif:
        from toolbox.exchange import exif as exif_reader

        parts.append(exif_reader.read_images(exif, crs))
    out = merge(parts) if len(parts) > 1 else parts[0]
    out.notes += notes
    return out


def write_orientations(oset: OrientationSet, fmt: str, path: str | Path,
                       angle_unit: str | None = None,
                       images: str | Path | None = None) -> list[Path]:
    """Write ``oset`` as ``fmt``; the files written (sidecars included). ``images``: the
    folder of the photos' images (a project's ``image`` paths)."""
    from toolbox.exchange import csvtable, orthority, patb
    from toolbox.exchange.project import write_project

    path = Path(path)
    if fmt == "project":
        return [write_project(oset, path, angle_unit or "deg", images)]
    if fmt == "orthority":
        if angle_unit not in (None, "rad", "radians"):
            raise ParameterError("ANGLE_UNIT", "must be rad for Orthority (its GeoJSON holds "
                                 f"radians), got {angle_unit!r}")
        if path.suffix.lower() in (".yaml", ".yml"):
            return [orthority.write_interior(oset, path)]
        written = [orthority.write_exterior(oset, path)]
        if oset.cameras:
            stem = path.stem.removesuffix("_ext_param")
            written.append(orthority.write_interior(oset, path.with_name(f"{stem}_int_param.yaml")))
        return written
    if fmt == "csv":
        csvtable.write_csv(oset, path, angle_unit or "deg")
        return [path] + ([path.with_suffix(".prj")] if oset.crs is not None else [])
    if fmt == "patb":
        if angle_unit is not None:
            raise ParameterError("ANGLE_UNIT_OUT", "does not apply to PAT-B (it holds rotation "
                                 "matrices, not angles)")
        return [patb.write_patb(oset, path)]
    raise ParameterError("FORMAT_OUT", f"must be one of {', '.join(WRITERS)}; got {fmt!r}")


def describe(oset: OrientationSet) -> str:
    return json.dumps(oset.summary(), indent=1)
