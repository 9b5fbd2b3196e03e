"""ortho:batch: a block of photos on one shared grid, a failing photo reported."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml

import toolbox

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402

SECOND = (scene.CENTRE[0] + 500.0, scene.CENTRE[1] - 80.0, scene.CENTRE[2] + 30.0)


def test_block_on_one_lattice_with_a_failing_photo(tmp_path):
    from toolbox.photogrammetry.synthetic import frame_photo, render_photo, write_photo

    sc = scene.make_scene(tmp_path)
    second = frame_photo(SECOND, (-0.01, 0.02, 0.35), width=scene.SIZE, height=scene.SIZE,
                         crs=scene.CRS)
    write_photo(tmp_path / "p2.tif", render_photo(second, sc.dem, sc.transform, sc.texture,
                                                  dtype="uint8"))
    doc = yaml.safe_load(sc.project_path.read_text())
    keys = ("X0", "Y0", "Z0", "omega", "phi", "kappa")
    doc["photos"] += [
        {"id": "p2", "camera": "synthetic", "image": "p2.tif", "strip": "1",
         "exterior": dict(zip(keys, [*SECOND, -0.01, 0.02, 0.35], strict=True))},
        {"id": "p3", "camera": "synthetic", "image": "missing.tif",
         "exterior": dict(zip(keys, [*SECOND, 0.0, 0.0, 0.0], strict=True))}]
    project = tmp_path / "block.yaml"
    project.write_text(yaml.safe_dump(doc))
    feedback = toolbox.Feedback()
    out = toolbox.run("ortho:batch", {"PROJECT": project, "DEM": sc.dem_path,
                                      "FOLDER": str(tmp_path / "orthos"), "WORKERS": 2,
                                      "OUTPUT": tmp_path / "block.json"}, feedback=feedback)
    stats = out["STATISTICS"]
    assert (stats["done"], stats["failed"]) == (2, 1)
    listing = json.loads((tmp_path / "block.json").read_text())
    assert [Path(p).name for p in listing["orthos"]] == ["p1.tif", "p2.tif"]
    assert listing["failed"][0]["photo"] == "p3" and "missing.tif" in listing["failed"][0]["error"]
    assert any("p3" in w for w in feedback.warnings)
    # one lattice: the largest GSD of the block (2 significant digits), origins on it; the GSD
    # from the scene's own geometry: pixel / c x (Z0 - terrain), terrain between the DEM's extremes
    cell = stats["cell_size"]
    scale = 230.0 / scene.SIZE / 153.0
    highest = max(scene.CENTRE[2], SECOND[2])
    low, high = (highest - float(sc.dem.max())) * scale, (highest - float(sc.dem.min())) * scale
    assert cell == float(f"{cell:.2g}") and 0.98 * low <= cell <= 1.02 * high
    for path in listing["orthos"]:
        scene.assert_on_lattice(path, cell)
        with rasterio.open(path) as src:
            t = src.transform
            assert float(src.tags()["NADIR_X"]) in (scene.CENTRE[0], SECOND[0])
            data = src.read()
            xs = t.c + (np.arange(src.width) + 0.5) * t.a
            ys = t.f + (np.arange(src.height) + 0.5) * t.e
        truth = sc.texture(*np.meshgrid(xs, ys))
        valid = data[1] == 255
        assert np.corrcoef(truth[valid], data[0][valid])[0, 1] > 0.99
    assert not list((tmp_path / "orthos").glob(".*"))  # no partial files left


def test_block_tasks_survive_pickling_for_dask_workers(tmp_path):
    """ortho:batch sends one OrthoTask per photo to run_task; on a Dask cluster they travel
    pickled, so a round trip must give the same ortho."""
    import pickle

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.block import OrthoTask, run_task
    from toolbox.ortho.plan import plan_photo
    from toolbox.ortho.run import OrthoOptions

    sc = scene.make_scene(tmp_path)
    dem = open_raster_info(sc.dem_path)
    plan = plan_photo(sc.photo, dem, sc.photo.crs, cell=10.0)
    task = OrthoTask(sc.photo, open_raster_info(sc.photo_path), dem, plan.grid,
                     tmp_path / "p1_ortho.tif", OrthoOptions(overviews=False), plan.mean_height)
    report = run_task(pickle.loads(pickle.dumps(task)))
    assert "error" not in report and Path(report["output"]).exists()
    with rasterio.open(report["output"]) as src:
        assert src.transform == plan.grid.transform and src.count == 2
        data = src.read()
        xs = src.transform.c + (np.arange(src.width) + 0.5) * src.transform.a
        ys = src.transform.f + (np.arange(src.height) + 0.5) * src.transform.e
    valid = data[1] == 255  # the travelled task still renders the scene's texture, not a blank
    assert valid.mean() > 0.3
    truth = sc.texture(*np.meshgrid(xs, ys))
    assert np.corrcoef(truth[valid], data[0][valid])[0, 1] > 0.99


@pytest.mark.distributed
@pytest.mark.slow
def test_block_on_a_dask_cluster_equals_the_local_run(tmp_path, monkeypatch):
    from distributed import LocalCluster

    sc = scene.make_scene(tmp_path)
    common = {"PROJECT": sc.project_path, "DEM": sc.dem_path, "CELL_SIZE": 10.0,
              "OVERVIEWS": False}
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    local = toolbox.run("ortho:batch", common | {"FOLDER": str(tmp_path / "local"),
                                                 "OUTPUT": tmp_path / "local.json"})
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        remote = toolbox.run("ortho:batch", common | {"SCHEDULER": cluster.scheduler_address,
                                                      "FOLDER": str(tmp_path / "dask"),
                                                      "OUTPUT": tmp_path / "dask.json"})
    assert remote["STATISTICS"]["executor"].startswith("dask scheduler")
    assert local["STATISTICS"]["done"] == remote["STATISTICS"]["done"] == 1
    with rasterio.open(tmp_path / "local" / "p1.tif") as a, \
            rasterio.open(tmp_path / "dask" / "p1.tif") as b:
        assert (a.read() == b.read()).all()


def test_scheduler_local_is_not_overridden_by_the_environment(tmp_path, monkeypatch):
    """SCHEDULER local decides every photo's windows too: a DASK_SCHEDULER_ADDRESS naming no
    cluster (nothing listens on port 9) must not be contacted, and the orthos equal a run
    without the variable."""
    sc = scene.make_scene(tmp_path)
    common = {"PROJECT": sc.project_path, "DEM": sc.dem_path, "CELL_SIZE": 10.0,
              "OVERVIEWS": False, "SCHEDULER": "local"}
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    toolbox.run("ortho:batch", common | {"FOLDER": str(tmp_path / "plain"),
                                         "OUTPUT": tmp_path / "plain.json"})
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")
    out = toolbox.run("ortho:batch", common | {"FOLDER": str(tmp_path / "env"),
                                               "OUTPUT": tmp_path / "env.json"})
    assert out["STATISTICS"]["executor"].startswith("local threads")
    assert out["STATISTICS"]["done"] == 1
    with rasterio.open(tmp_path / "plain" / "p1.tif") as a, \
            rasterio.open(tmp_path / "env" / "p1.tif") as b:
        assert (a.read() == b.read()).all()


def test_a_photo_task_reports_its_warnings_to_its_caller_once(tmp_path, caplog):
    """A block task runs on a thread or a worker: its warnings travel in its report for
    ortho:batch to push once; the task itself logs nothing (they were printed twice)."""
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.block import OrthoTask, run_task
    from toolbox.ortho.plan import plan_photo
    from toolbox.ortho.run import OrthoOptions

    sc = scene.make_scene(tmp_path)
    half = scene.write_dem(tmp_path / "half.tif", sc.dem[:, : sc.dem.shape[1] // 2], sc.transform)
    dem = open_raster_info(half)
    plan = plan_photo(sc.photo, open_raster_info(sc.dem_path), sc.photo.crs, cell=10.0)
    task = OrthoTask(sc.photo, open_raster_info(sc.photo_path), dem, plan.grid,
                     tmp_path / "p1_ortho.tif", OrthoOptions(overviews=False), plan.mean_height)
    with caplog.at_level("INFO", logger="toolbox"):
        report = run_task(task)
    assert any("have no DEM height" in w for w in report["warnings"])
    assert not any("have no DEM height" in r.getMessage() for r in caplog.records)


def test_plans_on_threads_keep_the_photos_order_and_their_failures():
    """plan_each on 3 threads: the plans and the failures in the photos' order whichever
    thread finishes first (the later photos' plans return first here)."""
    import threading
    import time
    from types import SimpleNamespace

    from algorithms.ortho.batch import plan_each
    from toolbox.errors import InputDataError
    from toolbox.feedback import Feedback

    threads = set()

    def plan(item):
        threads.add(threading.get_ident())
        time.sleep(0.05 * (6 - int(item.id)))
        if item.id in ("2", "4"):
            raise InputDataError(f"photo {item.id} cannot be planned")
        return f"plan {item.id}"

    items = [SimpleNamespace(id=str(k)) for k in range(6)]
    failed: list = []
    feedback = Feedback()
    assert plan_each(items, plan, failed, feedback, workers=3) == \
        ["plan 0", "plan 1", "plan 3", "plan 5"]
    assert [f["photo"] for f in failed] == ["2", "4"] and len(threads) == 3
    assert feedback.warnings == ["photo 2 failed: photo 2 cannot be planned",
                                 "photo 4 failed: photo 4 cannot be planned"]
    with pytest.raises(InputDataError, match="no photo could be orthorectified"):
        plan_each(items[2:5:2], plan, [], Feedback(), workers=2)


def test_photo_windows_split_only_where_a_photo_may_run_alone():
    """Photos that fill the local pool run their windows on their own thread (1); the last
    ``count % workers`` photos, or a block smaller than the pool, split theirs; a Dask worker's
    photo keeps its worker's threads (None)."""
    from algorithms.ortho.batch import window_workers
    from toolbox.executor import Executor

    two = Executor("local", 2)
    assert [window_workers(k, 4, two) for k in range(4)] == [1, 1, 1, 1]
    assert [window_workers(k, 3, two) for k in range(3)] == [1, 1, 2]
    assert window_workers(0, 1, two) == 2
    assert [window_workers(k, 5, Executor("local", 1)) for k in range(5)] == [1] * 5
    assert window_workers(0, 4, Executor("dask", 2, "tcp://x:8786")) is None
