"""Approximate orientations from drone image tags (EXIF and DJI XMP), read through GDAL.

- Position: XMP ``drone-dji:GpsLatitude``, ``GpsLongtitude`` (DJI's spelling) or
  ``GpsLongitude``, ``AbsoluteAltitude``; else EXIF ``GPSLatitude``/``GPSLongitude``/
  ``GPSAltitude`` (WGS84 degrees; heights as the drone records them).
- Attitude: XMP ``GimbalRollDegree``, ``GimbalPitchDegree``, ``GimbalYawDegree`` (degrees). DJI's
  gimbal pitch is -90 for a nadir view; as body angles for :func:`geodesy.rpy_to_grid_rotation`
  (0 = nadir) pitch becomes ``gimbal pitch + 90`` (Orthority and OpenSfM read them so).
- Camera: XMP ``CalibratedFocalLength``/``CalibratedOpticalCenterX/Y`` (pixels of the sensor's
  full EXIF size ``PixelXDimension``), else EXIF ``FocalLengthIn35mmFilm`` (``focal_len =
  f35 / 36``, the 35 mm frame's 36 mm long side), else nothing (an error). A ``pinhole`` spec
  named ``make model width height``: these orientations are approximate (GNSS metres, gimbal
  degrees) and meant as a start for a bundle adjustment or a quick look.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.exchange import geodesy
from toolbox.exchange.model import OrientationSet, PhotoOrientation, check_camera, opk_from_matrix

#: largest offset of a calibrated optical centre from the image centre (fraction of the size)
MAX_CENTRE_OFFSET = 0.25


def _rational(text: str | None) -> list[float]:
    return [float(v) for v in re.findall(r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?", text or "")]


def _dms(text: str | None, ref: str | None) -> float | None:
    parts = _rational(text)
    if not parts:
        return None
    value = sum(p / 60 ** k for k, p in enumerate(parts[:3]))
    return -value if (ref or "").strip().upper() in ("S", "W") else value


def image_tags(path: Path) -> tuple[dict[str, str], dict[str, str], tuple[int, int]]:
    """EXIF tags, DJI XMP attributes and the raster size of one image."""
    import rasterio
    from rasterio.errors import NotGeoreferencedWarning

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            with rasterio.open(path) as ds:
                tags = {k.removeprefix("EXIF_"): v for k, v in ds.tags().items()}
                xmp_text = (ds.tags(ns="xml:XMP") or {}).get("xml:XMP", "")
                size = (ds.width, ds.height)
    except rasterio.errors.RasterioIOError as exc:
        raise InputDataError(f"cannot read {path}: {exc}") from None
    xmp = dict(re.findall(r"drone-dji:(\w+)=\"([^\"]*)\"", xmp_text))
    xmp |= dict(re.findall(r"<drone-dji:(\w+)>([^<]*)</drone-dji:\1>", xmp_text))
    return tags, xmp, size


def read_images(paths: Sequence[str | Path], crs: Any = None) -> OrientationSet:
    """Approximate orientations and cameras from drone images' tags."""
    out = OrientationSet(source=", ".join(Path(p).name for p in paths[:3])
                         + (" ..." if len(paths) > 3 else ""), format="exif")
    records = []
    for path in map(Path, paths):
        tags, xmp, (w, h) = image_tags(path)
        lat = float(xmp["GpsLatitude"]) if "GpsLatitude" in xmp else \
            _dms(tags.get("GPSLatitude"), tags.get("GPSLatitudeRef"))
        lon = next((float(xmp[k]) for k in ("GpsLongtitude", "GpsLongitude") if k in xmp),
                   None) or _dms(tags.get("GPSLongitude"), tags.get("GPSLongitudeRef"))
        alt = float(xmp["AbsoluteAltitude"]) if "AbsoluteAltitude" in xmp else \
            next(iter(_rational(tags.get("GPSAltitude"))), None)
        if lat is None or lon is None or alt is None:
            raise InputDataError(f"{path.name}: no GPS position in its EXIF/XMP tags")
        try:
            rpy = [float(xmp[f"Gimbal{k}Degree"]) for k in ("Roll", "Pitch", "Yaw")]
        except KeyError:
            raise InputDataError(f"{path.name}: no gimbal angles (XMP GimbalRoll/Pitch/"
                                 "YawDegree): its attitude is unknown") from None
        full_w = int(_rational(tags.get("PixelXDimension"))[0]) if tags.get("PixelXDimension") \
            else w
        m = max(w, h)
        if "CalibratedFocalLength" in xmp:
            scale = w / full_w
            spec = {"type": "pinhole", "im_size": [w, h],
                    "focal_len": float(xmp["CalibratedFocalLength"]) * scale / m,
                    "cx": (float(xmp.get("CalibratedOpticalCenterX", full_w / 2)) * scale
                           - w / 2) / m,
                    "cy": (float(xmp.get("CalibratedOpticalCenterY", 0)) * scale - h / 2) / m
                    if "CalibratedOpticalCenterY" in xmp else 0.0}
            # the calibration is in pixels of the sensor's full size (PixelXDimension): a
            # resized copy whose EXIF was rewritten to its own size scales it wrongly, which
            # puts the optical centre far off the image's centre
            off = max(abs(spec["cx"]) * m / w, abs(spec["cy"]) * m / h)
            if off > MAX_CENTRE_OFFSET:
                raise InputDataError(
                    f"{path.name}: XMP CalibratedOpticalCenterX/Y "
                    f"({xmp.get('CalibratedOpticalCenterX')}, {xmp.get('CalibratedOpticalCenterY')}"
                    f") px, read against EXIF PixelXDimension {full_w}, put the optical centre "
                    f"{off:.0%} of the image size off the centre of the {w} x {h} px image: the "
                    "calibration is in pixels of a larger original (a resized copy whose EXIF "
                    "gives its own size?); use the original image or give its camera")
        elif tags.get("FocalLengthIn35mmFilm"):
            spec = {"type": "pinhole", "im_size": [w, h],
                    "focal_len": _rational(tags["FocalLengthIn35mmFilm"])[0] / 36.0}
        else:
            raise InputDataError(f"{path.name}: no focal length (XMP CalibratedFocalLength or "
                                 "EXIF FocalLengthIn35mmFilm)")
        name = " ".join(v for v in (tags.get("Make", "").strip(), tags.get("Model", "").strip(),
                                    str(w), str(h)) if v)
        spec = check_camera(spec, name, path.name)
        if name in out.cameras and out.cameras[name] != spec:
            raise InputDataError(f"{path.name}: camera {name!r} has other calibration tags than "
                                 "an earlier image of the same camera")
        out.cameras[name] = spec
        records.append((path, name, lon, lat, alt, rpy))
    if not records:
        raise InputDataError("no image given")
    lons = np.array([r[2] for r in records])
    lats = np.array([r[3] for r in records])
    out.crs = geodesy.require_projected(crs, "images") if crs is not None else \
        geodesy.utm_crs(float(lons.mean()), float(lats.mean()))
    xyz = geodesy.geographic_to_grid(lons, lats, [r[4] for r in records], out.crs)
    for k, (path, name, lon, lat, alt, (roll, pitch, yaw)) in enumerate(records):
        r = geodesy.rpy_to_grid_rotation(*np.radians([roll, pitch + 90.0, yaw]), lon, lat, alt,
                                         out.crs)
        out.add_photo(PhotoOrientation(path.stem, name, path.name, tuple(xyz[k].tolist()),
                                       opk_from_matrix(r, path.name)), path.name)
    out.notes += [f"positions: GNSS WGS84 -> {out.crs.name}; heights as tagged",
                  "attitude: DJI gimbal roll, pitch + 90, yaw (degrees) as body angles: "
                  "approximate orientations"]
    return out
