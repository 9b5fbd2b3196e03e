"""Fiducial mark templates: the built-in families drawn at the scan's pixel size, or a template
image read from a file.

Built-in families (bright mark on a dark background; the search also tries the inverse):

- ``cross``: two bars of ``line`` mm width and ``size`` mm length;
- ``dot``: a disc of ``size`` mm diameter;
- ``cross_in_circle``: a cross of ``0.8 size`` mm inside a ring of ``size`` mm diameter and
  ``line`` mm width (a generic shape: the camera families below follow their sources);
- ``wild_rc8``, ``wild_rc10``, ``zeiss_rmk_top``, ``zeiss_rmk_a``: the marks of those
  cameras, a different shape at corner and side marks where the camera has one
  (:mod:`toolbox.matching.camera_marks`, with their sources and default sizes).

Drawn by supersampling (8 x 8 per pixel), so the template is the area-averaged mark, centred
on the template's central pixel (odd sizes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolbox.errors import InputDataError
from toolbox.matching.camera_marks import DEFAULTS, camera_mark

FAMILIES = ("cross", "dot", "cross_in_circle", *DEFAULTS)


def default_size(family: str) -> tuple[float | None, float | None]:
    """(size, line width) mm a family is drawn with when none is given; None: no source gives
    it (the user must)."""
    return DEFAULTS.get(family, (1.0, 0.06))


def mark_function(family: str, size_mm: float, line_mm: float, kind: str = "side"):
    """``f(x, y) -> 0/1`` of the mark, coordinates in mm from its centre; ``kind`` (corner or
    side) picks the shape of families whose corner and side marks differ."""
    half, w = size_mm / 2.0, line_mm / 2.0
    if family in DEFAULTS:
        return camera_mark(family, size_mm, line_mm, kind)

    def cross(x, y):
        return ((np.abs(x) <= w) & (np.abs(y) <= half)) | ((np.abs(y) <= w) & (np.abs(x) <= half))

    def dot(x, y):
        return np.hypot(x, y) <= half

    def ring(x, y):
        r = np.hypot(x, y)
        return (r <= half) & (r >= half - 2 * w)

    if family == "cross":
        return cross
    if family == "dot":
        return dot
    if family == "cross_in_circle":
        return lambda x, y: cross(x * 1.25, y * 1.25) | ring(x, y)
    raise InputDataError(f"FAMILY must be one of {', '.join(FAMILIES)}, got {family!r}")


def draw(family: str, size_mm: float, line_mm: float, pixel_mm: float,
         affine: np.ndarray | None = None, supersample: int = 8, kind: str = "side"
         ) -> np.ndarray:
    """Template of a built-in mark, float32 in 0..1, odd size ~1.5 x the mark.

    ``affine`` (2 x 2, optional) maps template pixel offsets to mark mm (default: ``pixel_mm``
    times identity with y up), e.g. to draw the mark as a rotated or mirrored scan shows it.
    """
    if not (size_mm > 0 and line_mm > 0 and pixel_mm > 0):
        raise InputDataError(f"mark size, line width and pixel size must be > 0 mm, got "
                             f"{size_mm}, {line_mm}, {pixel_mm}")
    f = mark_function(family, size_mm, line_mm, kind)
    half = int(np.ceil(0.75 * size_mm / pixel_mm)) + 2
    a = np.array([[pixel_mm, 0.0], [0.0, -pixel_mm]]) if affine is None else np.asarray(affine)
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    k = np.arange(-half, half + 1, dtype="float64")
    out = np.zeros((len(k), len(k)))
    for dy in offsets:
        for dx in offsets:
            jj, ii = np.meshgrid(k + dx, k + dy)
            out += f(a[0, 0] * jj + a[0, 1] * ii, a[1, 0] * jj + a[1, 1] * ii)
    return (out / supersample ** 2).astype(np.float32)


def read_template(path: Path, name: str = "TEMPLATE") -> tuple[np.ndarray, str]:
    """A template image (first band, or the mean of RGB) and its data type name, read as the
    scans are (:func:`toolbox.raster.photo_grid.open_photo_grid`: a paletted one as its
    colours, never its colour codes; full resolution)."""
    import rasterio

    from toolbox.raster.photo_grid import open_photo_grid

    try:
        with open_photo_grid(path) as src:  # (no warning for its missing georeference)
            data = src.read()
            dtype = src.dtypes[0]
    except rasterio.errors.RasterioError as exc:
        raise InputDataError(f"{name}: cannot read {path}: {str(exc).splitlines()[0]}") from None
    grey = data[:3].astype("float32").mean(axis=0) if data.shape[0] >= 3 else \
        data[0].astype("float32")
    if grey.shape[0] < 5 or grey.shape[1] < 5 or float(grey.std()) == 0.0:
        raise InputDataError(f"{name}: {path} must be a mark image of at least 5 x 5 pixels with "
                             f"some contrast, got {grey.shape[1]} x {grey.shape[0]}")
    return grey, dtype


def bit_depth(dtype: str) -> int:
    """Bits of an integer raster type (8, 16, 32); floats count as 32."""
    kind = np.dtype(dtype)
    return kind.itemsize * 8 if kind.kind in "iu" else 32
