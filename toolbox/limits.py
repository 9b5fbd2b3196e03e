"""Size guards: an algorithm estimates what it will allocate or write (cells, vertices, features,
sheets) from its parameters before it starts, and :func:`check_size` refuses an estimate past the
limit with the numbers and the parameter to change, instead of a MemoryError or a run of hours.

Each limit has a default and an environment variable to raise it (``TOOLBOX_MAX_CELLS`` for grids,
also the default of the gridding algorithms' ``MAX_CELLS``).
"""

from __future__ import annotations

import math
import os

from toolbox.errors import ParameterError

#: kind -> (environment variable, default limit)
LIMITS = {
    "cells": ("TOOLBOX_MAX_CELLS", 1_000_000_000),
    "vertices": ("TOOLBOX_MAX_VERTICES", 100_000_000),
    "features": ("TOOLBOX_MAX_FEATURES", 10_000_000),
    "sheets": ("TOOLBOX_MAX_SHEETS", 10_000),
    # a tile and its halo held in memory by one worker (a tile of 512 + 2 x 1,744 cells)
    "window cells": ("TOOLBOX_MAX_WINDOW_CELLS", 16_000_000),
}


def size_limit(kind: str) -> int:
    """The limit for ``kind`` (a key of :data:`LIMITS`): its environment variable, else the
    default."""
    variable, default = LIMITS[kind]
    text = os.environ.get(variable)
    if text is None or not text.strip():
        return default
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 1):
        raise ParameterError(variable, f"(environment variable) must be a number of {kind} "
                             f">= 1, got {text!r}")
    return int(value)


def check_size(kind: str, estimate: float, parameter: str, what: str, hint: str,
               unit: str | None = None) -> None:
    """Refuse when ``estimate`` (a count of ``kind``, may be a float: inf and nan are refused)
    exceeds the limit. The message is ``PARAMETER <what> gives about N <unit>, over the limit
    of L <kind>; <hint>``: ``what`` continues the parameter's name (``"1e-09 over heights
    120 .. 480"``), ``hint`` says what to change (``"use a larger INTERVAL"``), ``unit`` names
    what is counted when it is not ``kind`` itself (``"contour levels"``)."""
    limit = size_limit(kind)
    if estimate <= limit:  # False for nan
        return
    shown = f"{estimate:,.0f}" if estimate < 1e15 else f"{estimate:.3g}"
    raise ParameterError(parameter, f"{what} gives about {shown} {unit or kind}, over the limit "
                         f"of {limit:,} {kind}; {hint} (or raise {LIMITS[kind][0]})")
