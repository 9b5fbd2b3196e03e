"""The demo (sample data and every demo step's outputs), built once per test process and shared by
test_error_contract, test_fuzz_readers and test_signals (building it costs several seconds)."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path

_DEMO: dict = {}


def demo() -> tuple[Path, dict[str, str]]:
    """``(folder, variables)``: the demo run into ``folder``; ``variables`` maps the sample
    names (``mass_points``, ``dem``, ``siena_project``...) and ``out`` to paths."""
    if not _DEMO:
        import yaml

        from toolbox.demo import run_demo

        folder = Path(tempfile.mkdtemp(prefix="toolbox_trust_demo_")) / "demo_out"
        atexit.register(shutil.rmtree, folder.parent, True)
        summary = run_demo(folder)
        doc = yaml.safe_load((folder / "demo_pipeline.yaml").read_text(encoding="utf-8"))
        _DEMO.update(folder=folder, variables=dict(doc["variables"]), summary=summary)
    return _DEMO["folder"], _DEMO["variables"]


def demo_summary() -> str:
    """What ``toolbox demo`` printed for the shared run."""
    demo()
    return _DEMO["summary"]
