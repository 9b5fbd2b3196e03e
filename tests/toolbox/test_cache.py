"""The per-user cache folder: numba's compiled kernels go there (never into the package), unless
the user chose NUMBA_CACHE_DIR."""

from __future__ import annotations

import os
import subprocess
import sys

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
    assert proc.stdout.strip() == str(folder)
    assert list(folder.rglob("*twice*.nbi")), "no compiled kernel in the per-user cache"
    assert not (tmp_path / "__pycache__").exists() or not list(
        (tmp_path / "__pycache__").glob("*.nbi"))  # nothing beside the sources


def test_the_users_numba_cache_dir_wins(tmp_path):
    proc = run("import toolbox, numba; print(numba.config.CACHE_DIR)", tmp_path,
               NUMBA_CACHE_DIR=str(tmp_path / "mine"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(tmp_path / "mine")
