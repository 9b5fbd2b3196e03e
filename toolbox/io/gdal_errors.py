"""The GDAL errors a run collects (:func:`toolbox.runner.failures.collect_gdal_errors`) and the
operations whose failure the caller handles, whose errors are not the run's
(:func:`handled_gdal_errors`)."""

from __future__ import annotations

import threading
from contextlib import contextmanager

#: the message lists of the runs collecting GDAL errors (each message has a ``thread``)
COLLECTORS: list[list[str]] = []


@contextmanager
def handled_gdal_errors(*handled: type[BaseException]):
    """Around an operation whose failure the caller handles (a probe: is this file a raster?):
    the GDAL errors this thread logged within it are not the run's and are dropped from the
    messages :func:`toolbox.runner.failures.collect_gdal_errors` gathers, so that a later
    failure is not read through them (a probe's "'x.gpkg' not recognized" made a later write
    error read as "INPUT is truncated or corrupt"). An exception of a type in ``handled`` leaving the block is
    suppressed (as by ``contextlib.suppress``); any other keeps the messages."""
    me = threading.get_ident()
    marks = [(messages, len(messages)) for messages in COLLECTORS]
    try:
        yield
    except handled:
        pass
    for messages, start in marks:
        messages[start:] = [m for m in messages[start:] if getattr(m, "thread", None) != me]
