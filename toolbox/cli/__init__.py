"""The ``toolbox`` command: list, help, run, batch, demo, warmup.

The console script enters at :func:`script` (:func:`console`, then a quick exit):
``--version``, ``list`` and ``help`` are answered from the cached spec index without importing
click or setting up logging (:mod:`toolbox.cli.quick`); everything else goes to the click
application :data:`main` (:mod:`toolbox.cli.app`, imported on first use, as are its other
names: ``from toolbox.cli import main`` works as before).
"""

from __future__ import annotations

SUBMODULES = ("app", "helptext", "quick", "terminal")

#: OpenBLAS's idle threads poll (``sched_yield``) for ``2**OPENBLAS_THREAD_TIMEOUT`` CPU cycles
#: (its default 28: about 0.1 s) after they start, which is at NumPy's import, and after each
#: threaded call, before they sleep: 0.03-0.07 s of CPU in every process (``import numpy`` alone:
#: 0.11 against 0.08 s CPU on this 2-core machine, measured), more than many a small run's own
#: work. 2**20 cycles (about 0.4 ms) keeps a burst of threaded calls from sleeping in between.
BLAS_THREAD_TIMEOUT = "20"


def console() -> int | None:
    """The ``toolbox`` script (and ``python -m toolbox``): a quick answer when there is one,
    else the click application (which exits itself)."""
    import sys

    from toolbox.cli.quick import answer

    code = answer(sys.argv[1:])
    if code is not None:
        return code
    from toolbox.cli.app import main

    return main(prog_name="toolbox")


def script() -> None:
    """The ``toolbox`` console script and ``python -m toolbox``: :func:`console`, then the
    process ends at once (:func:`exit_now`). A program calling :func:`console` itself gets its
    result or its ``SystemExit`` as before."""
    import sys

    quiet_blas_threads()
    small_pages_for_numpy()
    try:
        code = console()
    except SystemExit as done:
        code = done.code
    exit_now(code)
    sys.exit(code)


def quiet_blas_threads() -> None:
    """Give OpenBLAS :data:`BLAS_THREAD_TIMEOUT` (its documented ``OPENBLAS_THREAD_TIMEOUT``)
    unless the user set one: read once, when NumPy loads OpenBLAS, so the console script sets
    it first. The number of BLAS threads and what they compute are unchanged; only how long an
    idle one polls before it sleeps (a sleeping one is woken by the next threaded call)."""
    import os

    os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", BLAS_THREAD_TIMEOUT)


def small_pages_for_numpy() -> None:
    """Ask NumPy not to ``madvise`` its big arrays into transparent huge pages
    (``NUMPY_MADVISE_HUGEPAGE=0``, read when NumPy loads) unless the user set it. Where the
    kernel compacts memory to give an madvised region huge pages at its first touch (THP
    ``defrag`` = ``madvise``, a common default, and this machine's), that costs more system
    time than the pages save: on this 2-core machine, whole runs with it off, medians of 3
    interleaved (2026-12-05): tin:delaunay of 1 M points 1.31x faster, dem:idw 1 M points
    1.20x, carto:contours of a 2000 x 2000 DEM 1.50x, dem:hillshade at par
    (bench/results/tin.md). The values computed are the same."""
    import os

    os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")


def exit_now(code: object) -> None:
    """End the process with ``code`` (as ``sys.exit``) after the exit functions, logging and
    the standard streams, without the interpreter's teardown: every module and object freed one
    by one, GDAL's and the other libraries' cleanup, 40-80 ms of a small ``toolbox run`` (4
    drone orthos: 1.02 -> 0.98 s wall) for nothing, the outputs being closed and in place by
    then. Returns (the normal exit follows) under a profiler, tracer or debugger (they report at
    exit), with ``TOOLBOX_FULL_EXIT`` set, or if flushing fails (a closed pipe: Python's own
    exit reports it)."""
    import atexit
    import logging
    import os
    import sys

    if sys.gettrace() is not None or sys.getprofile() is not None or \
            os.environ.get("TOOLBOX_FULL_EXIT"):
        return
    status = 0 if code is None else code if isinstance(code, int) else 1
    try:
        if not isinstance(code, int | None):
            print(code, file=sys.stderr)  # as sys.exit("message")
        atexit._run_exitfuncs()
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
    except Exception:  # noqa: BLE001 - the normal exit then reports it
        return
    os._exit(status)


def __getattr__(name: str):
    """The click application's names (``main``, ``format_help``, ``setup_logging``...), imported
    on first use (PEP 562)."""
    if name.startswith("__") or name in SUBMODULES:
        raise AttributeError(f"module 'toolbox.cli' has no attribute {name!r}")
    from toolbox.cli import app

    return getattr(app, name)
