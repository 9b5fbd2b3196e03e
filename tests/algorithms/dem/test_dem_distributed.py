"""Tile execution: toolbox.executor on threads, and DEM gridding on a Dask LocalCluster of 2 worker
processes giving the same file, byte for byte, as the local run."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import threading
import time

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from toolbox.errors import CanceledError, ParameterError, ServiceError
from toolbox.executor import map_tiles, resolve_executor, scheduler_address
from toolbox.feedback import Feedback

X0, Y0 = 1_688_000.0, 4_799_500.0


def _slow_square(i: int) -> int:
    time.sleep(0.002 * ((7 * i) % 5))  # finish out of order
    return i * i


def test_map_tiles_keeps_task_order_and_bounds_prefetch():
    assert list(map_tiles(_slow_square, range(40), workers=4)) == [i * i for i in range(40)]
    assert list(map_tiles(_slow_square, range(5), workers=1)) == [0, 1, 4, 9, 16]
    pulled = []
    in_flight = []

    def tasks():
        for i in range(30):
            pulled.append(i)
            yield i

    for i, _ in enumerate(map_tiles(_slow_square, tasks(), workers=2, prefetch=3)):
        in_flight.append(len(pulled) - i)
    assert max(in_flight) <= 3  # never more than `prefetch` tasks ahead of the results


def test_map_tiles_progress_and_cancel():
    seen = []
    feedback = Feedback(lambda pct, msg: seen.append(pct))
    list(map_tiles(_slow_square, range(8), workers=2, feedback=feedback, total=8, start=10,
                   end=50))
    assert seen[-1] == 50 and all(10 <= p <= 50 for p in seen)
    feedback = Feedback()
    done = []

    def work(i):
        done.append(i)
        if i == 3:
            feedback.cancel()
        return i

    with pytest.raises(CanceledError):
        list(map_tiles(work, range(1000), workers=2, feedback=feedback, prefetch=4))
    assert len(done) < 20  # stopped soon after the request


def test_scheduler_resolution(monkeypatch):
    # dask reads DASK_* variables into its configuration once, when imported: import it before
    # the variable is set here, or the address below would stay configured for later tests
    import dask
    import distributed  # noqa: F401  (its config defaults must exist before they are overridden)

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    assert scheduler_address(None) is None
    assert resolve_executor(None, 3).describe() == "local threads (3)"
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://10.0.0.5:8786")
    assert scheduler_address(None) == "tcp://10.0.0.5:8786"
    assert scheduler_address("local") is None  # explicit local wins over the variable
    assert resolve_executor("tcp://h:1").kind == "dask"
    with pytest.raises(ParameterError, match="SCHEDULER must be a Dask scheduler address"):
        resolve_executor("nonsense")
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}), \
            pytest.raises(ServiceError, match="cannot connect"):  # exit 3: not the user's input
        list(map_tiles(_slow_square, range(2), scheduler="tcp://127.0.0.1:9"))


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.distributed
def test_dask_cluster_output_is_byte_identical_to_local(tmp_path, monkeypatch):
    from distributed import LocalCluster

    rng = np.random.default_rng(17)
    xy = np.column_stack([X0 + rng.uniform(0, 400, 3000), Y0 + rng.uniform(0, 300, 3000)])
    z = 300 + 10 * np.sin((xy[:, 0] - X0) / 50) * np.cos((xy[:, 1] - Y0) / 40)
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z),
                     crs="EPSG:3003").to_file(tmp_path / "pts.gpkg")
    common = {"INPUT": tmp_path / "pts.gpkg", "CELL_SIZE": 4, "TILE_SIZE": 32}
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        for alg in ("dem:idw", "dem:quadratic", "dem:tin_linear"):
            local = toolbox.run(alg, common | {"OUTPUT": tmp_path / f"{alg[4:]}_local.tif"})
            remote = toolbox.run(alg, common | {"SCHEDULER": cluster.scheduler_address,
                                                "OUTPUT": tmp_path / f"{alg[4:]}_dask.tif"})
            assert remote["STATISTICS"]["cells"]["executor"].startswith("dask scheduler")
            assert local["STATISTICS"]["cells"]["executor"].startswith("local threads")
            assert remote["STATISTICS"]["cells"]["tiles"] == 12  # 100 x 75 cells, 32-cell tiles
            assert _sha(tmp_path / f"{alg[4:]}_local.tif") == _sha(tmp_path / f"{alg[4:]}_dask.tif")
        # the standard Dask variable selects the cluster when SCHEDULER is not given
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster.scheduler_address)
        env = toolbox.run("dem:idw", common | {"OUTPUT": tmp_path / "env.tif"})
        assert env["STATISTICS"]["cells"]["executor"] == f"dask scheduler {cluster.scheduler_address}"
        assert _sha(tmp_path / "env.tif") == _sha(tmp_path / "idw_local.tif")
    assert threading.active_count() < 50


def test_dask_is_imported_only_when_something_may_configure_it(tmp_path):
    """No DASK_* variable and no Dask config folder: local threads without importing dask;
    a ``scheduler-address`` in ``~/.config/dask/*.yaml`` is still honoured."""
    if any(os.path.exists(os.path.join(prefix, "etc", "dask")) for prefix in ("/", sys.prefix)):
        pytest.skip("this machine has a Dask configuration folder")
    script = ("import json, sys\nfrom toolbox.executor import scheduler_address\n"
              "print(json.dumps([scheduler_address(None), 'dask' in sys.modules]))")
    env = {k: v for k, v in os.environ.items() if not k.startswith("DASK_")}
    env["HOME"] = str(tmp_path)

    def resolve():
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                              env=env, check=True)
        return json.loads(done.stdout.splitlines()[-1])

    assert resolve() == [None, False]
    (tmp_path / ".config" / "dask").mkdir(parents=True)
    (tmp_path / ".config" / "dask" / "cluster.yaml").write_text(
        "scheduler-address: tcp://10.1.2.3:8786\n")
    assert resolve() == ["tcp://10.1.2.3:8786", True]
