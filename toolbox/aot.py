"""Kernels compiled ahead of time: loaded by a run without importing numba.

A numba kernel costs its process numba's import and the load of its cached machine code before
the first call, while the kernel itself may need less: carto:contours traces a 2000 x 2000 DEM
in 0.15 s, and the whole run took 0.27-0.34 s longer with the JIT than with the module below
(``bench/results/round3.md``, contours, three sittings); the bulk GeoPackage writer's page and
blob passes (:mod:`toolbox.io.page_kernel`, :mod:`toolbox.io.blob_kernel`) and the TIN's
tables and areas (:mod:`toolbox.terrain.tin.edge_kernel`, ``unique_kernel.cdt_tables``) run
without numba too (their fallback is their numpy steps, not the JIT: a small input is not worth
numba's import). ``toolbox warmup`` (run by
``make venv``) therefore also builds the kernels of :data:`EXPORTS` with numba's ahead-of-time
compiler (``numba.pycc``) into one extension module each, for this machine's CPU, in the
per-user cache (:func:`aot_folder`); a run loads the module (a plain ``.so``: numpy only; it
releases the GIL as the JIT kernel does) when it is there and calls numba's JIT otherwise.
Both compile the same kernel source, so they give the same arrays (tests). Callers go through
:func:`compiled_kernel`, which checks the arguments that pycc's wrapper takes on trust. A build
needs a C compiler and Python's headers; without them, or when numba drops its AOT compiler, a
warning says so and runs keep the JIT.

The folder is keyed by the toolbox's sources (:func:`toolbox.cache.kernel_sources_key`), the
Python and numpy versions and the CPU (its model and feature flags), so a module is never loaded
by other sources or on another processor (a home folder shared by a cluster's machines).
``TOOLBOX_AOT=0`` makes runs use the JIT.
"""

from __future__ import annotations

import contextlib
import os
import threading

#: name -> (kernel module, its numba dispatcher, the exported signature, (dtype, ndim) of each
#: argument: C-contiguous arrays, or ndim 0 for an integer, checked before every call, see
#: :func:`compiled_kernel`)
EXPORTS = {
    "contour_lines": ("toolbox.cartography.contour_kernel", "lines_core",
                      "Tuple((float64[:, :], int64[:], int32[:]))(float64[:, ::1], float64[::1], "
                      "float64[::1], float64[::1])",
                      (("float64", 2), ("float64", 1), ("float64", 1), ("float64", 1))),
    "cocircular_edges": ("toolbox.terrain.tin.unique_kernel", "cocircular_edges",
                         "int64(float64[:, ::1], uint32[:, ::1])",
                         (("float64", 2), ("uint32", 2))),
    "cdt_tables": ("toolbox.terrain.tin.unique_kernel", "cdt_tables",
                   "Tuple((int32[:, ::1], int32[:, ::1]))(uint32[:, ::1], int32[::1], int64)",
                   (("uint32", 2), ("int32", 1), ("int64", 0))),
    "leaf_cells": ("toolbox.io.page_kernel", "leaf_cells",
                   "int64[::1](uint8[::1], int64, int64[::1], int64[::1], int64[::1], int64[::1], "
                   "int64[::1])",
                   (("uint8", 1), ("int64", 0), ("int64", 1), ("int64", 1), ("int64", 1),
                    ("int64", 1), ("int64", 1))),
    "copy_records": ("toolbox.io.page_kernel", "copy_records",
                     "void(uint8[::1], int64[::1], uint8[::1], int64[::1], int64[::1])",
                     (("uint8", 1), ("int64", 1), ("uint8", 1), ("int64", 1), ("int64", 1))),
    "gpkg_blobs": ("toolbox.io.blob_kernel", "gpkg_blobs",
                   "int64(uint8[:, ::1], int64, int64, uint8[::1], int64, uint8[:, ::1], "
                   "float64[:, ::1], float32[:, ::1])",
                   (("uint8", 2), ("int64", 0), ("int64", 0), ("uint8", 1), ("int64", 0),
                    ("uint8", 2), ("float64", 2), ("float32", 2))),
    "triangle_areas": ("toolbox.terrain.tin.edge_kernel", "triangle_areas",
                       "Tuple((float64[::1], float64[::1]))(float64[:, ::1], int32[:, ::1])",
                       (("float64", 2), ("int32", 2))),
    "edge_arrays": ("toolbox.terrain.tin.edge_kernel", "edge_arrays",
                    "Tuple((int32[:, ::1], int32[::1], int32[::1], int32[:, ::1]))"
                    "(int32[:, ::1], int32[:, ::1])",
                    (("int32", 2), ("int32", 2))),
}

_loaded: dict[str, object] = {}
_folder: list[str] = []
_lock = threading.Lock()


def _cpu_tag() -> tuple[str, str]:
    """``(tag, LLVM target CPU)``: the CPU's model and feature flags when Linux shows them
    (code built for this ``"host"``), else a generic build for the architecture."""
    import platform

    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as info:
            lines = [line for line in info if line.startswith(("model name", "flags"))]
    except OSError:
        lines = []
    model = next((line for line in lines if line.startswith("model name")), "")
    flags = next((line for line in lines if line.startswith("flags")), "")
    if not flags:
        return f"generic-{platform.machine()}", ""
    return model + flags, "host"


def aot_folder() -> str:
    """This process's folder of compiled modules (see the module docstring); not created."""
    if not _folder:
        import hashlib
        import sys

        import numpy as np

        from toolbox.cache import kernel_sources_key, user_cache_path

        key = (kernel_sources_key(), sys.version, np.__version__, _cpu_tag()[0])
        digest = hashlib.blake2b(repr(key).encode(), digest_size=8).hexdigest()
        _folder.append(user_cache_path("aot", digest))
    return _folder[0]


