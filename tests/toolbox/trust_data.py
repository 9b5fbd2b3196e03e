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
        from toolbox.batch import parse_pipeline, run_pipeline
        from toolbox.demo import demo_pipeline_doc
        from toolbox.demo.samples import make_samples

        folder = Path(tempfile.mkdtemp(prefix="toolbox_trust_demo_"))
        atexit.register(shutil.rmtree, folder, True)
        variables = {k: str(v) for k, v in make_samples(folder / "data").items()}
        variables["out"] = str(folder)
        run_pipeline(parse_pipeline(demo_pipeline_doc(), folder, variables, "demo pipeline"),
                     overwrite=True)
        _DEMO.update(folder=folder, variables=variables)
    return _DEMO["folder"], _DEMO["variables"]
