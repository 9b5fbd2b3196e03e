"""A Dask scheduler that does not answer, or that is lost mid-run, is one line and exit 3 (a
service failed: not the user's input, not a bug), with nothing written (issue 24 §5)."""

from __future__ import annotations

import socket
import threading
import time

import pytest
from click.testing import CliRunner

from toolbox.cli import main

pytestmark = pytest.mark.distributed


def _one_line(result) -> str:
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("toolbox: error: "), result.stderr
    assert "Traceback" not in result.stderr
    return lines[0]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_scheduler_that_does_not_answer(points_gpkg, tmp_path, monkeypatch):
    import dask
    import distributed  # noqa: F401  (its config defaults must exist before they are overridden)

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    out = tmp_path / "out"
    out.mkdir()
    address = f"tcp://127.0.0.1:{_free_port()}"  # nothing listens there
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        result = CliRunner().invoke(main, ["run", "dem:idw", "--INPUT", str(points_gpkg),
                                           "--CELL_SIZE", "5", "--SCHEDULER", address,
                                           "--OUTPUT", str(out / "dem.tif")])
        assert result.exit_code == 3, result.stderr
        line = _one_line(result)
        assert f"cannot connect to the Dask scheduler '{address}' (SCHEDULER)" in line
        # the standard variable names itself when it chose the address
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
        result = CliRunner().invoke(main, ["run", "dem:idw", "--INPUT", str(points_gpkg),
                                           "--CELL_SIZE", "5", "--OUTPUT", str(out / "dem.tif")])
    assert result.exit_code == 3 and "(DASK_SCHEDULER_ADDRESS)" in _one_line(result)
    assert list(out.iterdir()) == []


def test_a_scheduler_lost_mid_run(points_gpkg, tmp_path, monkeypatch):
    """The cluster is closed once the scheduler holds the run's first tasks."""
    from distributed import LocalCluster

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    out = tmp_path / "out"
    out.mkdir()
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp",
                           host="127.0.0.1", dashboard_address=None)
    closed = []

    def close_when_busy():
        deadline = time.monotonic() + 60
        while not cluster.scheduler.tasks and time.monotonic() < deadline:
            time.sleep(0.005)
        cluster.close()
        closed.append(True)

    watcher = threading.Thread(target=close_when_busy, daemon=True)
    watcher.start()
    try:  # a 5 cm grid: hundreds of tiles, far more than are in flight when the cluster goes
        result = CliRunner().invoke(main, ["run", "dem:idw", "--INPUT", str(points_gpkg),
                                           "--CELL_SIZE", "0.05", "--SCHEDULER",
                                           cluster.scheduler_address, "--OUTPUT",
                                           str(out / "dem.tif")])
    finally:
        watcher.join(60)
        cluster.close()
    assert closed and result.exit_code == 3, (result.exit_code, result.stderr)
    line = _one_line(result)
    assert "lost the connection to the Dask scheduler" in line and "nothing was written" in line
    assert list(out.iterdir()) == []
