"""CRS helpers: every CRS goes through pyproj; mixing CRSs is refused, never silent."""

from __future__ import annotations

import functools
import math
import os
import threading
from pathlib import Path
from typing import Any

import numpy as np
from pyproj import CRS
from pyproj.exceptions import CRSError

from toolbox.errors import InputDataError, ParameterError, ToolboxError


def parse_crs(value: Any, name: str = "CRS") -> CRS:
    """Return the :class:`pyproj.CRS` for ``value`` (``"EPSG:3003"``, ``3003``, WKT, PROJ string).

    Raises :class:`ParameterError` naming ``name`` when PROJ does not know it.
    """
    if isinstance(value, CRS):
        return value
    if hasattr(value, "to_wkt"):  # rasterio CRS
        value = value.to_wkt()
    try:
        return CRS.from_user_input(value)
    except (CRSError, TypeError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else ""
        raise ParameterError(name, f"{value!r} is not a CRS PROJ knows (expected e.g. EPSG:3003, "
                             f"WKT or a PROJ string){': ' + first if first else ''}") from None


@functools.lru_cache(maxsize=64)
def _authority_matches(wkt: str, auth_name: str | None) -> tuple[tuple[str, str, int], ...]:
    """PROJ's identification of the CRS of ``wkt`` in ``auth_name``'s codes (None: every
    authority, slower), ``(authority, code, confidence)`` with confidence >= 70, best first;
    cached by the normalised WKT, so the same CRS read from different files (a GeoJSON's WKT,
    a GeoTIFF's) is identified once, and kept in the user cache (:func:`remembered`): for a
    CRS without a code PROJ searches its whole database, 0.1-0.7 s every run."""
    matches = remembered(f"identify|{auth_name}|{wkt}")
    if matches is None:
        matches = [(m.auth_name, m.code, m.confidence) for m in CRS.from_wkt(wkt)
                   .list_authority(auth_name=auth_name, min_confidence=70)]
        remember(f"identify|{auth_name}|{wkt}", matches)
    return tuple((str(a), str(c), int(n)) for a, c, n in matches)


LOOKUP_CACHE = "proj_lookups.json"  # in toolbox.cache.user_cache_dir()


def _key(question: str) -> str:
    import hashlib

    import pyproj

    return hashlib.sha1(f"{pyproj.proj_version_str}|{question}".encode()).hexdigest()


def remembered(question: str) -> Any:
    """The answer (JSON) PROJ's database gave to ``question`` in an earlier run with this PROJ
    version (:func:`remember`), or None. Searches of the database (identifying a CRS without a
    code, finding a UTM zone) cost 0.1-0.7 s each run, the same answer every time."""
    return _stored_lookups().get(_key(question))


@functools.lru_cache(maxsize=1)
def _stored_lookups() -> dict[str, Any]:
    import json

    from toolbox.cache import user_cache_dir

    try:
        stored = json.loads(user_cache_dir(LOOKUP_CACHE).read_text())
        return stored if isinstance(stored, dict) else {}
    except (OSError, ValueError):
        return {}


def remember(question: str, answer: Any, keep: int = 512) -> None:
    """Keep ``answer`` (JSON-able) to ``question`` in the user cache (written atomically:
    another process may be reading it; the oldest dropped beyond ``keep``); a cache that
    cannot be written is left alone."""
    import json
    import os
    import tempfile

    from toolbox.cache import user_cache_dir

    with _LOOKUP_LOCK:  # (photos planned or reported on threads)
        stored = _stored_lookups()
        stored[_key(question)] = answer
        while len(stored) > keep:
            stored.pop(next(iter(stored)))
        path = user_cache_dir(LOOKUP_CACHE)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False,
                                             suffix=".tmp") as tmp:
                json.dump(stored, tmp)
            os.replace(tmp.name, path)
        except OSError:
            pass


_LOOKUP_LOCK = threading.Lock()


def crs_authority(crs: CRS, min_confidence: int = 90, auth_name: str | None = None
                  ) -> tuple[str, str] | None:
    """As ``crs.to_authority`` (``("EPSG", "3003")`` or None), identified once per CRS (as
    its WKT: a CRS made from a PROJ string matches its EPSG code with more confidence so)."""
    if crs.srs.upper().startswith(f"{auth_name or 'EPSG'}:"):  # made from its code
        auth = crs.to_authority(auth_name, min_confidence)
        if auth is not None:
            return auth
    for name, code, confidence in _authority_matches(crs.to_wkt(), auth_name):
        if confidence >= min_confidence:
            return name, code
    return None


def crs_label(crs: CRS | None) -> str:
    """``EPSG:3003`` when the CRS has an authority code, else its name; a CRS without a code
    nor a name (one made from a PROJ string: its name is "unknown") is shown by its PROJ
    string, so that a message naming two such CRSs tells them apart; ``none`` for None."""
    if crs is None:
        return "none"
    auth = crs_authority(crs)
    if auth:
        return f"{auth[0]}:{auth[1]}"
    if crs.name and crs.name.lower() not in ("unknown", "unnamed", "undefined"):
        return crs.name
    import warnings

    with warnings.catch_warnings():  # "you will likely lose important projection information"
        warnings.simplefilter("ignore")
        try:
            proj = crs.to_proj4()
        except CRSError:
            proj = None
    return f"an unnamed CRS ({proj.replace(' +type=crs', '')})" if proj else "an unnamed CRS"


