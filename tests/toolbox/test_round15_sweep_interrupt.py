"""Round 15, interruption sweep: what a signal leaves on disk and what the command says.

- a batch interrupted at step 2 kept step 1's outputs but said "no output was written";
- a signal during the final moves undid a run that had finished writing, and one during the
  undo or the removal of the staging folder (a second Ctrl-C) left half of it (staging folders,
  the folders the run created);
- a signal that a library turns into its own error (lazrs: "Failed to call write") was an
  "internal error" (exit 3) instead of an interruption (128 + signal).
"""

from __future__ import annotations

import io
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from toolbox.cli.app import _handle_errors, _signals_as_interrupts
from toolbox.io import staging as staging_module
from toolbox.io.staging import OutputStaging


def _files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


def test_batch_interrupted_at_step_2_names_the_step_and_the_outputs_kept(tmp_path):
    import numpy as np

    rng = np.random.default_rng(0)  # a tilted plane of 4000 points over 1 km
    x, y = rng.uniform(0, 1000, (2, 4000))
    points = tmp_path / "points.csv"
    np.savetxt(points, np.c_[x + 500000, y + 4800000, 100 + 0.01 * x], delimiter=",",
               header="x,y,z", comments="", fmt="%.3f")
    out = tmp_path / "out"
    pipeline = tmp_path / "pipe.yaml"
    pipeline.write_text(
        "steps:\n"
        "- name: coarse\n  algorithm: dem:idw\n"
        "  params: {INPUT: points.csv, CRS: 'EPSG:32632', CELL_SIZE: 50, OUTPUT: out/coarse.tif}\n"
        "- name: grid\n  algorithm: dem:idw\n"
        "  params: {INPUT: points.csv, CRS: 'EPSG:32632', CELL_SIZE: 0.5, OUTPUT: out/dem.tif}\n")
    proc = subprocess.Popen([sys.executable, "-m", "toolbox.cli", "batch", str(pipeline)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not list(out.glob(".dem.tif.*.part")):
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    assert "during step 2 of 2 (dem:idw 'grid')" in lines[0], lines[0]
    assert str(out / "coarse.tif") in lines[0] and "kept" in lines[0], lines[0]
    assert "no output was written" not in lines[0], lines[0]
    assert _files(out) == ["coarse.tif"]  # step 1 stays (as documented), nothing of step 2


def _stage_two(tmp_path: Path) -> tuple[OutputStaging, list[Path]]:
    staging = OutputStaging(record=True)
    finals = [tmp_path / "new" / "a.txt", tmp_path / "new" / "b.txt"]
    for final in finals:
        staging.stage(final).write_text(final.name)
    return staging, finals


def test_a_signal_during_the_final_moves_waits_until_the_files_are_in_place(
        tmp_path, monkeypatch, capsys):
    staging, finals = _stage_two(tmp_path)
    real_move = staging_module._move_no_replace

    def move_then_signal(source, target):  # the first move of the commit: SIGTERM comes
        real_move(source, target)
        if target == finals[0]:
            signal.raise_signal(signal.SIGTERM)

    monkeypatch.setattr(staging_module, "_move_no_replace", move_then_signal)

    @_handle_errors
    def command():
        try:
            staging.commit(overwrite=False)
        finally:
            staging.rollback()

    with pytest.raises(SystemExit) as exit_info:
        command()
    assert exit_info.value.code == 128 + signal.SIGTERM
    assert [f.read_text() for f in finals] == ["a.txt", "b.txt"]  # the whole commit
    assert _files(tmp_path) == ["new", "new/a.txt", "new/b.txt"]  # no staging folder left
    message = capsys.readouterr().err.strip()
    assert message.startswith("toolbox: terminated by SIGTERM; written before it and kept: ")
    assert str(finals[0]) in message and str(finals[1]) in message, message


def test_a_second_signal_during_the_cleanup_still_removes_everything(tmp_path, monkeypatch):
    staging, _ = _stage_two(tmp_path)
    real_rmtree = staging_module.shutil.rmtree
    sent = []

    def rmtree_after_a_signal(path, *args, **kwargs):  # Ctrl-C again while cleaning up
        if not sent:
            sent.append(path)
            signal.raise_signal(signal.SIGINT)
        real_rmtree(path, *args, **kwargs)

    monkeypatch.setattr(staging_module.shutil, "rmtree", rmtree_after_a_signal)
    with _signals_as_interrupts(), pytest.raises(KeyboardInterrupt):
        staging.rollback()
    assert sent and _files(tmp_path) == []  # staging folders and the folder "new" removed


def test_an_interruption_a_library_turns_into_its_own_error_is_an_interruption(capsys):
    laspy = pytest.importorskip("laspy")
    pytest.importorskip("lazrs")
    import numpy as np

    class Output(io.BytesIO):  # SIGTERM while lazrs calls write(): it raises LazrsError
        sent = False

        def write(self, data):
            if len(data) > 512 and not self.sent:
                self.sent = True
                signal.raise_signal(signal.SIGTERM)
            return super().write(data)

    @_handle_errors
    def command():
        header = laspy.LasHeader(point_format=6, version="1.4")
        points = laspy.LasData(header)
        points.x = points.y = points.z = np.linspace(0, 1, 100_000)
        with laspy.open(Output(), mode="w", header=header, do_compress=True, closefd=False,
                        laz_backend=laspy.LazBackend.Lazrs) as writer:
            writer.write_points(points.points)

    with pytest.raises(SystemExit) as exit_info:
        command()
    assert exit_info.value.code == 128 + signal.SIGTERM  # not 3, "internal error"
    assert capsys.readouterr().err.strip() == "toolbox: terminated by SIGTERM; no output was written"


def test_a_laz_output_on_a_full_disk_is_a_write_error(tmp_path):
    """lazrs reports a failed write as its own "IoError: Failed to call write" (no cause kept):
    it was exit 3, "internal error"; the disk tells why, as for the other libraries."""
    laspy = pytest.importorskip("laspy")
    pytest.importorskip("lazrs")
    import numpy as np

    from tests.helpers_cli import run_on_full_disk

    rng = np.random.default_rng(1)
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales, header.offsets = [0.01] * 3, [500000, 4800000, 0]
    points = laspy.LasData(header)
    points.x = 500000 + rng.uniform(0, 200, 40000)
    points.y = 4800000 + rng.uniform(0, 200, 40000)
    points.z = 100 + rng.normal(0, 0.05, 40000)
    points.write(tmp_path / "points.laz")  # 177 kB; the rasters of a 2 m grid: a few kB
    out = tmp_path / "out"
    proc = run_on_full_disk(["dem:ground", "--INPUT", str(tmp_path / "points.laz"), "--CRS",
                             "EPSG:32632", "--FILTER_CELL", "2", "--OUTPUT", str(out / "dtm.tif"),
                             "--NONGROUND", str(out / "ng.tif"), "--GROUND_POINTS",
                             str(out / "ground.laz"), "--quiet"], limit=120_000)
    errors = [line for line in proc.stderr.splitlines() if not line.startswith("WARNING")]
    assert proc.returncode == 2, proc.stderr
    assert len(errors) == 1 and errors[0].startswith(
        f"toolbox: error: cannot write GROUND_POINTS '{out / 'ground.laz'}'"), proc.stderr
    assert not out.exists()


def test_a_signal_a_library_swallows_still_stops_the_run(tmp_path):
    """pyogrio's reading loop swallows the exception a signal handler raises in it (a batch
    step SIGTERMed while reading its points ran on and exited 0, about 1 in 4): the signal also
    cancels the run, whose check before the commit stops it."""
    from tests.helpers_cli import cli, register_testing
    from toolbox.parameters import OutputFile

    def process(self, params, feedback):
        params["OUTPUT"].write_text("complete")
        try:  # a library's loop that swallows the exception
            signal.raise_signal(signal.SIGTERM)
        except KeyboardInterrupt:
            pass
        return {}

    register_testing("swallower", OutputFile("OUTPUT", extensions=[".txt"]), process,
                     "Reads with a library that swallows a signal's exception.")
    code, out, err = cli("run", "testing:swallower", "--OUTPUT", tmp_path / "new" / "a.txt")
    assert code == 128 + signal.SIGTERM, (code, out, err)
    assert err.strip() == "toolbox: terminated by SIGTERM; no output was written"
    assert list(tmp_path.iterdir()) == []


def test_a_swallowed_signal_is_named_in_the_json_progress_error(tmp_path):
    """With --progress json, the error record of a run a swallowed signal stopped said "run
    canceled by the user" (the exit code and the stderr line were right): it names the
    signal as the stderr line does."""
    import json

    from tests.helpers_cli import cli, register_testing
    from toolbox.parameters import OutputFile

    def process(self, params, feedback):
        params["OUTPUT"].write_text("complete")
        try:
            signal.raise_signal(signal.SIGTERM)
        except KeyboardInterrupt:
            pass
        feedback.check_canceled()  # the algorithm's own next check
        return {}

    register_testing("swallower2", OutputFile("OUTPUT", extensions=[".txt"]), process,
                     "Reads with a library that swallows a signal's exception.")
    code, out, err = cli("run", "testing:swallower2", "--progress", "json",
                         "--OUTPUT", tmp_path / "a.txt")
    assert code == 128 + signal.SIGTERM, (code, out, err)
    records = [json.loads(line) for line in err.splitlines() if line.startswith("{")]
    texts = " ".join(json.dumps(r) for r in records)
    assert "terminated by SIGTERM" in texts and "canceled by the user" not in texts, texts
    assert not (tmp_path / "a.txt").exists()
