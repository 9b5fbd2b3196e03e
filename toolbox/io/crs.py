"""CRS helpers: every CRS goes through pyproj; mixing CRSs is refused, never silent."""

from __future__ import annotations

from typing import Any

from pyproj import CRS
from pyproj.exceptions import CRSError

from toolbox.errors import InputDataError, ParameterError


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


def crs_label(crs: CRS | None) -> str:
    """``EPSG:3003`` when the CRS has an authority code, else its name; ``none`` for None."""
    if crs is None:
        return "none"
    auth = crs.to_authority(min_confidence=90)
    return f"{auth[0]}:{auth[1]}" if auth else crs.name


def same_crs(a: CRS | None, b: CRS | None) -> bool:
    if a is None or b is None:
        return a is b
    return a == b or a.equals(b, ignore_axis_order=True)


def common_crs(named: dict[str, CRS | None], override: CRS | None = None) -> CRS | None:
    """The one CRS shared by the named inputs (``{"INPUT": crs, ...}``).

    Inputs without a CRS (e.g. CSV) take ``override`` or the others' CRS. With ``override`` given,
    inputs that do have a CRS must match it. Different CRSs raise :class:`InputDataError`.
    """
    known = {k: c for k, c in named.items() if c is not None}
    reference = override
    ref_name = "CRS"
    for key, crs in known.items():
        if reference is None:
            reference, ref_name = crs, key
        elif not same_crs(reference, crs):
            raise InputDataError(f"{key} is in {crs_label(crs)} but {ref_name} is in "
                                 f"{crs_label(reference)}; reproject the inputs to one CRS first")
    return reference