def _named(crs: CRS) -> str:
    """``crs_label(crs)``, followed by its name when that says more (``EPSG:3003 (Monte Mario
    / Italy zone 1)``)."""
    label = crs_label(crs)
    return label if label.startswith("an unnamed CRS") or label == crs.name \
        else f"{label} ({crs.name})"


def same_crs(a: CRS | None, b: CRS | None) -> bool:
    if a is None or b is None:
        return a is b
    return a == b or a.equals(b, ignore_axis_order=True)


def read_prj(prj: Any, name: str | None = None) -> CRS:
    """The CRS in the ``.prj`` file ``prj`` beside a table (WKT, ESRI WKT, a PROJ string or
    an EPSG code), the one reader of every table's sidecar: its text is UTF-8, else
    Windows-1252 as ESRI software writes an accented name (:func:`toolbox.io.text.read_text`).
    A file that cannot be read or holds no CRS PROJ knows is an :class:`InputDataError`
    naming ``name`` (the parameter of the table it sits beside) when given, the file, the
    start of its text and what was expected."""
    from toolbox.io.text import read_text

    prj = Path(prj)
    text = read_text(prj, name).strip()
    try:
        return CRS.from_user_input(text)
    except (CRSError, TypeError, ValueError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else ""
        shown = text if len(text) <= 60 else text[:57] + "..."
        raise InputDataError(
            f"{name + ': ' if name else ''}{prj}: {shown!r} is not a CRS PROJ knows (expected "
            f"the table's CRS as WKT, ESRI WKT, a PROJ string or an EPSG code)"
            f"{': ' + first if first else ''}") from None


#: how far (metres) a table's points may move between the CRS of its ``.prj`` sidecar and the
#: CRS parameter for the two to be taken as one (an ESRI ``.prj`` rarely equals its EPSG code's
#: definition: :func:`centroid_shift`)
PRJ_TOLERANCE_M = 1e-3


def centroid_shift(source: Any, target: Any, xy: Any) -> tuple[float, tuple[float, float]]:
    """How far (metres, on ``target``'s ellipsoid) the centroid of the points ``xy`` ((n, 2),
    NaN rows left out) moves when transformed from ``source``'s horizontal CRS to
    ``target``'s (pyproj), and the centroid: 0 for two definitions of one CRS (an ESRI WKT and
    its EPSG code), the datum shift for another datum; infinite where the transformation
    fails; ``(0.0, (nan, nan))`` without points. The definitions are not compared."""
    xy = np.asarray(xy, dtype="float64").reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(axis=1)]
    if not len(xy):
        return 0.0, (math.nan, math.nan)
    x, y = (float(v) for v in xy.mean(axis=0))
    return float(_moves(source, target, np.array([x]), np.array([y]))[0]), (x, y)


def _moves(source: Any, target: Any, x: Any, y: Any) -> np.ndarray:
    """How far (metres, on ``target``'s ellipsoid) each point (``x``, ``y``: arrays in
    ``source``'s horizontal CRS) moves from ``source`` to ``target``; infinite where the
    transformation fails."""
    source, target = horizontal_part(source), horizontal_part(target)
    forward, geodetic, geod = _movers(source.to_wkt(), target.to_wkt())
    x, y = np.asarray(x, dtype="float64"), np.asarray(y, dtype="float64")
    mx, my = forward.transform(x, y)
    lon, lat = geodetic.transform(np.concatenate([x, mx]), np.concatenate([y, my]))
    n = len(x)
    with np.errstate(invalid="ignore"):
        distance = np.asarray(geod.inv(lon[:n], lat[:n], lon[n:], lat[n:])[2], dtype="float64")
    ok = np.isfinite(lon[:n]) & np.isfinite(lat[:n]) & np.isfinite(lon[n:]) \
        & np.isfinite(lat[n:]) & np.isfinite(distance)
    return np.where(ok, distance, math.inf)


@functools.lru_cache(maxsize=32)
def _movers(source_wkt: str, target_wkt: str) -> tuple[Any, Any, Any]:
    """(source -> target, target -> its geographic CRS, the target's ellipsoid) for
    :func:`_moves`, cached (creating a transformer costs ~10-100 ms)."""
    from pyproj import Geod, Transformer

    source, target = CRS.from_wkt(source_wkt), CRS.from_wkt(target_wkt)
    ellipsoid = target.ellipsoid
    geod = Geod(a=ellipsoid.semi_major_metre, rf=ellipsoid.inverse_flattening) \
        if ellipsoid is not None else Geod(ellps="WGS84")
    return (Transformer.from_crs(source, target, always_xy=True),
            Transformer.from_crs(target, target.geodetic_crs, always_xy=True), geod)


def extent_shift(source: Any, target: Any, bounds: Any = None
                 ) -> tuple[float, tuple[float, float]]:
    """How far (metres, on ``target``'s ellipsoid) the data's extent moves from ``source``'s
    horizontal CRS to ``target``'s: the largest move of its centre and four corners
    (``bounds``: xmin, ymin, xmax, ymax in ``source``), and the point that moves most. Without
    bounds (or with bounds that are not finite), the area of use of either CRS stands for the
    extent (its centre and corners, taken in ``source``'s geographic CRS). 0 for two
    definitions of one CRS (an ESRI WKT and its EPSG code), the datum shift for another
    datum; infinite where the transformation fails; NaN where no place is known (a CRS
    without an area of use, no bounds)."""
    source, target = horizontal_part(source), horizontal_part(target)
    points = _extent_points(source, target, bounds)
    if points is None:
        return math.nan, (math.nan, math.nan)
    x, y = points
    try:
        moved = _moves(source, target, x, y)
    except Exception:  # noqa: BLE001 - no operation between them: no common place
        return math.inf, (float(x[0]), float(y[0]))
    k = int(np.argmax(moved))
    return float(moved[k]), (float(x[k]), float(y[k]))


