"""Round 17, leftovers: staging folders of killed runs, judged by host, boot and start time."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

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
