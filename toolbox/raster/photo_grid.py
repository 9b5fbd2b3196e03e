"""The pixel grid of a photo file as every photo algorithm reads it (fiducials, tie points,
control measurements, ortho, rectification, epipolar): the grid as stored, at full resolution.

- orientation tags are not applied: a JPEG's EXIF Orientation (GDAL's ``EXIF_Orientation``) and
  a TIFF's Orientation tag leave the grid as stored, as GDAL reads it (OpenCV's ``imread`` and
  PIL's ``exif_transpose`` would turn it); a photo with an EXIF Orientation other than 1 gets a
  warning, since its camera file may have been measured on the turned view;
- a TIFF with several pages is read by its first page; internal overviews (and a JPEG's
  reduced DCT scales) are never read instead of the full-resolution pixels, also for a reduced
  read (``out_shape``): GDAL would otherwise serve a decimated read from an overview made with
  whatever resampling its writer chose;
- a paletted photo (one band with a colour table, 1-bit scans included) is read as its colours
  (RGB, or RGBA when the table has transparency: ``gdal_translate -expand``), never as colour
  codes;
- a world file or ``.aux.xml`` georeferencing beside a photo is not used: photo algorithms
  address pixels by (col, row), never through the file's transform.
"""

from __future__ import annotations

import warnings
from typing import Any

#: GDAL open option that keeps overviews out of every read
FULL_RESOLUTION = "OVERVIEW_LEVEL=NONE"


def expanded_path(src: Any, path: str) -> str:
    """The path to read the open dataset ``src`` of ``path`` by: a paletted one (one band with a
    colour table) as its colours through GDAL's ``vrt://`` expansion, else ``path``."""
    from toolbox.errors import InputDataError

    if src.count != 1:
        return path
    try:
        table = src.colormap(1)
    except ValueError:  # no colour table
        return path
    expand = "rgba" if any(entry[3] < 255 for entry in table.values()) else "rgb"
    if "?" in path:  # vrt:// takes what follows a '?' as its options
        raise InputDataError(f"'{path}' is a paletted photo whose path holds a '?': expand it "
                             f"first: gdal_translate -expand {expand} '{path}' photo_{expand}.tif")
    return f"vrt://{path}?expand={expand}"


def open_expanded(path: Any, full_resolution: bool = False,
                  warn_orientation: bool = False) -> tuple[str, Any]:
    """``(read path, dataset)``: the photo at ``path`` open (rasterio; the caller closes it) by
    :func:`expanded_path`'s path, one open of the file unless it is paletted (reopened as its
    colours), without the warning about a photo's missing georeferencing. ``full_resolution``:
    its overviews kept out of every read (:data:`FULL_RESOLUTION`); ``warn_orientation``:
    :func:`warn_orientation_tag` of the file as first opened."""
    import rasterio

    path = str(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        src = rasterio.open(path, **({"OVERVIEW_LEVEL": "NONE"} if full_resolution else {}))
        try:
            if warn_orientation:
                warn_orientation_tag(src, path)
            read = expanded_path(src, path)
        except BaseException:
            src.close()
            raise
        if read == path:
            return path, src
        src.close()
        return read, rasterio.open(f"{read}&oo={FULL_RESOLUTION}" if full_resolution else read)


def open_photo_grid(path: Any) -> Any:
    """The photo at ``path`` open (rasterio dataset; the caller closes it) as photo algorithms
    read it (module docstring): full resolution only, a paletted one as its colours."""
    return open_expanded(path, full_resolution=True)[1]


def warn_orientation_tag(src: Any, path: Any, name: str = "photo") -> None:
    """A warning when the open photo ``src`` carries an EXIF Orientation other than 1 (normal):
    the toolbox uses the grid as stored, like GDAL, not the turned view a viewer shows. Logged on
    the ``toolbox`` logger, as the other input warnings of a reader without a feedback: the run's
    feedback keeps it (:func:`toolbox.feedback.logged_warnings`), so ``toolbox.run`` callers,
    the console and the run report see it (a Python ``UserWarning`` reached none of them but the
    console, labelled by its module)."""
    import logging

    value = src.tags().get("EXIF_Orientation")
    if value is not None and value.strip() not in ("", "1"):
        logging.getLogger("toolbox").warning(
            f"{name}: {path} has EXIF Orientation {value.strip()} (the view is turned or "
            "mirrored): the pixels are used as stored, not turned; image measurements and "
            "camera files must refer to the stored grid")
