"""Orientation exchange: cameras and exterior orientations read from and written to the files
other programs use (OpenSfM/ODM, Orthority, Metashape, CSV, PAT-B, drone EXIF), through one
in-memory :class:`~toolbox.exchange.model.OrientationSet` in the product's conventions.

Formats and conventions: :mod:`toolbox.exchange.formats` and each format's module.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.photogrammetry.tables import PROJECT_EXTENSIONS, PROJECT_READERS

__all__ = ["PROJECT_EXTENSIONS", "project_from_file", "read_orientations", "write_orientations"]


def read_orientations(*args, **kwargs):
    """See :func:`toolbox.exchange.formats.read_orientations`."""
    from toolbox.exchange.formats import read_orientations as read

    return read(*args, **kwargs)


def write_orientations(*args, **kwargs):
    """See :func:`toolbox.exchange.formats.write_orientations`."""
    from toolbox.exchange.formats import write_orientations as write

    return write(*args, **kwargs)


CAMERA_FILES = ("*int_param*.yaml", "*int_param*.yml", "cameras.json")


def _companion_cameras(oset, path: Path):
    """Cameras the photos name but the file lacks, from a camera file beside it (Orthority's
    ``*_int_param.yaml``, OpenSfM's ``cameras.json``)."""
    from toolbox.exchange.formats import merge, read_one

    wanted = {p.camera for p in oset.photos.values()} - set(oset.cameras)
    if not wanted and oset.cameras:
        return oset
    for pattern in CAMERA_FILES:
        for candidate in sorted(path.parent.glob(pattern)):
            kind = "opensfm_cameras" if candidate.suffix == ".json" else "orthority_interior"
            cams = read_one(candidate, kind)
            if wanted <= set(cams.cameras) | {None}:
                merged = merge([oset, cams])
                merged.notes.append(f"cameras from {candidate.name} (beside {path.name})")
                return merged
    return oset


def project_from_file(path: str | Path, images: str | Path | None = None, crs: Any = None,
                      angle_unit: str | None = None):
    """The product's project object from any readable orientation file, images matched by file
    stem in ``images`` (default: the file's folder, or ODM's ``images`` folder); see
    :func:`toolbox.exchange.project.project_from_orientations`."""
    from toolbox.exchange.project import project_from_orientations

    path = Path(path)
    oset = _companion_cameras(read_orientations([path], "auto", crs, angle_unit), path)
    return project_from_orientations(oset, images)


PROJECT_READERS["exchange"] = project_from_file  # load_project_parameter's reader of other files