def _extent_points(source: CRS, target: CRS, bounds: Any) -> tuple[Any, Any] | None:
    """(x, y) arrays in ``source``: the centre and corners of ``bounds``, else of the area of
    use (:func:`extent_shift`), or None."""
    if bounds is not None:
        b = [float(v) for v in bounds]
        if len(b) == 4 and all(math.isfinite(v) for v in b):
            xs, ys = sorted((b[0], b[2])), sorted((b[1], b[3]))
            return (np.array([(xs[0] + xs[1]) / 2, xs[0], xs[1], xs[0], xs[1]]),
                    np.array([(ys[0] + ys[1]) / 2, ys[0], ys[0], ys[1], ys[1]]))
    area = None
    for crs in (source, target):
        area = crs.area_of_use or _area_of_use_by_code(crs)
        if area is not None:
            break
    if area is None or area.east < area.west:  # across the antimeridian: not sampled
        return None
    lon = np.array([(area.west + area.east) / 2, area.west, area.east, area.west, area.east])
    lat = np.array([(area.south + area.north) / 2, area.south, area.south, area.north,
                    area.north])
    if source.is_geographic:
        return lon, lat
    from pyproj import Transformer

    x, y = Transformer.from_crs(source.geodetic_crs, source, always_xy=True).transform(lon, lat)
    keep = np.isfinite(x) & np.isfinite(y)
    return (np.asarray(x)[keep], np.asarray(y)[keep]) if keep.any() else None


def one_crs(a: Any, b: Any, bounds: Any = None) -> bool:
    """Whether data in ``a`` may be taken as in ``b`` as they are (no transformation): the
    same definition (:func:`same_crs`, the fast path), or two definitions of one CRS (an ESRI
    WKT, as GDAL labels a raster or layer, and its EPSG code): the data's extent
    (``bounds``, in ``a``; :func:`extent_shift`) moves by at most :data:`PRJ_TOLERANCE_M` from
    one to the other, and both state the same height datum or neither does. A CRS missing on
    one side only is not the other's here (the callers decide)."""
    if a is None or b is None:
        return a is b
    a, b = parse_crs(a), parse_crs(b)
    if same_crs(a, b):
        return True
    ours, theirs = vertical_part(a), vertical_part(b)
    if (ours is None) != (theirs is None) or (
            ours is not None and not same_datum(ours, theirs)):
        return False
    return one_horizontal_crs(a, b, bounds)


@functools.lru_cache(maxsize=128)
def one_crs_of_wkt(a: str, b: str, bounds: tuple | None = None) -> bool:
    """:func:`one_crs` of two CRSs given as WKT, once per pair and extent (asked for every
    tile a raster engine reads)."""
    return a == b or one_crs(a, b, bounds)


def one_horizontal_crs(a: Any, b: Any, bounds: Any = None) -> bool:
    """:func:`one_crs` of the horizontal parts of ``a`` and ``b`` (height datums not looked
    at: a vertical datum moves no cell). Besides the extent's move, PROJ's operation from one
    to the other must be conversions only (one datum): a null or ballpark datum transformation
    (WGS 84 to RDN2008, "1 m"; ETRS89 to RDN2008; an unknown datum to any) moves no point
    either, but those are two CRSs, not two definitions of one: refused or transformed as
    before."""
    if a is None or b is None:
        return a is b
    a, b = horizontal_part(a), horizontal_part(b)
    return same_crs(a, b) or (extent_shift(a, b, bounds)[0] <= PRJ_TOLERANCE_M
                              and _conversions_only(a.to_wkt(), b.to_wkt()))


@functools.lru_cache(maxsize=32)
def _conversions_only(source_wkt: str, target_wkt: str) -> bool:
    """Whether PROJ goes from ``source`` to ``target`` by conversions only (no datum
    transformation step; one operation, not a choice among several by area)."""
    try:
        operation = _movers(source_wkt, target_wkt)[0].to_json_dict()
    except Exception:  # noqa: BLE001 - several candidate operations: datums differ
        return False

    def kinds(step: dict) -> list[str]:
        return [str(step.get("type"))] + [k for s in step.get("steps", []) for k in kinds(s)]

    return set(kinds(operation)) <= {"Conversion", "ConcatenatedOperation"}


def shift_phrase(shift: float, centre: tuple[float, float]) -> str:
    """:func:`centroid_shift`'s answer in words, for a message refusing a ``.prj``."""
    moved_by = f"{shift:.3f} m" if math.isfinite(shift) else \
        "an undefined distance (the transformation fails there)"
    return f"its points (centroid {centre[0]:.3f}, {centre[1]:.3f}) move by {moved_by} from " \
        "one to the other"


