"""A warning logged by a task on a Dask worker (another process) reaches the run's feedback and
its JSON report, each text once, as a local run's do: ortho:batch of two JPEG photos with an
EXIF orientation on a two-process LocalCluster kept 0 of the 2 EXIF warnings the local run
keeps (the worker logged them in its own process). Also when the task fails."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import rasterio

import toolbox

sys.path.insert(0, str(Path(__file__).parent))
from test_round20_leftovers12_worker_warnings import EXIF, two_turned_photos  # noqa: E402

pytestmark = [pytest.mark.distributed]


def _exif(warnings) -> list[str]:
    return sorted(w for w in warnings if EXIF in w)


def test_dask_worker_warnings_reach_feedback_and_report_like_a_local_run(tmp_path, cluster,
                                                                        monkeypatch):
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    sc, project = two_turned_photos(tmp_path)
    runs = {}
    for name, scheduler in (("local", "local"), ("dask", cluster)):
        feedback = toolbox.Feedback()
        result = toolbox.run("ortho:batch", {
            "PROJECT": project, "DEM": sc.dem_path, "CELL_SIZE": 25.0, "OVERVIEWS": False,
            "FOLDER": str(tmp_path / name), "SCHEDULER": scheduler,
            "OUTPUT": tmp_path / f"{name}.json"},
            feedback=feedback, report=tmp_path / f"{name}.run.json")
        assert result["STATISTICS"]["executor"].startswith(
            "dask scheduler" if name == "dask" else "local"), result["STATISTICS"]
        report = json.loads((tmp_path / f"{name}.run.json").read_text())["warnings"]
        runs[name] = (feedback.warnings, report)
    local, dask = runs["local"], runs["dask"]
    # the local run: one warning per photo, naming it (what the EXIF tag says, by hand)
    names = sorted(f"{tmp_path / p} {EXIF}" for p in ("p1.jpg", "p2.jpg"))
    assert sorted(w.split(": ", 1)[1].split(" (the view", 1)[0] for w in _exif(local[0])) == names
    assert _exif(dask[0]) == _exif(local[0]), dask[0]
    assert _exif(dask[1]) == _exif(local[1]) == _exif(local[0]), dask[1]
    assert len(dask[0]) == len(set(dask[0]))  # each text once
    with rasterio.open(tmp_path / "local" / "p1.tif") as a, \
            rasterio.open(tmp_path / "dask" / "p1.tif") as b:
        assert (a.read() == b.read()).all()  # the results are unchanged


def _warn_then(task):
    import logging

    logging.getLogger("toolbox.test").warning("tile %d: a note from the worker", task)
    logging.getLogger("rasterio._env").warning("a GDAL note %d", task)
    if task == 2:
        raise ValueError(f"tile {task} is broken")
    return task * 10


def test_warnings_of_a_failing_task_reach_the_run_too(cluster):
    from toolbox.executor import map_tiles, resolve_executor
    from toolbox.feedback import logged_warnings

    feedback = toolbox.Feedback()
    with logged_warnings(feedback), pytest.raises(ValueError, match="tile 2 is broken"):
        list(map_tiles(_warn_then, [1, 2], executor=resolve_executor(cluster)))
    assert "tile 2: a note from the worker" in feedback.warnings, feedback.warnings
    assert "GDAL: a GDAL note 2" in feedback.warnings, feedback.warnings