def module_path(name: str, folder: str | None = None) -> str:
    """The extension module file of kernel ``name`` in ``folder`` (default :func:`aot_folder`)."""
    from importlib.machinery import EXTENSION_SUFFIXES

    return os.path.join(folder or aot_folder(), f"toolbox_aot_{name}{EXTENSION_SUFFIXES[0]}")


def _jit_forced() -> bool:
    """``TOOLBOX_AOT=0``: runs use numba's JIT."""
    return os.environ.get("TOOLBOX_AOT", "1") == "0"


def compiled_available(name: str) -> bool:
    """Whether kernel ``name`` has a compiled module this run would load (nothing imported)."""
    if _jit_forced():
        return False
    return _loaded.get(name) is not None or os.path.isfile(module_path(name))


def load_compiled(name: str, folder: str | None = None):
    """The compiled module of kernel ``name`` (its function is the kernel's name), or None when
    there is none (or ``TOOLBOX_AOT=0``). Thread-safe; loaded once a process. Call kernels
    through :func:`compiled_kernel`, which checks their arguments."""
    key = f"{name}@{folder}" if folder else name
    with _lock:
        if key not in _loaded:
            _loaded[key] = None
            path = module_path(name, folder)
            if (folder or not _jit_forced()) and os.path.isfile(path):
                import importlib.util

                try:
                    spec = importlib.util.spec_from_file_location(f"toolbox_aot_{name}", path)
                    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
                    spec.loader.exec_module(module)  # type: ignore[union-attr]
                    _loaded[key] = module
                except (ImportError, OSError):
                    pass  # a broken build: the JIT
        return _loaded[key]


def compiled_kernel(name: str, folder: str | None = None):
    """Kernel ``name`` compiled ahead of time, as a function that checks its arguments, or None
    (no module, or ``TOOLBOX_AOT=0``: the caller uses numba's JIT).

    pycc's wrapper does not check them as the JIT's dispatcher does: a float32 or non-contiguous
    array would be read as the declared type (a crash, or wrong values in silence). So every
    argument must be a C-contiguous, aligned array of the exported dtype and dimensions (or an
    integer where the export takes one), else :class:`TypeError` before the call."""
    module = load_compiled(name, folder)
    if module is None:
        return None
    import numpy as np

    _, kernel, _, arrays = EXPORTS[name]
    function = getattr(module, kernel)
    wanted = [(np.dtype(dtype), ndim) for dtype, ndim in arrays]

    def call(*args):
        if len(args) != len(wanted):
            raise TypeError(f"{name} takes {len(wanted)} arguments, got {len(args)}")
        for i, ((dtype, ndim), value) in enumerate(zip(wanted, args, strict=True)):
            if ndim == 0:
                if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                    raise TypeError(f"{name}: argument {i} must be an integer, got "
                                    f"{type(value).__name__}")
                continue
            if not (isinstance(value, np.ndarray) and value.dtype == dtype and value.ndim == ndim
                    and value.flags.c_contiguous and value.flags.aligned):
                got = (f"{value.dtype} {value.ndim}-D, C-contiguous {value.flags.c_contiguous}"
                       if isinstance(value, np.ndarray) else type(value).__name__)
                raise TypeError(f"{name}: argument {i} must be a C-contiguous {ndim}-D {dtype} "
                                f"array, got {got}")
        return function(*args)

    return call


def build_compiled(folder: str | None = None, names: tuple[str, ...] | None = None) -> list[str]:
    """Compile the kernels ``names`` (default all of :data:`EXPORTS`) into ``folder`` (default
    :func:`aot_folder`), each staged and renamed into place; returns the module files. Raises
    what numba's compiler raises (no compiler, no Python headers, no ``numba.pycc``)."""
    import importlib
    import shutil
    import tempfile
    import warnings

    from toolbox.cache import prune_stale_kernel_caches

    folder = folder or aot_folder()
    os.makedirs(folder, exist_ok=True)
    prune_stale_kernel_caches(os.path.dirname(folder))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numba's pending deprecation of pycc
        from numba.pycc import CC
        from numba.pycc import compiler as pycc_compiler
    built = []
    for name in names or tuple(EXPORTS):
        module_name, kernel, signature, _ = EXPORTS[name]
        dispatcher = getattr(importlib.import_module(module_name), kernel)
        staging = tempfile.mkdtemp(prefix=f".{name}-", dir=folder)
        try:
            cc = CC(f"toolbox_aot_{name}")
            cc.output_dir = staging
            cc.target_cpu = _cpu_tag()[1]
            cc.export(kernel, signature)(dispatcher.py_func)
            with warnings.catch_warnings(), _releasing_the_gil(pycc_compiler):
                warnings.simplefilter("ignore")
                cc.compile()
            target = module_path(name, folder)
            os.replace(os.path.join(staging, cc.output_file), target)
            built.append(target)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    return built


@contextlib.contextmanager
def _releasing_the_gil(pycc_compiler):
    """pycc's Python wrappers release the GIL around the kernel, as ``@njit(nogil=True)``'s do
    (pycc has no option for it: its compile flags are made with ``release_gil`` set). The
    kernels touch no Python object; two threads then trace two blocks at once."""
    plain = pycc_compiler.Flags

    class NoGilFlags(plain):  # type: ignore[misc, valid-type]
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.release_gil = True

    pycc_compiler.Flags = NoGilFlags
    try:
        yield
    finally:
        pycc_compiler.Flags = plain