def check_one_crs(key: str, crs: Any, ref_name: str, reference: Any, xy: Any,
                  advice: str = "give the inputs in one CRS") -> float:
    """``key``'s positions ``xy`` (in ``crs``) taken as ``ref_name``'s (in ``reference``): one
    CRS when their centroid moves by at most :data:`PRJ_TOLERANCE_M` from one to the other
    (:func:`centroid_shift`: two definitions of one CRS, an ESRI WKT and its EPSG code, are
    not equal but move no point), else an :class:`InputDataError` naming both and the shift;
    two different height datums stated one on each side are refused too
    (:func:`check_same_heights`). Without positions the CRSs' area of use stands for them
    (:func:`one_horizontal_crs`). The shift (0 without positions)."""
    crs, reference = parse_crs(crs), parse_crs(reference)
    finite = np.asarray(xy, dtype="float64").reshape(-1, 2)
    if not np.isfinite(finite).all(axis=1).any():
        if not one_horizontal_crs(crs, reference):  # the CRSs' area of use stands for them
            raise InputDataError(f"{key} is in {crs_label(crs)} but {ref_name} is in "
                                 f"{crs_label(reference)}: {advice}")
        check_same_heights(key, crs, ref_name, reference)
        return 0.0
    shift, centre = centroid_shift(crs, reference, finite)
    if not shift <= PRJ_TOLERANCE_M:
        raise InputDataError(f"{key} is in {crs_label(crs)} but {ref_name} is in "
                             f"{crs_label(reference)}: {shift_phrase(shift, centre)}; {advice}")
    check_same_heights(key, crs, ref_name, reference)
    return shift


def common_crs(named: dict[str, CRS | None], override: CRS | None = None,
               bounds: dict[str, Any] | None = None) -> CRS | None:
    """The one CRS shared by the named inputs (``{"INPUT": crs, ...}``).

    Inputs without a CRS (e.g. CSV) take ``override`` or the others' CRS. With ``override`` given,
    inputs that do have a CRS must match it. Different CRSs raise :class:`InputDataError`.
    Two definitions of one CRS (an ESRI WKT and its EPSG code) are one (:func:`one_crs`: the
    input's extent, ``bounds[name]`` in its own CRS, else the CRSs' area of use, moves by at
    most :data:`PRJ_TOLERANCE_M` from one to the other); the first CRS (or ``override``) is
    returned.
    """
    known = {k: c for k, c in named.items() if c is not None}
    bounds = bounds or {}
    reference = override
    ref_name = "CRS"
    for key, crs in known.items():
        if reference is None:
            reference, ref_name = crs, key
        elif not one_crs(crs, reference, bounds.get(key)):
            _heights_only(key, crs, ref_name, reference, bounds.get(key))
    return reference


def _heights_only(key: str, crs: CRS, ref_name: str, reference: CRS, bounds: Any = None
                  ) -> None:
    """Two CRSs that differ: another horizontal CRS (:func:`one_horizontal_crs` on ``key``'s
    extent ``bounds``), or two different height datums, is an
    :class:`InputDataError` saying which; the same horizontal CRS with a height datum stated
    on one side only (``EPSG:3003+5214`` and ``EPSG:3003``) is taken as one, with a warning
    (the "toolbox" logger's: the console and the run report show it)."""
    if not one_horizontal_crs(crs, reference, bounds):
        raise InputDataError(f"{key} is in {crs_label(crs)} but {ref_name} is in "
                             f"{crs_label(reference)}; reproject the inputs to one CRS first")
    ours, theirs = vertical_part(reference), vertical_part(crs)
    check_same_heights(key, crs, ref_name, reference)
    import logging

    logging.getLogger("toolbox").warning(
        f"{key}'s heights are {datum_label(theirs)}, {ref_name}'s {datum_label(ours)} (the same "
        f"horizontal CRS): taken as the same height datum, in {crs_label(reference)}")


def check_same_heights(key: str, crs: CRS | None, ref_name: str, reference: CRS | None) -> None:
    """Heights of ``key`` (in ``crs``) used as ``ref_name``'s (in ``reference``): two height
    datums stated, one on each side, that differ are an :class:`InputDataError` (the heights
    would be relabelled, not converted); a datum stated on one side only passes."""
    ours = None if reference is None else vertical_part(reference)
    theirs = None if crs is None else vertical_part(crs)
    if ours is not None and theirs is not None and not same_datum(ours, theirs):
        raise InputDataError(f"{key}'s heights are {datum_label(theirs)} but {ref_name}'s are "
                             f"{datum_label(ours)}: convert them to one height datum first")


def extent_bounds_in(extent: Any, crs: Any, name: str = "EXTENT") -> tuple[float, ...]:
    """The bounds of ``extent`` (an object with ``.bounds`` and ``.crs``, e.g. a parameter's
    :class:`toolbox.parameters.Extent`) in ``crs``: as given when it names no CRS or the same
    one; else the bounding box of the rectangle transformed into ``crs`` (its edges densified,
    as QGIS converts an extent drawn on a canvas in another CRS and ``gdalwarp -te_srs`` does),
    logged as a warning naming ``name`` and the bounds taken."""
    bounds = tuple(float(v) for v in extent.bounds)
    own = getattr(extent, "crs", None)
    if own is None or crs is None or one_crs(own, crs, bounds):
        return bounds
    import logging

    from pyproj import Transformer

    box = Transformer.from_crs(own, crs, always_xy=True).transform_bounds(*bounds,
                                                                        densify_pts=21)
    if not all(math.isfinite(v) for v in box) or not (box[2] > box[0] and box[3] > box[1]):
        raise InputDataError(f"{name} {bounds} in {crs_label(own)} does not convert to "
                             f"{crs_label(crs)}: give it in {crs_label(crs)}")
    logging.getLogger("toolbox").warning(
        f"{name} is in {crs_label(own)}: taken as its bounding box in {crs_label(crs)}, "
        f"{box[0]:.3f},{box[1]:.3f},{box[2]:.3f},{box[3]:.3f}")
    return tuple(float(v) for v in box)


