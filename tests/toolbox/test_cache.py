"""The per-user cache folder: numba's compiled kernels go there (never into the package), unless
the user chose NUMBA_CACHE_DIR."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

KERNEL = """
from numba import njit

@njit(cache=True)
def twice(x):
    return 2 * x
"""


def run(code: str, tmp_path, **env):
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    environ |= {"XDG_CACHE_HOME": str(tmp_path / "cache"), "PYTHONPATH": str(tmp_path)} | env
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=environ, cwd=tmp_path, timeout=300)


def test_numba_kernels_are_cached_per_user(tmp_path):
    (tmp_path / "kernel_mod.py").write_text(KERNEL)
    proc = run("import toolbox, numba, kernel_mod; assert kernel_mod.twice(3) == 6; "
               "print(numba.config.CACHE_DIR)", tmp_path)
    assert proc.returncode == 0, proc.stderr
    folder = tmp_path / "cache" / "photogrammetry-toolbox" / "numba"
    assert Path(proc.stdout.strip()).parent == folder  # numba/<key of the toolbox's sources>
    assert list(folder.rglob("*twice*.nbi")), "no compiled kernel in the per-user cache"
    assert not (tmp_path / "__pycache__").exists() or not list(
        (tmp_path / "__pycache__").glob("*.nbi"))  # nothing beside the sources


def test_the_users_numba_cache_dir_wins(tmp_path):
    proc = run("import toolbox, numba; print(numba.config.CACHE_DIR)", tmp_path,
               NUMBA_CACHE_DIR=str(tmp_path / "mine"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(tmp_path / "mine")


def test_a_changed_source_gets_a_new_kernel_cache(tmp_path):
    """numba's own cache checks only a kernel's file, not the kernels it calls from other modules:
    a caller compiled before a change of its callee keeps the old callee (a wrong result in
    silence). Shown here with numba alone; the toolbox keys its whole cache by its sources."""
    (tmp_path / "callee.py").write_text("from numba import njit\n\n@njit(cache=True)\n"
                                        "def f(x):\n    return x + 1\n")
    (tmp_path / "caller.py").write_text("from numba import njit\nfrom callee import f\n\n"
                                        "@njit(cache=True)\ndef g(x):\n    return f(x)\n")
    code = "import caller; print(caller.g(1))"
    plain = {"NUMBA_CACHE_DIR": str(tmp_path / "plain")}
    assert run(code, tmp_path, **plain).stdout.strip() == "2"
    (tmp_path / "callee.py").write_text((tmp_path / "callee.py").read_text().replace("+ 1", "+ 10"))
    assert run(code, tmp_path, **plain).stdout.strip() == "2"  # numba alone: stale, 11 expected

    import toolbox
    from toolbox.cache import kernel_sources_key, sources_stamp
    package = Path(toolbox.__file__).parent
    key = kernel_sources_key()
    assert key == kernel_sources_key() and len(key) == 16
    assert sources_stamp(package)  # a source tree: the key follows every file's time and size
    stamp = package / "version.py"
    before = stamp.stat()
    try:
        os.utime(stamp, ns=(before.st_atime_ns, before.st_mtime_ns + 1_000_000_000))
        assert kernel_sources_key() != key
    finally:
        os.utime(stamp, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert kernel_sources_key() == key


BLAS_PROBE = """
import sys
import numpy as np
import numba
from toolbox.cache import skip_numba_blas_probe
from kernel_mod import twice

skip_numba_blas_probe()
assert twice(3) == 6
assert "scipy.linalg" not in sys.modules, "numba's array math imported scipy.linalg"
from numba.np import arraymath, linalg
assert arraymath._HAVE_BLAS is True  # scipy is installed: the answer numba's probe gives
assert not getattr(linalg.ensure_blas, "presence_only", False)  # numba's own check is back

@numba.njit
def products(a, b, v, w):
    return a @ b, np.correlate(v, w)

a, b = np.arange(6.0).reshape(2, 3), np.arange(12.0).reshape(3, 4)
v, w = np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.5, -1.0])
ab, corr = products(a, b, v, w)
assert np.allclose(ab, a @ b) and np.allclose(corr, np.correlate(v, w))  # numpy, the oracle
assert "scipy.linalg" in sys.modules  # BLAS through numba's own probe, when a kernel needs it
"""


def test_the_first_kernel_load_skips_the_scipy_blas_probe(tmp_path):
    """Loading a kernel does not import scipy.linalg (numba's import-time BLAS probe answered
    by scipy's presence); kernels with matrix products and np.correlate still give numpy's
    results."""
    (tmp_path / "kernel_mod.py").write_text(KERNEL)
    proc = run(BLAS_PROBE, tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
