"""Shared helpers of the error-contract tests: run the CLI in-process, read its one error line,
register a throwaway algorithm, run the CLI under a file-size limit (a full disk), find the
system Python that has QGIS."""

from __future__ import annotations

import functools
import os
import resource
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from click.testing import CliRunner

from toolbox.cli import main


def cli(*args: Any, env: dict | None = None) -> tuple[int, str, str]:
    """The CLI run in-process: exit code, stdout, stderr (never a traceback)."""
    result = CliRunner().invoke(main, [str(a) for a in args], env=env)
    assert "Traceback" not in result.stderr, result.stderr
    return result.exit_code, result.stdout, result.stderr


def one_error(stderr: str) -> str:
    """The one ``toolbox: error:`` line of stderr (warnings aside)."""
    lines = [ln for ln in stderr.strip().splitlines() if not ln.startswith("WARNING:")]
    assert len(lines) == 1 and lines[0].startswith("toolbox: error: "), stderr
    return lines[0]


def register_testing(name: str, output: Any, process: Callable[[Any, dict, Any], Any],
                     doc: str = "A test algorithm.") -> type:
    """Register algorithm ``testing:<name>`` with the one parameter ``output`` whose
    ``process(self, params, feedback)`` is given."""
    from toolbox.algorithm import Algorithm
    from toolbox.registry import register

    cls = type(f"_Testing_{name}", (Algorithm,), {
        "__doc__": doc, "id": f"testing:{name}", "display_name": name, "group": name,
        "short_help": name, "parameters": [output], "process": process})
    return register(cls)


def run_on_full_disk(args: list[str], limit: int = 20_000) -> subprocess.CompletedProcess:
    """``toolbox run *args`` in a subprocess that may write at most ``limit`` bytes a file.

    It writes no bytecode: Python's importlib ignores a short write of a ``.pyc`` (3.11's
    ``_write_atomic``), so a module compiled there left a ``.pyc`` cut at ``limit`` bytes in
    the source tree, and every later import of it failed ("marshal data too short": exit 3,
    Dask workers that never started), depending on the order the tests ran in."""

    def cap():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run([sys.executable, "-m", "toolbox.cli", "run", *args], preexec_fn=cap,
                          env=env, capture_output=True, text=True, timeout=300)


def assert_cannot_write(proc: subprocess.CompletedProcess, out: Path) -> None:
    """Exit 2, one line naming OUTPUT, and nothing left in ``out``."""
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("toolbox: error: cannot write OUTPUT"), \
        proc.stderr
    assert not out.exists() or list(out.iterdir()) == []


def assert_refused(args: list, text: str, absent: tuple[Path, ...] = ()) -> str:
    """``toolbox *args`` exits 2 with one error line containing ``text``; no ``absent`` file
    exists afterwards. Returns the error line."""
    code, _, err = cli(*args)
    line = one_error(err)
    assert code == 2 and text in line, err
    assert not any(p.exists() for p in absent)
    return line


@functools.cache
def qgis_python() -> str | None:
    """The system ``python3`` that imports ``qgis.core`` (python3-qgis), or None."""
    python = shutil.which("python3", path="/usr/bin")
    if python is None:
        return None
    check = subprocess.run([python, "-c", "import qgis.core"], capture_output=True)
    return python if check.returncode == 0 else None