# -- CRS sanity of the inputs (called by the runner for every CRS-bearing input) ---------------
AREA_MARGIN_DEG = 1.0  # outside the area of use by less than this (or 10 % of it): accepted
AREA_ERROR_DEG = 5.0  # outside by more than this: certainly the wrong CRS (or lon/lat numbers)


def input_crs_and_bounds(value: Any) -> list[tuple[CRS | None, tuple | None]]:
    """``(crs, bounds)`` pairs of a parameter value: layer references, raster infos, extents,
    CRSs and lists of them; bounds are ``(xmin, ymin, xmax, ymax)`` or ``None``."""
    if isinstance(value, (list, tuple)):
        return [pair for item in value for pair in input_crs_and_bounds(item)]
    if isinstance(value, CRS):
        return [(value, None)]
    if value is None or not hasattr(value, "crs"):
        return []
    try:
        crs = value.crs
        crs = None if crs is None else parse_crs(crs)
    except (ToolboxError, CRSError, ValueError, TypeError):
        return []
    bounds = None
    info = getattr(value, "info", None)
    if isinstance(info, dict) and info.get("total_bounds") is not None:
        bounds = tuple(float(b) for b in info["total_bounds"])
    elif getattr(value, "georeferenced", True) and hasattr(value, "bounds"):
        bounds = tuple(float(b) for b in value.bounds)
    if bounds is not None and not all(np.isfinite(bounds)):
        bounds = None
    return [(crs, bounds)]


def check_input_crs(algorithm_id: str, name: str, value: Any,
                    warnings: list[str] | None = None, units: str = "metre") -> None:
    """Refuse a geographic CRS or one not in metres with x east, y north (:func:`not_metric`:
    the algorithm works in metres) and coordinates far outside the CRS's area of use; append a
    warning to ``warnings`` when they are a little outside."""
    for crs, bounds in input_crs_and_bounds(value):
        if crs is None:
            continue
        if crs.is_geographic:
            raise ParameterError(name, f"is in the geographic CRS {crs_label(crs)} ({crs.name}, "
                                 f"degrees), but {algorithm_id} works in metres (cell sizes, "
                                 "tolerances, slopes, volumes): reproject it to a projected CRS "
                                 "(e.g. EPSG:3003 or a UTM zone) first")
        problem = not_metric(crs, units)
        if problem:
            works = "in metres" if units == "metre" else "in one length unit"
            raise ParameterError(name, f"is in {_named(crs)}, {problem}, but "
                                 f"{algorithm_id} works {works}, x east and y north (cell "
                                 "sizes, tolerances, scales, heights): reproject it to a metric "
                                 "CRS (e.g. a UTM zone, heights in metres) first")
        if bounds is not None:
            problem, far = outside_area_of_use(crs, bounds)
            if problem and far:
                raise InputDataError(f"{name}: {problem}: is the CRS right? Label the data with "
                                     "its true CRS, then reproject if needed")
            if problem and warnings is not None:
                warnings.append(f"{name}: {problem}")


def not_metric(crs: CRS, units: str = "metre") -> str | None:
    """Why ``crs`` does not suit an algorithm whose lengths are in ``units``, or None. Always
    refused: a geocentric CRS, axes pointing west or south. ``units``: "metre" (every axis in
    metres, a compound CRS's height too), "one" (every axis in one unit, e.g. feet),
    "horizontal" (x and y in one unit; heights in any). Axes of an unknown unit pass."""
    if crs.is_geocentric:
        return "a geocentric CRS (Earth-centred X, Y, Z)"
    axes = [a for a in crs.axis_info
            if a.unit_name not in ("", "unknown") and a.unit_conversion_factor > 0]
    for axis in axes:
        if axis.direction in ("west", "south"):
            return f"whose {axis.name.lower()} axis points {axis.direction}"
        if units == "metre":
            if abs(axis.unit_conversion_factor - 1.0) > 1e-12:
                return f"whose {axis.name.lower()} unit is the {axis.unit_name}"
        elif (units == "one" or axis.direction in ("east", "north")) and abs(
                axis.unit_conversion_factor - axes[0].unit_conversion_factor) > 1e-12:
            return (f"whose {axis.name.lower()} unit ({axis.unit_name}) is not its "
                    f"{axes[0].name.lower()} unit ({axes[0].unit_name})")
    return None


