"""The date outputs record: ``SOURCE_DATE_EPOCH`` when set (the reproducible-builds convention,
https://reproducible-builds.org/specs/source-date-epoch/: a whole number of seconds since
1970-01-01 00:00 UTC), else now. Two runs with the same inputs and the same ``SOURCE_DATE_EPOCH``
write byte-identical files: a PDF's ``CreationDate`` (matplotlib reads the variable itself), a
map sheet's printed date, a GeoPackage's ``gpkg_contents.last_change`` (GDAL's
``OGR_CURRENT_DATE``, set by :func:`source_date_for_gdal`) and ``layer_styles.update_time``."""

from __future__ import annotations

import datetime as dt
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from toolbox.errors import ParameterError

VARIABLE = "SOURCE_DATE_EPOCH"


def source_date() -> dt.datetime | None:
    """``SOURCE_DATE_EPOCH`` as an aware UTC datetime, None when unset or empty; a value that is
    not a whole number of seconds from 1970 to 9999 is refused (ParameterError, exit 2)."""
    text = os.environ.get(VARIABLE, "").strip()
    if not text:
        return None
    try:
        if not text.isdigit():
            raise ValueError(text)
        return dt.datetime.fromtimestamp(int(text), dt.UTC)
    except (ValueError, OverflowError, OSError):
        raise ParameterError(VARIABLE, f"(environment variable) is {text!r}, expected a whole "
                             "number of seconds since 1970-01-01 00:00 UTC (e.g. the "
                             "output of 'date +%s'), or unset") from None


def today() -> dt.date:
    """The date an output prints: ``SOURCE_DATE_EPOCH``'s (UTC) when set, else today's."""
    when = source_date()
    return dt.date.today() if when is None else when.date()


def gpkg_timestamp() -> str | None:
    """``SOURCE_DATE_EPOCH`` as a GeoPackage timestamp (``2023-11-14T22:13:20.000Z``), or None
    (then the current time is written)."""
    when = source_date()
    return None if when is None else when.strftime("%Y-%m-%dT%H:%M:%S.000Z")


_LOCK = threading.Lock()
_PUSHED: dict[str, dict] = {}  # variable -> {"original": its value before, "values": [...]}


@contextmanager
def _pushed(name: str, value: str) -> Iterator[None]:
    """``os.environ[name] = value`` within the block; blocks may overlap (tasks in threads):
    the variable's value from before the first comes back when the last one ends."""
    with _LOCK:
        entry = _PUSHED.setdefault(name, {"original": os.environ.get(name), "values": []})
        entry["values"].append(value)
        os.environ[name] = value
    try:
        yield
    finally:
        with _LOCK:
            entry["values"].remove(value)
            if entry["values"]:
                os.environ[name] = entry["values"][-1]
            else:
                del _PUSHED[name]
                if entry["original"] is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = entry["original"]


@contextmanager
def source_date_for_gdal() -> Iterator[None]:
    """Within the block, GDAL writes ``SOURCE_DATE_EPOCH`` as a GeoPackage's ``last_change``
    (``OGR_CURRENT_DATE``, unless the user set that one); checks the variable (exit 2 when
    malformed) before anything is written. Blocks may overlap (runs in threads): the variable
    is removed when the last one ends (:func:`_pushed`)."""
    stamp = gpkg_timestamp()
    with _LOCK:
        ours = stamp is not None and (not os.environ.get("OGR_CURRENT_DATE")
                                      or "OGR_CURRENT_DATE" in _PUSHED)
    if not ours:
        yield
        return
    with _pushed("OGR_CURRENT_DATE", stamp):
        yield


def client_date() -> str | None:
    """The client's ``SOURCE_DATE_EPOCH`` text (None when unset), sent with each Dask task:
    :func:`on_worker`."""
    return os.environ.get(VARIABLE, "").strip() or None


@contextmanager
def on_worker(value: str | None) -> Iterator[None]:
    """Within a Dask task: the client's ``SOURCE_DATE_EPOCH`` (``value``, from
    :func:`client_date`) in the worker's environment, and GDAL's ``OGR_CURRENT_DATE`` from it
    (:func:`source_date_for_gdal`). A worker process started before the run did not see the
    variable the user set for it: the GeoPackages written there (``mosaic:cut``'s sheets of a
    vector layer) got the current time as ``last_change``, a sheet PDF its ``CreationDate``.
    ``value`` None leaves the worker's environment as it is."""
    if value is None:
        yield
        return
    with _pushed(VARIABLE, value), source_date_for_gdal():
        yield
