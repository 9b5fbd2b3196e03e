"""Round 17, leftovers: staging folders of killed runs, judged by host, boot and start time."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

import toolbox
from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.io.staging import (
    OutputStaging,
    machine_tag,
    process_start,
    staging_leftovers,
    stale_staging_folders,
)

ALG_WITH_LAYERS = "carto:sheet"  # LAYERS: a MultipleLayers of vector layers
GONE_PID = 2**22 + 41  # above Linux's largest pid: no such process


def _dem(path, n=16):
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs="EPSG:32632", transform=from_origin(500000, 5000160, 10, 10)) as dst:
        dst.write(np.arange(n * n, dtype="float32").reshape(n, n), 1)


# -- 1. a kill -9 leaves a staging folder: the next run of any algorithm into the folder removes it
def test_a_killed_runs_staging_folder_goes_with_the_next_run_into_that_folder(tmp_path):
    """A process staging ortho.tif (3 MB written) is killed by SIGKILL; a hillshade of another
    name into the same folder removes its staging folder and says so in one info line with the
    space freed (before: it stayed until a run wrote ortho.tif again)."""
    child = textwrap.dedent(f"""
        import os, signal
        from toolbox.io.staging import OutputStaging
        staged = OutputStaging().stage({str(tmp_path / "ortho.tif")!r})
        staged.write_bytes(os.urandom(3_000_000))
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    proc = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    left = [p for p in tmp_path.iterdir() if p.name.startswith(".ortho.tif.")]
    assert len(left) == 1 and (left[0] / "ortho.tif").stat().st_size == 3_000_000
    _dem(tmp_path / "dem.tif")
    feedback = Feedback()
    toolbox.run("dem:hillshade", {"INPUT": str(tmp_path / "dem.tif"),
                                  "OUTPUT": str(tmp_path / "hs.tif")}, feedback=feedback)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif", "hs.tif"]
    infos = [text for level, text in feedback.messages if level == "info" and "staging" in text]
    assert len(infos) == 1 and str(left[0]) in infos[0] and "3.0 MB freed" in infos[0], infos


# -- 2. judged by host, boot and the process's start time, not the PID alone -------------------
def test_a_reused_pid_does_not_keep_a_dead_runs_folder(tmp_path):
    """The PID of a live process (our parent) recorded with another start time: the run that
    made the folder is gone (the PID was given again). With the right start time: running."""
    pid = os.getppid()
    start = process_start(pid)
    assert start
    reused = tmp_path / f".a.tif.{pid}-{start + 1}-{machine_tag()}.abcd1234.part"
    running = tmp_path / f".b.tif.{pid}-{start}-{machine_tag()}.abcd1234.part"
    reused.mkdir()
    running.mkdir()
    assert stale_staging_folders(tmp_path / "c.tif") == [reused]


def test_another_hosts_staging_folder_is_left_alone(tmp_path):
    """A folder made on another host (its PID means nothing here) is never removed; one not
    changed for more than a day gets a warning naming it and its age."""
    other = "f" * 12 if machine_tag() != "f" * 12 else "e" * 12
    fresh = tmp_path / f".a.tif.{GONE_PID}-123-{other}.abcd1234.part"
    old = tmp_path / f".b.tif.{GONE_PID}-456-{other}.abcd1234.part"
    mine = tmp_path / f".c.tif.{GONE_PID}-789-{machine_tag()}.abcd1234.part"  # this host: gone
    for folder in (fresh, old, mine):
        folder.mkdir()
    three_days = time.time() - 3 * 86400
    os.utime(old, (three_days, three_days))
    assert staging_leftovers([tmp_path])[0] == [mine]
    _dem(tmp_path / "dem.tif")
    feedback = Feedback()
    toolbox.run("dem:hillshade", {"INPUT": str(tmp_path / "dem.tif"),
                                  "OUTPUT": str(tmp_path / "hs.tif")}, feedback=feedback)
    assert fresh.exists() and old.exists() and not mine.exists()
    warned = [w for w in feedback.warnings if "staging folder" in w]
    assert len(warned) == 1 and str(old) in warned[0] and "3 days old" in warned[0], warned


def test_own_staging_folders_are_named_with_host_boot_and_start_time(tmp_path):
    staging = OutputStaging()
    staged = staging.stage(tmp_path / "x.tif")
    pid = os.getpid()
    assert staged.parent.name.startswith(f".x.tif.{pid}-{process_start(pid)}-{machine_tag()}.")
    assert stale_staging_folders(tmp_path / "x.tif") == []  # this run's own: running
    staging.rollback()
    assert list(tmp_path.iterdir()) == []


# -- 3. a named pipe (socket, device) as an input: refused before GDAL's open blocks on it -----
def _cli(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "toolbox.cli", "run", *args],
                          capture_output=True, text=True, timeout=timeout)


