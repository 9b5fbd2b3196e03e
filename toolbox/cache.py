"""The per-user cache folder: compiled numba kernels and the algorithm spec index.

Never inside the installed package (which may be read-only): ``$XDG_CACHE_HOME`` or
``~/.cache``, then ``photogrammetry-toolbox/``. Everything there can be deleted at any time.
"""

from __future__ import annotations

import os

# ``import toolbox`` runs this module: no typing, pathlib, functools or collections here (with
# the ``re`` they bring, about a third of ``toolbox --version``); the type checkers read this as
# typing.TYPE_CHECKING
TYPE_CHECKING = False
if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

APP_NAME = "photogrammetry-toolbox"


def user_cache_path(*parts: str) -> str:
    """``$XDG_CACHE_HOME/photogrammetry-toolbox/<parts>`` (default ``~/.cache/...``) as a string;
    not created."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, APP_NAME, *parts)


def user_cache_dir(*parts: str) -> Path:
    """:func:`user_cache_path` as a :class:`~pathlib.Path`."""
    from pathlib import Path

    return Path(user_cache_path(*parts))


def configure_numba_cache() -> None:
    """Point numba's on-disk kernel cache (``@njit(cache=True)``) at the per-user cache folder.

    Only when the user did not set ``NUMBA_CACHE_DIR``; must run before numba is imported (numba
    reads it once). Without it numba writes next to the installed sources, or recompiles every
    run when that folder is read-only.
    """
    if "NUMBA_CACHE_DIR" not in os.environ:
        folder = user_cache_path("numba", kernel_sources_key())
        if not os.path.isdir(folder):
            prune_stale_kernel_caches(os.path.dirname(folder))
        os.environ["NUMBA_CACHE_DIR"] = folder


def kernel_sources_key() -> str:
    """A name for this toolbox's sources, so that compiled kernels are never reused across changes.

    numba's cache checks only the file of each kernel, not the kernels it calls from other
    modules: after an upgrade (or a checkout) that changes a called kernel, a caller cached before
    would keep the old callee compiled into it, silently. So the whole kernel cache is keyed by the
    sources: an installed package by its folder's and ``__init__.py``'s modification times (pip
    writes both anew), a source tree (editable install) by every ``.py`` file's time and size.
    """
    import hashlib
    import marshal

    package = os.path.dirname(os.path.abspath(__file__))
    if os.path.basename(os.path.dirname(package)) in ("site-packages", "dist-packages"):
        stamp: object = (package, os.stat(package).st_mtime_ns,
                         os.stat(os.path.join(package, "__init__.py")).st_mtime_ns)
    else:
        stamp = (package, sources_stamp(package))
    return hashlib.blake2b(marshal.dumps(stamp), digest_size=8).hexdigest()


def sources_stamp(folder: str | os.PathLike) -> tuple:
    """``((relative path, mtime ns, size), ...)`` of every ``.py`` file under ``folder``, sorted
    (``__pycache__`` left out)."""
    stamp: list[tuple[str, int, int]] = []

    def walk(path: str, rel: str) -> None:
        with os.scandir(path) as scan:
            entries = sorted(scan, key=lambda e: e.name)
        for entry in entries:
            if entry.is_dir(follow_symlinks=False):
                if entry.name != "__pycache__":
                    walk(entry.path, rel + entry.name + "/")
            elif entry.name.endswith(".py"):
                st = entry.stat()
                stamp.append((rel + entry.name, st.st_mtime_ns, st.st_size))

    walk(os.fspath(folder), "")
    return tuple(stamp)


def prune_stale_kernel_caches(folder: str, days: float = 14.0) -> None:
    """Delete the kernel caches of other sources not used for ``days`` (best effort)."""
    import shutil
    import time

    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    limit = time.time() - days * 86400.0
    for entry in entries:
        try:
            if entry.is_dir() and entry.stat().st_mtime < limit:
                shutil.rmtree(entry.path, ignore_errors=True)
        except OSError:
            continue


def skip_numba_blas_probe() -> None:
    """Spare the first compiled call of a process numba's BLAS probe: importing scipy.linalg.

    When numba loads its first kernel (from the cache too) it imports ``numba.np.arraymath``,
    whose import asks :func:`numba.np.linalg.ensure_blas` whether scipy's BLAS is there, and
    that imports ``scipy.linalg`` (with scipy's array-API layer: about 0.2 s of CPU, a sixth of a
    small contour run). The answer only chooses BLAS or a loop for ``np.correlate`` and
    ``np.convolve`` inside kernels; scipy is a dependency of the toolbox, so this answers it by
    scipy's presence (no import) for that one import-time call; every other caller (``np.dot``,
    ``np.linalg`` in a kernel) gets numba's own check, as before. Call it after ``import numba``,
    before the first kernel call; once numba's array math is loaded it does nothing.
    """
    import sys

    if "numba.np.arraymath" in sys.modules:
        return
    try:
        from numba.np import linalg
    except ImportError:  # pragma: no cover - another numba layout: keep its probe
        return
    real = getattr(linalg, "ensure_blas", None)
    if real is None or getattr(real, "presence_only", False):
        return

    def ensure_blas() -> None:
        if sys._getframe(1).f_globals.get("__name__") != "numba.np.arraymath":
            return real()
        linalg.ensure_blas = real  # once: arraymath's import-time question
        import importlib.util

        if importlib.util.find_spec("scipy") is None:
            raise ImportError("scipy 0.16+ is required for linear algebra")

    ensure_blas.presence_only = True  # type: ignore[attr-defined]
    linalg.ensure_blas = ensure_blas


def njit_on_first_call(**options) -> Callable[[Callable], Callable]:
    """Decorator: ``numba.njit(**options)`` applied on the function's first call, so that
    importing its module does not import numba (about 0.4 s). Only for kernels called from
    Python: a compiled caller needs the numba dispatcher itself."""
    import functools

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
