"""Approximate photo positions for choosing pairs: a GNSS log (CSV) or the photos' EXIF GPS tags.

Positions are returned as planar ``(x, y)`` (N, 2) in metres or the CSV's planar unit: lon/lat
(EXIF, or CSV columns ``lon``/``lat``) go through a local equirectangular projection on the
WGS84 ellipsoid's radii of curvature at the block's mean latitude (centimetres over a block of a
few kilometres: ample for ranking neighbours). Heights are not needed.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from toolbox.errors import InputDataError

WGS84_A = 6_378_137.0  # m, semi-major axis
WGS84_E2 = 0.00669437999014  # first eccentricity squared


def lonlat_to_local(lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
    """Degrees -> metres east/north of the mean position: the meridian and prime-vertical radii
    of curvature of WGS84 at the mean latitude (equirectangular about it)."""
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    phi = math.radians(float(lat.mean()))
    w = 1.0 - WGS84_E2 * math.sin(phi) ** 2
    meridian = WGS84_A * (1.0 - WGS84_E2) / w ** 1.5
    prime = WGS84_A / math.sqrt(w)
    k = math.radians(1.0)
    return np.column_stack([(lon - lon.mean()) * k * prime * math.cos(phi),
                            (lat - lat.mean()) * k * meridian])


def _rational(text: str) -> list[float]:
    """GDAL's EXIF rationals ``(24) (40) (49.0009)`` -> [24, 40, 49.0009]."""
    return [float(v) for v in re.findall(r"\(([^)]*)\)", text) if v.strip()]


def exif_lonlat(tags: dict[str, str]) -> tuple[float, float] | None:
    """(lon, lat) in degrees from GDAL's EXIF tags (``EXIF_GPSLatitude`` ...), or None."""
    try:
        lat = _rational(tags["EXIF_GPSLatitude"])
        lon = _rational(tags["EXIF_GPSLongitude"])
    except KeyError:
        return None
    if len(lat) != 3 or len(lon) != 3:
        return None
    deg_lat = lat[0] + lat[1] / 60.0 + lat[2] / 3600.0
    deg_lon = lon[0] + lon[1] / 60.0 + lon[2] / 3600.0
    if tags.get("EXIF_GPSLatitudeRef", "N").strip().upper().startswith("S"):
        deg_lat = -deg_lat
    if tags.get("EXIF_GPSLongitudeRef", "E").strip().upper().startswith("W"):
        deg_lon = -deg_lon
    if not (-90.0 <= deg_lat <= 90.0 and -180.0 <= deg_lon <= 180.0) or \
            (deg_lat == 0.0 and deg_lon == 0.0):  # a camera without a fix writes zeros
        return None
    return deg_lon, deg_lat


def read_positions(path: Path, ids: list[str], name: str = "POSITIONS") -> np.ndarray:
    """Planar positions (len(ids), 2) of the photos ``ids`` from a CSV with a ``photo`` column
    and either ``x``, ``y`` (planar, e.g. easting/northing) or ``lon``, ``lat`` (degrees)."""
    from toolbox.photogrammetry.tables import column, read_csv_table

    header, rows = read_csv_table(Path(path), name)
    photo = column(header, "photo", "image", "id", name=name, path=path)
    lon = column(header, "lon", "longitude", required=False)
    lat = column(header, "lat", "latitude", required=False)
    planar = lon is None or lat is None
    cx = column(header, "x", "easting", "e", name=name, path=path) if planar else lon
    cy = column(header, "y", "northing", "n", name=name, path=path) if planar else lat
    found: dict[str, tuple[float, float]] = {}
    for line, r in enumerate(rows, start=1):
        try:
            xy = (float(r[cx]), float(r[cy]))
        except ValueError:
            raise InputDataError(f"{name}: {path}, data line {line}: {cx}/{cy} must be numbers, "
                                 f"got {r[cx]!r}, {r[cy]!r}") from None
        if not all(math.isfinite(v) for v in xy):
            raise InputDataError(f"{name}: {path}, data line {line}: {cx}/{cy} must be finite, "
                                 f"got {r[cx]!r}, {r[cy]!r}")
        found[Path(r[photo]).stem if r[photo] not in ids else r[photo]] = xy
    missing = [i for i in ids if i not in found]
    if missing:
        raise InputDataError(f"{name}: {path} gives no position for {len(missing)} photo(s): "
                             f"{', '.join(missing[:5])} (column {photo!r} must name every photo)")
    xy = np.array([found[i] for i in ids], dtype="float64")
    return xy if planar else lonlat_to_local(xy[:, 0], xy[:, 1])
