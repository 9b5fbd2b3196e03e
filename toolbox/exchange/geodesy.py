"""Positions and rotations from Cartesian frames (topocentric ENU, geocentric ECEF, a camera's local
level frame) into a projected CRS, with pyproj.

A map grid is not a Cartesian frame: its axes turn against true north by the meridian convergence
and its scale varies. The rotation that carries a frame's axes onto the grid's at a point is taken
from the Jacobian of the pyproj transformation there (central differences of ``STEP_M``), made
orthonormal by its polar decomposition: it holds the convergence, the tilt of the local vertical
against a distant topocentric origin and nothing of the scale. Heights pass through as the source
gives them (ellipsoidal for WGS84 ECEF/topocentric sources unless the target CRS has a vertical
datum, which pyproj then applies).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

STEP_M = 1.0
WGS84_3D = "EPSG:4979"


@functools.lru_cache(maxsize=16)
def utm_crs(lon: float, lat: float):
    """The WGS 84 / UTM zone CRS holding ``(lon, lat)`` (degrees); cached (PROJ's database query
    takes 0.1-0.3 s, and a reconstruction asks once per shot)."""
    from pyproj import CRS
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    from toolbox.io.crs import remember, remembered

    question = f"utm|{lon!r}|{lat!r}"  # (kept between runs: the same answer every time)
    code = remembered(question)
    if code is None:
        info = query_utm_crs_info("WGS 84", area_of_interest=AreaOfInterest(lon, lat, lon, lat))
        code = [info[0].auth_name, info[0].code] if info else []
        remember(question, code)
    if not code:
        raise InputDataError(f"no UTM zone for lon {lon}, lat {lat}")
    return CRS.from_authority(*code)


def require_projected(crs: Any, where: str):
    from toolbox.io.crs import parse_crs

    crs = parse_crs(crs, "CRS")
    if not crs.is_projected:
        raise InputDataError(f"{where}: CRS {crs.name!r} is not projected; the orientations need "
                             "a projected CRS (metres), e.g. a UTM zone")
    return crs


@functools.lru_cache(maxsize=16)
def _geographic_to(crs):
    """The transformer from WGS84 3D to ``crs`` (a pyproj CRS or a text PROJ reads), one per
    CRS: making one queries PROJ's database (3-4 ms), and a reconstruction read asked for the
    same one three times (pyproj's transformers are thread-safe: each thread gets its own PROJ
    object)."""
    from pyproj import Transformer

    return Transformer.from_crs(WGS84_3D, crs, always_xy=True)


def topocentric_function(lat0: float, lon0: float, h0: float, crs) -> Callable:
    """``f(enu (N, 3)) -> grid xyz (N, 3)`` for a WGS84 topocentric frame at (lat0, lon0, h0)."""
    from pyproj import Transformer

    to_lla = Transformer.from_pipeline(
        f"+proj=pipeline +step +inv +proj=topocentric +ellps=WGS84 +lat_0={float(lat0)!r} "
        f"+lon_0={float(lon0)!r} +h_0={float(h0)!r} +step +inv +proj=cart +ellps=WGS84 "
        "+step +proj=unitconvert +xy_in=rad +xy_out=deg")
    to_grid = _geographic_to(crs)

    def f(enu: np.ndarray) -> np.ndarray:
        enu = np.atleast_2d(np.asarray(enu, dtype="float64"))
        lon, lat, h = to_lla.transform(enu[:, 0], enu[:, 1], enu[:, 2])
        return np.column_stack(to_grid.transform(lon, lat, h))

    return f


def ecef_function(crs) -> Callable:
    """``f(ecef (N, 3)) -> grid xyz (N, 3)`` (WGS84 geocentric, metres)."""
    from pyproj import Transformer

    to_grid = Transformer.from_crs("EPSG:4978", crs, always_xy=True)

    def f(xyz: np.ndarray) -> np.ndarray:
        xyz = np.atleast_2d(np.asarray(xyz, dtype="float64"))
        return np.column_stack(to_grid.transform(xyz[:, 0], xyz[:, 1], xyz[:, 2]))

    return f


def frame_to_grid(function: Callable, points: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` rotations carrying the source frame's axes onto the grid axes (X east-ish,
    Y north-ish, Z up) at each point: the polar factor of the Jacobian of ``function``."""
    points = np.atleast_2d(np.asarray(points, dtype="float64"))
    n = len(points)
    steps = np.eye(3) * STEP_M
    plus = function(np.repeat(points, 3, axis=0) + np.tile(steps, (n, 1))).reshape(n, 3, 3)
    minus = function(np.repeat(points, 3, axis=0) - np.tile(steps, (n, 1))).reshape(n, 3, 3)
    jacobian = np.transpose((plus - minus) / (2 * STEP_M), (0, 2, 1))  # columns: d grid / d axis
    if not np.isfinite(jacobian).all():
        raise InputDataError("a position falls outside the target CRS's domain (no finite "
                             "transformation): choose a CRS that covers the block")
    u, _, vt = np.linalg.svd(jacobian)
    return u @ vt


def local_level_function(lon: float, lat: float, h: float, crs) -> Callable:
    """``f(enu) -> grid`` of the east-north-up frame at a geographic point (degrees, metres)."""
    return topocentric_function(lat, lon, h, crs)


def geographic_to_grid(lon, lat, h, crs) -> np.ndarray:
    """Geographic WGS84 (degrees, ellipsoidal height) -> grid xyz, (N, 3)."""
    x, y, z = _geographic_to(crs).transform(np.atleast_1d(lon), np.atleast_1d(lat),
                                            np.atleast_1d(h))
    return np.column_stack([x, y, z])


def grid_to_geographic(xyz: np.ndarray, crs) -> np.ndarray:
    """Grid xyz -> (lon, lat, h), (N, 3)."""
    xyz = np.atleast_2d(np.asarray(xyz, dtype="float64"))
    lon, lat, h = _geographic_to(crs).transform(xyz[:, 0], xyz[:, 1], xyz[:, 2],
                                                direction="INVERSE")
    return np.column_stack([lon, lat, h])


def rpy_to_grid_rotation(roll: float, pitch: float, yaw: float, lon: float, lat: float, h: float,
                         crs, camera_to_body: np.ndarray | None = None) -> np.ndarray:
    """Camera (photogrammetric axes) -> grid rotation from roll, pitch, yaw (radians) of a body
    at (lon, lat, h).

    Body axes x front, y right, z down; navigation axes north, east, down; ``R_nb = Rz(yaw)·
    Ry(pitch)·Rx(roll)`` (aerospace convention, as Pix4D's note and Orthority use). The camera
    (x right, y up, z back) sits in the body as ``camera_to_body`` (default: camera x = body y,
    camera y = body x, camera z = -body z, a nadir camera whose top faces forward).
    """
    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    c_bb = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]], dtype=float) \
        if camera_to_body is None else np.asarray(camera_to_body, dtype=float)
    ned_to_enu = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]], dtype=float)
    camera_to_enu = ned_to_enu @ rz(yaw) @ ry(pitch) @ rx(roll) @ c_bb
    enu_to_grid = frame_to_grid(local_level_function(lon, lat, h, crs), np.zeros(3))[0]
    return enu_to_grid @ camera_to_enu
