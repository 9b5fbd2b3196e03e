"""The QGIS provider with inputs as QGIS gives them (round 15): each test runs a short PyQGIS
script in Debian's QGIS Python (no Processing framework, no toolbox run unless needed)."""

from __future__ import annotations

import json
import os
import subprocess
import textwrap
from pathlib import Path

import pytest
from test_qgis_provider import PLUGIN, SYSTEM_PYTHON, needs_qgis

PREAMBLE = """
import json, os, sys
os.environ["QT_QPA_PLATFORM"] = "offscreen"
sys.path.insert(0, {plugin!r})
from qgis.core import *
app = QgsApplication([], False); app.initQgis()
from photogrammetry_toolbox.algorithm import ToolboxAlgorithm

def done(value):
    print("RESULT " + json.dumps(value), flush=True)
    os._exit(0)
"""


def pyqgis(tmp_path: Path, body: str, timeout: float = 60):
    """Run ``body`` after the preamble in QGIS's Python; what it passed to ``done``."""
    script = tmp_path / "script.py"
    script.write_text(PREAMBLE.format(plugin=str(PLUGIN)) + textwrap.dedent(body))
    done = subprocess.run([SYSTEM_PYTHON, str(script)], capture_output=True, text=True,
                          timeout=timeout, cwd=tmp_path,
                          env=dict(os.environ, HOME=str(tmp_path), QT_QPA_PLATFORM="offscreen"))
    line = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    assert line, done.stdout[-2000:] + done.stderr[-2000:]
    return json.loads(line[0][len("RESULT "):])


@needs_qgis
def test_a_result_larger_than_the_pipe_does_not_hang_the_run(tmp_path):
    """A toolbox printing more than the pipe's 64 KB on stdout (vector:info of a file with many
    layers and fields) used to block for ever: the plugin read stdout only after the exit."""
    fake = tmp_path / "toolbox"
    fake.write_text("#!/bin/sh\n"
                    "head -c 300000 /dev/zero | tr '\\0' 'x'\n"
                    "echo '{\"type\": \"result\", \"outputs\": {\"INFO\": 1}}' >&2\n")
    fake.chmod(0o755)
    try:
        got = pyqgis(tmp_path, f"""
            alg = ToolboxAlgorithm({{"id": "vector:info", "parameters": []}}, "tb")
            result, errors = alg._run([{str(fake)!r}], QgsProcessingFeedback())
            done({{"outputs": result.get("outputs"), "errors": errors}})
            """, timeout=20)
    except subprocess.TimeoutExpired:
        pytest.fail("the run hung on a 300 KB stdout")
    assert got == {"outputs": {"INFO": 1}, "errors": []}