def warn_unlabelled_elsewhere(inputs: dict[str, Any], warnings: list[str] | None) -> None:
    """An input without a CRS is taken to be in the other inputs' CRS; when its extent lies
    away from theirs it is most likely in another CRS (numbers of another projection): append a
    warning naming it to ``warnings`` (its features would otherwise fall outside in silence)."""
    spatial = {name: value for name, value in inputs.items()
               if value is not None and (hasattr(value, "crs") or isinstance(value, list))}
    if warnings is None or len(spatial) < 2:  # one input: nothing to compare (no pyproj load)
        return
    pairs = {name: input_crs_and_bounds(value) for name, value in spatial.items()}
    labelled = [(crs, b) for found in pairs.values() for crs, b in found
                if crs is not None and b is not None]
    if not labelled:
        return
    crs = labelled[0][0]
    boxes = [b for c, b in labelled if one_crs(c, crs, b)]
    box = (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes),
           max(b[3] for b in boxes))
    margin = 0.1 * max(box[2] - box[0], box[3] - box[1], 1.0)
    for name, found in pairs.items():
        for own, b in found:
            if own is not None or b is None:
                continue
            if b[0] > box[2] + margin or b[2] < box[0] - margin or b[1] > box[3] + margin \
                    or b[3] < box[1] - margin:
                warnings.append(f"{name} has no CRS and lies away from the other inputs "
                                f"({b[0]:.0f}..{b[2]:.0f}, {b[1]:.0f}..{b[3]:.0f} against "
                                f"{box[0]:.0f}..{box[2]:.0f}, {box[1]:.0f}..{box[3]:.0f} in "
                                f"{crs_label(crs)}): it is taken to be in {crs_label(crs)}; if "
                                "its coordinates are of another CRS, label it with that CRS")


def check_unlabelled_in_area(inputs: dict[str, Any], crs: CRS,
                             warnings: list[str] | None) -> None:
    """The inputs without a CRS are taken to be in ``crs`` (the CRS parameter): their extent
    far outside its area of use is an :class:`InputDataError` naming the input (numbers of
    another CRS, e.g. UTM eastings labelled Monte Mario), a little outside a warning, as
    :func:`check_input_crs` judges the inputs that name their CRS."""
    for name, value in inputs.items():
        if name == "CRS":
            continue
        for own, bounds in input_crs_and_bounds(value):
            if own is not None or bounds is None:
                continue
            problem, far = outside_area_of_use(crs, bounds)
            if problem and far:
                raise InputDataError(f"{name} has no CRS and is taken to be in CRS "
                                     f"{crs_label(crs)}, but {problem}: is CRS right? Give its "
                                     "coordinates' CRS")
            if problem and warnings is not None:
                warnings.append(f"{name} (no CRS, taken to be in CRS {crs_label(crs)}): "
                                f"{problem}")


def unlabelled_raster(name: str, bounds: Any, crs: Any, crs_name: str, xy: Any,
                      points_name: str, warn: Any = None) -> None:
    """A raster ``name`` without a CRS, used with points ``xy`` ((n, 2)) in ``crs`` (the
    project's, called ``crs_name``): taken to be in ``crs``, with a warning (``warn(text)``),
    when its grid (``bounds``: left, bottom, right, top, in any order) holds at least one of the
    points; none of them on it (a grid in pixels, another CRS's numbers) is an
    :class:`InputDataError` naming ``name``: nothing would be measured on it."""
    xy = np.asarray(xy, dtype="float64").reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(axis=1)]
    left, right = sorted((float(bounds[0]), float(bounds[2])))
    bottom, top = sorted((float(bounds[1]), float(bounds[3])))
    inside = int(((xy[:, 0] >= left) & (xy[:, 0] <= right) & (xy[:, 1] >= bottom)
                  & (xy[:, 1] <= top)).sum())
    grid = f"{left:.0f}..{right:.0f}, {bottom:.0f}..{top:.0f}"
    if not inside:
        where = "" if not len(xy) else (
            f" ({xy[:, 0].min():.0f}..{xy[:, 0].max():.0f}, "
            f"{xy[:, 1].min():.0f}..{xy[:, 1].max():.0f})")
        raise InputDataError(f"{name} has no CRS and its grid ({grid}) holds none of the "
                             f"{len(xy)} {points_name} points{where}: it is not in {crs_name}'s CRS "
                             f"({crs_label(crs)}); label it with its CRS (or georeference it)")
    if warn is not None:
        warn(f"{name} has no CRS: taken to be in {crs_name}'s CRS ({crs_label(crs)}), its grid "
             f"({grid}) holding {inside} of the {len(xy)} {points_name} points; label it to "
             "be sure")


def check_coordinates_in_area(name: str, crs: Any, xy: Any, warn: Any = None) -> None:
    """Coordinates ``xy`` ((n, 2), in ``crs``) read from a table rather than a layer: far
    outside the CRS's area of use is an :class:`InputDataError` naming ``name``, a little
    outside a warning (``warn(text)``), as :func:`check_input_crs` does for layers."""
    xy = np.asarray(xy, dtype="float64")
    xy = xy[np.isfinite(xy).all(axis=1)]
    crs = parse_crs(crs, name)
    if not len(xy) or crs.is_geographic:
        return
    bounds = (xy[:, 0].min(), xy[:, 1].min(), xy[:, 0].max(), xy[:, 1].max())
    problem, far = outside_area_of_use(crs, bounds)
    if problem and far:
        raise InputDataError(f"{name}: {problem}: is the CRS right? Label the data with its "
                             "true CRS, then reproject if needed")
    if problem and warn is not None:
        warn(f"{name}: {problem}")


