"""The per-user cache folder: compiled numba kernels and the algorithm spec index.

Never inside the installed package (which may be read-only): ``$XDG_CACHE_HOME`` or
``~/.cache``, then ``photogrammetry-toolbox/``. Everything there can be deleted at any time.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from pathlib import Path

APP_NAME = "photogrammetry-toolbox"


def user_cache_dir(*parts: str) -> Path:
    """``$XDG_CACHE_HOME/photogrammetry-toolbox/<parts>`` (default ``~/.cache/...``); not created."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base, APP_NAME, *parts)


def configure_numba_cache() -> None:
    """Point numba's on-disk kernel cache (``@njit(cache=True)``) at the per-user cache folder.

    Only when the user did not set ``NUMBA_CACHE_DIR``; must run before numba is imported (numba
    reads it once). Without it numba writes next to the installed sources, or recompiles every
    run when that folder is read-only.
    """
    if "NUMBA_CACHE_DIR" not in os.environ:
        os.environ["NUMBA_CACHE_DIR"] = str(user_cache_dir("numba"))


def njit_on_first_call(**options) -> Callable[[Callable], Callable]:
    """Decorator: ``numba.njit(**options)`` applied on the function's first call, so that
    importing its module does not import numba (about 0.4 s). Only for kernels called from
    Python: a compiled caller needs the numba dispatcher itself."""

    def decorate(func: Callable) -> Callable:
        compiled: list[Callable] = []

        @functools.wraps(func)
        def call(*args):
            if not compiled:
                from numba import njit

                compiled.append(njit(**options)(func))
            return compiled[0](*args)

        return call

    return decorate
