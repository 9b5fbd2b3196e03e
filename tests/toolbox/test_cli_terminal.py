"""What a user sees on the terminal (issue 30): -v after 'run' or after the id, and a progress
bar that fits one line and is wiped before the JSON is printed."""

from __future__ import annotations

import io
import json

import pytest
from conftest import run_cli

from toolbox.cli.terminal import TerminalFeedback
from toolbox.demo.samples import linework


@pytest.fixture(scope="module")
def lines(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lines")
    return linework.make(folder, {})["linework"]


@pytest.mark.parametrize("where", ["after the id", "at the end"])
def test_verbose_after_the_id(lines, tmp_path, where):
    out = tmp_path / "check.gpkg"
    params = ["--INPUT", lines, "--OUTPUT", out]
    args = {"after the id": ["run", "topology:check", "-v", *params],
            "at the end": ["run", "topology:check", *params, "-v"]}[where]
    proc = run_cli(*args)
    assert proc.returncode == 0, proc.stderr
    assert "INFO: input: 14 features, 14 lines, 0 invalid" in proc.stderr
    assert json.loads(proc.stdout)["OUTPUT"] == str(out)


def test_not_verbose_by_default(lines, tmp_path):
    proc = run_cli("run", "topology:check", "--INPUT", lines, "--OUTPUT", tmp_path / "c.gpkg")
    assert proc.returncode == 0 and "INFO:" not in proc.stderr


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def screen_line(text: str) -> str:
    """What one terminal line shows after ``text`` (carriage returns rewind, no newline)."""
    line: list[str] = []
    col = 0
    for ch in text:
        if ch == "\r":
            col = 0
            continue
        if col < len(line):
            line[col] = ch
        else:
            line.append(ch)
        col += 1
    return "".join(line)


def test_progress_bar_fits_the_terminal_and_is_wiped(monkeypatch):
    import os
    import shutil

    monkeypatch.setattr(shutil, "get_terminal_size", lambda fallback=None: os.terminal_size((80, 24)))
    term = FakeTerminal()
    feedback = TerminalFeedback("mosaic:seamlines", stream=term)
    feedback.set_progress(50, "a long message that makes the line longer than the terminal")
    feedback._last_draw = 0.0
    feedback.set_progress(60, "short")
    drawn = [piece for piece in term.getvalue().split("\r") if piece.strip()]
    assert drawn and all(len(piece) <= 79 for piece in drawn)  # never wraps to a second line
    assert "short" in screen_line(term.getvalue()) and "longer" not in screen_line(term.getvalue())
    feedback.finish()
    assert screen_line(term.getvalue()).strip() == ""  # nothing left before the JSON
    assert term.getvalue().endswith("\r")


def test_library_warnings_become_one_toolbox_line():
    from toolbox.cli import warning_message

    where = "/venv/lib/python3.11/site-packages/rasterio/__init__.py"
    assert warning_message(UserWarning("block size\nnot a multiple"), UserWarning, where) == \
        "block size; not a multiple (rasterio)"
    assert warning_message(DeprecationWarning("old"), DeprecationWarning, where) is None

    class NotGeoreferencedWarning(UserWarning):
        pass

    assert warning_message(NotGeoreferencedWarning("no geotransform"), NotGeoreferencedWarning,
                           where) is None


def test_a_library_warning_during_a_command_is_one_line(tmp_path):
    import subprocess
    import sys

    script = (
        "import sys, warnings, click\n"
        "from toolbox.cli import _handle_errors, setup_logging\n"
        "setup_logging(0, False)\n"
        "@click.command()\n"
        "@_handle_errors\n"
        "def cmd():\n"
        "    warnings.warn_explicit('values clipped', RuntimeWarning,\n"
        "        '/x/site-packages/rasterio/warp.py', 10)\n"
        "    warnings.warn('going away', DeprecationWarning)\n"
        "cmd()\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "WARNING: values clipped (rasterio)\n"