def _area_of_use_by_code(crs: CRS):
    """The area of use of the EPSG CRS ``crs`` matches (a GeoTIFF's CRS read back as WKT has
    lost it), or None."""
    try:
        match = crs_authority(crs, 70, "EPSG")
        return None if match is None else _epsg_area_of_use(int(match[1]))
    except Exception:  # noqa: BLE001 - no match: not judged
        return None


@functools.lru_cache(maxsize=32)
def _epsg_area_of_use(code: int):
    return CRS.from_epsg(code).area_of_use


@functools.lru_cache(maxsize=32)
def _to_lonlat(wkt: str):
    """A cached transformer to WGS 84 lon/lat (creating one costs ~0.1 s)."""
    from pyproj import Transformer

    return Transformer.from_crs(CRS.from_wkt(wkt), CRS.from_epsg(4326), always_xy=True)


def outside_area_of_use(crs: CRS, bounds: tuple) -> tuple[str | None, bool]:
    """``(message, far)``: a message when ``bounds`` (in ``crs``) lie outside the CRS's area of
    use by more than a margin; ``far`` when by more than :data:`AREA_ERROR_DEG` degrees."""
    horizontal = crs.sub_crs_list[0] if crs.is_compound and crs.sub_crs_list else crs
    area = crs.area_of_use or horizontal.area_of_use or _area_of_use_by_code(horizontal)
    if area is None or crs.is_geographic:
        return None, False
    xmin, ymin, xmax, ymax = bounds
    shown = f"coordinates {xmin:.6g}..{xmax:.6g}, {ymin:.6g}..{ymax:.6g}"
    where = (f"the area of use of {crs_label(crs)} ({area.west:g}..{area.east:g} E, "
             f"{area.south:g}..{area.north:g} N)")
    try:
        to_lonlat = _to_lonlat(crs.to_wkt())
        lon0, lat0, lon1, lat1 = to_lonlat.transform_bounds(xmin, ymin, xmax, ymax, densify_pts=5)
    except Exception:  # PROJ cannot place them on the ellipsoid at all
        return f"{shown} cannot be coordinates of {crs_label(crs)}", True
    if not all(np.isfinite([lon0, lat0, lon1, lat1])):
        return f"{shown} cannot be coordinates of {crs_label(crs)}", True
    west, east = area.west, area.east
    if east < west:  # crosses the antimeridian: not judged
        return None, False
    margin_x = max(AREA_MARGIN_DEG, 0.1 * (east - west))
    margin_y = max(AREA_MARGIN_DEG, 0.1 * (area.north - area.south))
    dx = max(west - lon1, lon0 - east, 0.0)
    dy = max(area.south - lat1, lat0 - area.north, 0.0)
    if dx <= margin_x and dy <= margin_y:
        return None, False
    off = max(dx, dy)
    return (f"{shown} lie {off:.3g} degrees outside {where}", off > AREA_ERROR_DEG)


# -- the datum transformation PROJ applies between two CRSs -------------------------------------
@functools.lru_cache(maxsize=32)
def _transformation(source_wkt: str, target_wkt: str, x: float, y: float
                    ) -> tuple[str, float | None, tuple[tuple[str, float, tuple[str, ...]], ...]]:
    """(description, accuracy in metres or None when PROJ knows none, better operations that
    need missing grids ``(name, accuracy, grids)``) of the operation PROJ uses at (x, y) of the
    source CRS: the one every reprojection here (pyproj, GDAL's warper, GeoPandas) applies."""
    import warnings

    from pyproj import Transformer
    from pyproj.transformer import TransformerGroup

    use_system_grids()  # a system PROJ's grids (e.g. /usr/share/proj) count as installed
    source, target = CRS.from_wkt(source_wkt), CRS.from_wkt(target_wkt)
    transformer = Transformer.from_crs(source, target, always_xy=True)
    description, accuracy = transformer.description, transformer.accuracy
    if math.isfinite(x) and math.isfinite(y):
        try:
            transformer.transform(x, y, errcheck=True)
            used = transformer.get_last_used_operation()
            description, accuracy = used.description, used.accuracy
        except Exception:  # noqa: BLE001 - a single operation (no choice), or out of its area
            pass
    known = None if accuracy is None or accuracy < 0 or "ballpark" in description.lower() \
        else float(accuracy)
    better = []
    try:
        with warnings.catch_warnings():  # "best transformation is not available": said below
            warnings.simplefilter("ignore", UserWarning)
            group = TransformerGroup(source, target, always_xy=True)
        for op in group.unavailable_operations:
            grids = tuple(sorted({g.short_name for g in op.grids if not g.available}))
            if grids and op.accuracy is not None and op.accuracy >= 0 and (
                    known is None or op.accuracy < known):
                better.append((op.name, float(op.accuracy), grids))
    except Exception:  # noqa: BLE001 - no list of operations: nothing better to name
        pass
    return description, known, tuple(sorted(better, key=lambda b: b[1]))


