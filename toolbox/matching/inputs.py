"""The photos of a tie-point run: from an orientation project (photos with an image, their
cameras and orientations) or from a folder of images (no camera: pairs by thumbnails)."""

from __future__ import annotations

from pathlib import Path

from toolbox.errors import InputDataError
from toolbox.matching.block import BlockPhoto
from toolbox.matching.images import ImageSource
from toolbox.photogrammetry.photo import fit_image_size

IMAGE_SUFFIXES = (".tif", ".tiff", ".jpg", ".jpeg", ".png", ".jp2", ".vrt")


def photos_from_project(project, name: str = "PROJECT") -> tuple[list[BlockPhoto], list[str]]:
    """Photos of the project that name an image, and the ids of those that do not."""
    photos, skipped = [], []
    for photo in project.photos.values():
        if photo.image is None:
            skipped.append(photo.id)
            continue
        if not Path(photo.image).exists():
            raise InputDataError(f"{name}: the image {photo.image} of photo {photo.id!r} does not "
                                 "exist")
        source = ImageSource.open(photo.image, f"{name} photo {photo.id!r}")
        # tie points are measured in the raster's pixels: they must be the camera's
        photo = fit_image_size(photo, source.width, source.height, photo.image)
        photos.append(BlockPhoto(photo.id, source, photo))
    return photos, skipped


def photos_from_folder(folder: Path, name: str = "IMAGES") -> list[BlockPhoto]:
    """Every image file of ``folder`` (by suffix, sorted by name); the id is the file's stem."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputDataError(f"{name}: {folder} is not a folder")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    stems = [p.stem for p in files]
    twice = sorted({s for s in stems if stems.count(s) > 1})
    if twice:
        raise InputDataError(f"{name}: {folder} holds several images named {twice[0]!r} (ids are "
                             "file names without the suffix)")
    return [BlockPhoto(p.stem, ImageSource.open(p, name)) for p in files]