def test_a_named_pipe_as_an_input_is_refused_before_it_is_opened(tmp_path):
    """GDAL's open of a FIFO waits for a writer forever (the run hung until killed); it is
    refused with exit 2, naming the parameter, the path and what it is."""
    fifo = tmp_path / "dem.tif"
    os.mkfifo(fifo)
    proc = _cli("dem:hillshade", "--INPUT", str(fifo), "--OUTPUT", str(tmp_path / "hs.tif"),
                timeout=30)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert "INPUT" in lines[0] and str(fifo) in lines[0], lines
    assert "a named pipe; give a regular file" in lines[0], lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif"]


def test_a_named_pipe_given_as_a_layer_reference_or_in_a_list_is_refused(tmp_path):
    fifo = tmp_path / "points.gpkg"
    os.mkfifo(fifo)
    with_layer = _cli("vector:info", "--INPUT", f"{fifo}|layername=a", timeout=30)
    assert with_layer.returncode == 2 and "a named pipe" in with_layer.stderr, with_layer.stderr
    with pytest.raises(ParameterError, match="a named pipe; give a regular file") as caught:
        toolbox.validate(ALG_WITH_LAYERS, {"LAYERS": [str(fifo)]})
    assert caught.value.name == "LAYERS" and str(fifo) in str(caught.value)


# -- 4. tasks of runs from two folders on one Dask worker: each reads its own folder's files ----
def test_tasks_of_two_client_folders_on_one_worker_read_their_own_files(tmp_path, monkeypatch):
    """A worker's threads share one working folder: with two runs from two folders on one
    cluster, a task of one changed it under a task of the other, which read the other folder's
    'dem.txt' (a wrong result, exit 0). Tasks of another folder now wait their turn."""
    from concurrent.futures import ThreadPoolExecutor

    from toolbox.executor import _in_client_folder

    monkeypatch.chdir(tmp_path)
    for name in "AB":
        (tmp_path / name).mkdir()
        (tmp_path / name / "dem.txt").write_text(name)

    def task(_):
        time.sleep(0.005)  # another thread's task starts meanwhile
        with open("dem.txt") as f:
            return f.read()

    folders = [name for _ in range(20) for name in "AB"]
    with ThreadPoolExecutor(6) as pool:
        read = list(pool.map(lambda name: _in_client_folder(str(tmp_path / name), task, None),
                             folders))
    assert read == folders


def test_a_worker_keeps_two_folders_rasters_apart_however_alike(tmp_path, monkeypatch):
    """'dem.tif' of two folders, same size and modification time, different heights: the
    worker's open datasets are keyed by absolute path, so the second run reads its own."""
    from toolbox.raster.datasets import WorkerDatasets

    for k, name in enumerate("AB"):
        (tmp_path / name).mkdir()
        with rasterio.open(tmp_path / name / "dem.tif", "w", driver="GTiff", width=4, height=4,
                           count=1, dtype="float32") as dst:
            dst.write(np.full((4, 4), k, "float32"), 1)
        os.utime(tmp_path / name / "dem.tif", ns=(10**18, 10**18))
    datasets = WorkerDatasets()
    read = []
    for name in "AB":
        monkeypatch.chdir(tmp_path / name)
        read.append(float(datasets.get("dem.tif").read(1)[0, 0]))
    assert read == [0.0, 1.0]


# -- 5. mosaic:build's scratch source index: in the output's staging folder, no overviews -------
def test_mosaic_scratch_index_lives_in_the_staging_folder_without_overviews(tmp_path,
                                                                            monkeypatch):
    """Without SOURCE_INDEX, the index the seams come from was written in the client's /tmp with
    overviews, which on a Dask cluster a worker built (reading the client's /tmp: a worker on
    another machine cannot). It now goes in the output's staging folder, without overviews
    (read once, at full resolution), and is gone after the run."""
    import toolbox.mosaic.index_seams as index_seams
    from toolbox.demo.samples.mosaic import make_block

    specs = [{"name": f"g{c}", "bounds": (200 * c, 0, 200 * c + 260, 260),
              "nadir": (200 * c + 130, 130), "gain": 1.0} for c in range(2)]
    orthos, _ = make_block(tmp_path / "block", specs)
    seen = []
    read = index_seams.index_raster_seams

    def spy(path):
        with rasterio.open(path) as src:
            seen.append((Path(path), src.overviews(1)))
        return read(path)

    monkeypatch.setattr(index_seams, "index_raster_seams", spy)
    out = tmp_path / "out"
    toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos],
                                 "SEAMLINES": out / "seams.gpkg", "OUTPUT": out / "mosaic.tif"})
    (path, overviews), = seen
    assert path.parent.parent.parent == out and path.parent.parent.name.startswith(".mosaic.tif.")
    assert overviews == [] and not path.exists()
    assert sorted(p.name for p in out.iterdir()) == ["mosaic.tif", "seams.gpkg"]
