"""Interruptions: SIGINT, SIGTERM and SIGHUP while an output is being written leave nothing (exit
128 + signal); after SIGKILL, which no program can catch, the next run to the same path removes
the dead run's staging folder and says so.

Real processes and real signals: a 0.5 m IDW DEM of the demo mass points (a few seconds of tiled
work), interrupted as soon as its staged GeoTIFF appears. The runs go in parallel.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import trust_data

from toolbox.io.staging import OutputStaging, stale_staging_folders

SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGKILL]


@pytest.fixture(scope="module")
def mass_points():
    return Path(trust_data.demo()[1]["mass_points"])


def _start(points: Path, output: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "toolbox.cli", "run", "dem:idw", "--INPUT", str(points),
         "--CELL_SIZE", "0.5", "--OUTPUT", str(output)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def _staged_file(output: Path) -> Path | None:
    if not output.parent.exists():
        return None
    for folder in output.parent.glob(f".{output.name}.*.part"):
        if (folder / output.name).exists():
            return folder / output.name
    return None


def test_signals_during_a_write_leave_nothing(mass_points, tmp_path):
    runs = {}
    for sig in SIGNALS:
        output = tmp_path / sig.name / "new_folder" / "dem.tif"  # the run creates new_folder
        runs[sig] = (output, _start(mass_points, output))
    pending = dict(runs)
    deadline = time.monotonic() + 120
    while pending and time.monotonic() < deadline:  # signal each run once it writes
        for sig, (output, proc) in list(pending.items()):
            assert proc.poll() is None, f"{sig.name} run ended before writing: {proc.stderr.read()}"
            if _staged_file(output) is not None:
                proc.send_signal(sig)
                del pending[sig]
        time.sleep(0.02)
    assert not pending, "no staged output appeared in 120 s"
    for sig, (_, proc) in runs.items():
        _, stderr = proc.communicate(timeout=120)
        if sig == signal.SIGKILL:
            assert proc.returncode == -signal.SIGKILL
            continue
        assert proc.returncode == 128 + sig, (sig.name, proc.returncode, stderr)
        lines = stderr.strip().splitlines()
        assert len(lines) == 1 and "no output was written" in lines[0], stderr
        assert "Traceback" not in stderr
        assert not (tmp_path / sig.name / "new_folder").exists(), \
            f"{sig.name} left {list((tmp_path / sig.name).rglob('*'))}"

    # SIGKILL: the staging folder stays (nothing can remove it then) ...
    output = runs[signal.SIGKILL][0]
    left = list(output.parent.glob(f".{output.name}.*.part"))
    assert len(left) == 1 and left[0].is_dir()
    # ... and the next run to the same path removes it, with an info line
    proc = subprocess.run(
        [sys.executable, "-m", "toolbox.cli", "-v", "run", "dem:idw", "--INPUT", str(mass_points),
         "--CELL_SIZE", "25", "--OUTPUT", str(output)], capture_output=True, text=True,
        timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "removed" in proc.stderr and left[0].name in proc.stderr, proc.stderr
    assert sorted(p.name for p in output.parent.iterdir()) == ["dem.tif"]


def test_stale_folder_of_a_live_process_is_kept(tmp_path):
    final = tmp_path / "a.tif"
    dead = tmp_path / f".a.tif.{2**22 + 17}.x1y2.part"  # above Linux's largest pid: gone
    alive = tmp_path / f".a.tif.{os.getppid()}.x1y2.part"  # our parent: running
    other = tmp_path / f".b.tif.{2**22 + 17}.x1y2.part"  # another output's: not ours to judge
    for folder in (dead, alive, other):
        folder.mkdir()
    assert stale_staging_folders(final) == [dead]
    staging = OutputStaging()
    staging.stage(final)
    assert staging.removed_stale == [dead] and not dead.exists()
    assert alive.exists() and other.exists()
    staging.rollback()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name, other.name])