def transformation_check(source: Any, target: Any, bounds: Any = None,
                         cell_size: float | None = None, what: str = "data",
                         tolerance_of: str = "the output cell"
                         ) -> tuple[dict[str, Any] | None, str | None]:
    """The datum transformation used to bring ``what`` from ``source`` to ``target`` (CRSs),
    judged: ``(record for the report, warning text or None)``; ``(None, None)`` when the CRSs
    are the same or either is unknown. ``bounds`` (in ``source``): where it is applied (PROJ
    chooses by area). Warned: a transformation of unknown accuracy (a "ballpark" one that
    ignores the datum shift: tens to hundreds of metres off), one whose accuracy is coarser
    than ``cell_size`` (metres, the output's cell, or the tolerance ``tolerance_of`` names),
    and a better one that needs a PROJ grid
    not installed here (e.g. Monte Mario -> RDN2008 by the IGM grid: 0.1 m instead of 4 m)."""
    if source is None or target is None:
        return None, None
    source, target = parse_crs(source), parse_crs(target)
    if same_crs(source, target):
        return None, None
    x = y = math.nan
    if bounds is not None and all(math.isfinite(float(b)) for b in bounds):
        # the centre, to 10 km (0.1 degree): one look-up per area
        x, y = (float(bounds[0]) + float(bounds[2])) / 2, (float(bounds[1]) + float(bounds[3])) / 2
        step = 0.1 if source.is_geographic else 1e4
        x, y = round(x / step) * step, round(y / step) * step
    description, accuracy, better = _transformation(source.to_wkt(), target.to_wkt(), x, y)
    record: dict[str, Any] = {"from": crs_label(source), "to": crs_label(target),
                              "operation": description, "accuracy_m": accuracy}
    problems = []
    if accuracy is None:
        problems.append("its accuracy is unknown (a ballpark transformation ignores the datum "
                        "shift: positions may be off by tens to hundreds of metres)")
    elif cell_size is not None and accuracy > float(cell_size):
        problems.append(f"its accuracy ({accuracy:g} m) is coarser than {tolerance_of} "
                        f"({float(cell_size):g} m)")
    if better:
        name, best, grids = better[0]
        record["better_operation"] = {"operation": name, "accuracy_m": best,
                                      "missing_grids": list(grids)}
        problems.append(f"'{name}' ({best:g} m) needs the PROJ grid {', '.join(grids)}, not "
                        f"installed here (projsync --file {grids[0]}, or copy it into PROJ_DATA "
                        "or /usr/share/proj)")
    if not problems:
        return record, None
    return record, (f"{what} transformed from {record['from']} to {record['to']} by "
                    f"'{description}': " + "; ".join(problems))


def note_transformation(feedback: Any, source: Any, target: Any, bounds: Any = None,
                        cell_size: float | None = None, what: str = "data",
                        tolerance_of: str = "the output cell") -> dict[str, Any] | None:
    """:func:`transformation_check`, its warning pushed to ``feedback`` (once per text; no
    feedback: the "toolbox" logger's, which the runner reports); the record (for the run
    report) returned, None when no transformation is made."""
    record, text = transformation_check(source, target, bounds, cell_size, what, tolerance_of)
    if text is None:
        return record
    if feedback is None:
        import logging

        logging.getLogger("toolbox").warning(text)
    elif ("warning", text) not in getattr(feedback, "messages", []):
        feedback.push_warning(text)
    return record


# -- height datums (compound CRSs) ------------------------------------------------------------
ELLIPSOIDAL = "ellipsoidal"
#: folders holding PROJ grids besides pyproj's own (a system PROJ's data: egm96_15.gtx...)
SYSTEM_GRID_DIRS = ("/usr/share/proj", "/usr/local/share/proj")


def vertical_part(crs: Any) -> Any:
    """The vertical part of a CRS: a vertical pyproj CRS (compound CRS), :data:`ELLIPSOIDAL`
    (a 3D geographic or projected CRS) or None (a 2D CRS names no height datum)."""
    if crs is None:
        return None
    crs = parse_crs(crs)
    if crs.is_compound:
        vertical = [c for c in crs.sub_crs_list if c.is_vertical]
        return vertical[0] if vertical else None
    if crs.is_vertical:
        return crs
    if len(crs.axis_info) == 3 and "ellipsoidal" in crs.axis_info[2].name.lower():
        return ELLIPSOIDAL
    return None


def is_ellipsoidal(vertical: Any) -> bool:
    """Whether :func:`vertical_part`'s answer is :data:`ELLIPSOIDAL` (a pyproj CRS compared
    with a string parses it as a CRS: a PROJ database search of 0.2-0.4 s CPU, for False)."""
    return isinstance(vertical, str) and vertical == ELLIPSOIDAL


def horizontal_part(crs: Any) -> Any:
    crs = parse_crs(crs)
    if crs.is_compound:
        return crs.sub_crs_list[0]
    if len(crs.axis_info) == 3:
        return crs.to_2d()
    return crs


def datum_label(vertical: Any) -> str:
    if vertical is None:
        return "not stated"
    if is_ellipsoidal(vertical):
        return "ellipsoidal heights"
    label = crs_label(vertical)
    return vertical.name if label == vertical.name else f"{vertical.name} ({label})"


def same_datum(a: Any, b: Any) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return same_crs(a, b) or (a.datum is not None and b.datum is not None
                              and a.datum.name == b.datum.name)


def use_system_grids() -> None:
    """Let pyproj find the PROJ grids of a system PROJ (its wheel ships none)."""
    import pyproj.datadir

    known = os.pathsep.join([pyproj.datadir.get_data_dir(), os.environ.get("PROJ_DATA", "")])
    for folder in SYSTEM_GRID_DIRS:
        if os.path.isdir(folder) and folder not in known:
            pyproj.datadir.append_data_dir(folder)
