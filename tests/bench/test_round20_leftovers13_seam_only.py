"""``bench/mosaic_bench.py --seam-only`` rewrites its own section of the results file: it kept
the previous run's machine-facts and load-note lines (written just before the section) and
added its own, so every rerun left one more copy of them. Run twice on a copy of the repository's
results file (the measurements stubbed), the file holds one copy of each and the rest of the
file is untouched."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

pytest.importorskip("cv2")
pytest.importorskip("skimage")
import mosaic_bench  # noqa: E402


def fake_run(monkeypatch, tmp_path, facts, note, parts):
    monkeypatch.setattr(mosaic_bench, "HERE", tmp_path)
    monkeypatch.setattr(mosaic_bench, "make_pair", lambda work, n: None)
    monkeypatch.setattr(mosaic_bench, "measure", lambda name, work, n: {})
    monkeypatch.setattr(mosaic_bench, "load_note", lambda: note)
    monkeypatch.setattr(mosaic_bench, "machine_facts", lambda *versions: facts)
    monkeypatch.setattr(mosaic_bench, "seam_section", lambda cv, n: {k: list(v)
                                                                      for k, v in parts.items()})
    mosaic_bench.main(False, seam_only=True)
    return (tmp_path / "results" / "mosaic.md").read_text()


def test_seam_only_replaces_its_section_and_its_facts(monkeypatch, tmp_path):
    original = (BENCH / "results" / "mosaic.md").read_text()
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "mosaic.md").write_text(original)
    head = original.split("<!-- mosaic_bench: seam_times")[0]
    parts = {"seam_times": ["### One seam, 1000 x 1000 overlap (stub)", "", "| stub | table |"],
             "seam_quality": ["Seam quality (stub)"]}
    first = fake_run(monkeypatch, tmp_path, "2031-01-01, 2 cores (X), Python 3.11.7",
                     "CPU 3% busy in the second before the start: quiet machine", parts)
    second = fake_run(monkeypatch, tmp_path, "2031-01-02, 2 cores (X), Python 3.11.7",
                      "CPU 4% busy in the second before the start: quiet machine", parts)
    # one facts line and one note for the seam section: the second run's
    assert "2031-01-01" not in second and second.count("2031-01-02") == 1
    assert second.count("busy in the second before the start") == \
        head.count("busy in the second before the start") + 1  # the full run's note, then ours
    assert second.count("### One seam,") == 1
    assert "2031-01-02, 2 cores (X), Python 3.11.7\n\nCPU 4% busy in the second before the "\
        "start: quiet machine\n\n### One seam, 1000 x 1000 overlap (stub)" in second
    # the rest of the file (the full run's table and notes) is kept as it was
    assert second.startswith(head)
    assert first.replace("2031-01-01", "2031-01-02").replace("CPU 3%", "CPU 4%") == second


def test_seam_only_on_a_file_without_the_section_keeps_it_whole():
    old = "## Mosaics (`bench/mosaic_bench.py`)\n\n2026-12-04, 2 cores (X)\n\nsome text\n"
    text = mosaic_bench.rewrite_results(old, {"seam_times": ["F", "", "N", "", "### One seam, x"]})
    from benchlib import generated_markers

    start, end = generated_markers(mosaic_bench.TAG, "seam_times")
    assert text == old.rstrip("\n") + f"\n\n{start}\n\nF\n\nN\n\n### One seam, x\n\n{end}\n"
