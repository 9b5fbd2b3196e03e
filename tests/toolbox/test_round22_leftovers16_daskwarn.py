"""Python warnings (``warnings.warn``: numpy's RuntimeWarnings, a library's) of a task run on a
Dask worker reach the client as a local run's do. dem:slope of a float64 DEM holding +-1e300
(16-cell tiles, a 2-process LocalCluster): the local run prints "overflow encountered in
multiply (shading)" and "... in square (shading)" and keeps both in its report; on the cluster
both were printed on the workers' stderr only (0 warnings shown, 0 in the report, exit 0). Now
each task records them and the client gives them again through ``warnings.warn_explicit``,
each once per map, in task order, with their category, file and line."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from tests.helpers_cli import cli

pytestmark = [pytest.mark.distributed]


def _warned_lines(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("WARNING:") and "GDAL" not in ln]


def test_slope_on_a_cluster_shows_the_local_runs_numpy_warnings(tmp_path, cluster, monkeypatch):
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    z = np.full((64, 64), 100.0)
    z[10, 10], z[40, 50] = 1e300, -1e300  # two tiles whose gradients overflow when squared
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=64, height=64, count=1,
                       dtype="float64", crs="EPSG:32632",
                       transform=from_origin(680000, 4800000, 10, 10)) as dst:
        dst.write(z, 1)
    # numpy's own words for these overflows (the reference for the texts)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        np.array([1e300]) * np.array([1e300])
        np.square(np.array([1e300]))
    texts = [str(w.message) for w in caught]
    assert texts == ["overflow encountered in multiply", "overflow encountered in square"]
    runs = {}
    for name, scheduler in (("local", "local"), ("dask", cluster)):
        code, _, err = cli("run", "dem:slope", "--INPUT", tmp_path / "dem.tif", "--TILE_SIZE",
                           "16", "--OVERVIEWS", "false", "--SCHEDULER", scheduler,
                           "--OUTPUT", tmp_path / f"{name}.tif",
                           "--run-report", tmp_path / f"{name}.json")
        assert code == 0, err
        report = json.loads((tmp_path / f"{name}.json").read_text())["warnings"]
        runs[name] = (_warned_lines(err), [w for w in report if "GDAL" not in w])
    expected = [f"{t} (shading)" for t in texts]
    assert runs["local"] == ([f"WARNING: {t}" for t in expected], expected), runs["local"]
    assert runs["dask"] == runs["local"], runs["dask"]  # before: ([], [])
    assert (tmp_path / "dask.tif").read_bytes() == (tmp_path / "local.tif").read_bytes()


class TileWarning(UserWarning):
    """A warning class of the task's own module (found again by name on the client)."""


def _warn(task: int) -> int:
    from toolbox.executor import thread_pool

    warnings.warn(f"tile {task % 2} is odd", TileWarning, stacklevel=1)
    with thread_pool(2) as submit:  # a local thread of the task: its warnings are the task's
        submit(_warn_in_thread, task).result()
    if task == 5:
        raise ValueError("tile 5 is broken")
    return task * 10


def _warn_in_thread(task: int) -> None:
    warnings.warn(f"thread of tile {task}", RuntimeWarning, stacklevel=1)


def test_map_tiles_gives_each_python_warning_once_in_task_order(cluster):
    from toolbox.executor import map_tiles, resolve_executor

    for _ in range(2):  # a second map on the same workers shows them again, as a new process
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert list(map_tiles(_warn, [0, 1, 2, 3], executor=resolve_executor(cluster))) \
                == [0, 10, 20, 30]
        got = [(w.category, str(w.message)) for w in caught]
        assert got == [(TileWarning, "tile 0 is odd"), (RuntimeWarning, "thread of tile 0"),
                       (TileWarning, "tile 1 is odd"), (RuntimeWarning, "thread of tile 1"),
                       (RuntimeWarning, "thread of tile 2"),
                       (RuntimeWarning, "thread of tile 3")], got
        assert caught[0].filename == __file__ and caught[0].lineno == \
            _warn.__code__.co_firstlineno + 3


def test_python_warnings_of_a_failing_task_reach_the_client(cluster):
    from toolbox.executor import map_tiles, resolve_executor

    with warnings.catch_warnings(record=True) as caught, \
            pytest.raises(ValueError, match="tile 5 is broken"):
        warnings.simplefilter("always")
        list(map_tiles(_warn, [5], executor=resolve_executor(cluster)))
    assert [str(w.message) for w in caught] == ["tile 1 is odd", "thread of tile 5"]
