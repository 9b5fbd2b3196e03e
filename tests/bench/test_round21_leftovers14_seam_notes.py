"""``bench/mosaic_bench.py`` rewrites only the parts of its results file it generates: the notes
the lead writes after a sitting (under the one-seam timings' table, between the sections) are
kept. Before, ``--seam-only`` replaced everything from its section's heading to the end of the
file, and the round notes under its table went with it. Checked on a copy of the repository's
file (the measurements stubbed; the bench never runs on the repository's file)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

pytest.importorskip("cv2")
pytest.importorskip("skimage")
import mosaic_bench  # noqa: E402

NOTE = "Round twenty-two (a note written by hand after a sitting, under the table)."
LATE = "Round twenty-two, a last note at the end of the file."


def _run(monkeypatch, tmp_path, stamp: str, seam_only: bool = True) -> str:
    """The bench's ``main`` on ``tmp_path/results/mosaic.md``, every measurement stubbed."""
    monkeypatch.setattr(mosaic_bench, "HERE", tmp_path)
    monkeypatch.setattr(mosaic_bench, "make_pair", lambda work, n: None)
    monkeypatch.setattr(mosaic_bench, "make_block", lambda work, n: None)
    monkeypatch.setattr(mosaic_bench, "gdalwarp_mosaic", lambda work: None)
    monkeypatch.setattr(mosaic_bench, "load_note", lambda: "CPU 1% busy in the second before "
                        "the start: quiet machine")
    monkeypatch.setattr(mosaic_bench, "machine_facts", lambda *versions: f"{stamp}, 2 cores (X)")
    monkeypatch.setattr(mosaic_bench, "measure", lambda name, work, n: _stub_cv() if
                        name == "seam_compare" else {"seconds": 1.0, "peak_mb": 2.0})
    mosaic_bench.main(False, seam_only=seam_only)
    return (tmp_path / "results" / "mosaic.md").read_text()


def _stub_cv() -> dict:
    """What the one-seam case measures, every time 0.1 s."""
    return {"times": {k: {"wall": [0.1], "cpu": [0.1]} for k in (
              "kernel_ours", "kernel_dp", "e2e_ours", "e2e_dp", "e2e_dp_written")},
          "graphcut": {"wall": 7.0, "cpu": 7.0}, "load": (0.5, 0.5), "path_cost": 1.0,
          "exact_cost": 1.0,
          "quality": {k: {"edges": 10, "colour": 1.0, "balanced": 0.5, "cost": 0.1,
                          "on_buildings": 0} for k in (
              "kernel_ours", "exact_optimum", "e2e_ours", "kernel_dp", "graphcut",
              "kernel_ours_heights", "e2e_ours_heights")}}


def test_seam_only_keeps_the_notes_under_its_table(monkeypatch, tmp_path):
    original = (BENCH / "results" / "mosaic.md").read_text()
    notes = [p for p in original.split("\n\n") if p.startswith(("Round twenty", "Round nineteen",
                                                                "Round thirteen"))]
    assert notes  # the repository's round notes, some under the seam table
    table_end = original.index("<!-- /mosaic_bench: seam_times")  # the table's end marker
    table_end = original.index("\n", table_end)
    ours = original[:table_end] + "\n\n" + NOTE + original[table_end:] + "\n" + LATE + "\n"
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "mosaic.md").write_text(ours)
    first = _run(monkeypatch, tmp_path, "2031-01-01")
    second = _run(monkeypatch, tmp_path, "2031-01-02")
    for text in (first, second):
        for note in [*notes, NOTE, LATE]:
            assert text.count(note) == 1, note[:60]
        # the timings' table is the stub's, the notes still under it, then the quality table
        assert text.index("| (a) kernel on the same arrays | ours | cost surface + centre term "
                          "+ route (overlap 1000 x 1000, coarse-to-fine) | 0.100 |") < \
            text.index(NOTE) < text.index("Round twenty, quiet machine") < \
            text.index("| ours, kernel | 10 | 1.00 | 0.500 |") < text.index(LATE)
        assert "| ours, kernel | 1010 |" not in text and "| 7.60 | 7.61 |" not in text
    assert "2031-01-01" not in second and second.count("2031-01-02") == 1
    # everything before the seam section, the full run's table and notes, as it was
    head = ours.split("<!-- mosaic_bench: seam_times")[0]
    assert second.startswith(head)


def test_rewriting_keeps_text_outside_the_markers_and_refuses_broken_ones():
    from benchlib import generated_markers, rewrite_generated

    (s1, e1), (s2, e2) = generated_markers("b", "one"), generated_markers("b", "two")
    old = (f"# T\n\n{s1}\n\nold 1\n\n{e1}\n\nhand note\n\n{s2}\n\nold 2\n\n{e2}\n\n"
           "tail note\n")
    new = rewrite_generated(old, "b", {"one": ["new 1", ""], "two": ["", "new 2"]})
    assert new == old.replace("old 1", "new 1").replace("old 2", "new 2")
    assert rewrite_generated(new, "b", {"one": ["new 1"], "two": ["new 2"]}) == new
    # a part the file lacks is appended; nothing is dropped
    s3, e3 = generated_markers("b", "three")
    assert rewrite_generated("# T\n\nnotes\n", "b", {"three": ["x"]}) == \
        f"# T\n\nnotes\n\n{s3}\n\nx\n\n{e3}\n"
    for broken in (old.replace(e1, ""), old.replace(s2, e2, 1), old + s1 + "\n"):
        with pytest.raises(ValueError, match="markers"):
            rewrite_generated(broken, "b", {"one": ["x"], "two": ["y"]})


def test_full_run_keeps_the_notes_too(monkeypatch, tmp_path):
    """The full run rewrote the whole file: the round notes under its first table went too."""
    original = (BENCH / "results" / "mosaic.md").read_text()
    notes = [p for p in original.split("\n\n") if p.startswith("Round ")]
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "mosaic.md").write_text(original)
    text = _run(monkeypatch, tmp_path, "2031-01-01", seam_only=False)
    for note in notes:
        assert text.count(note) == 1, note[:60]
    assert "| least-cost seamline (overview + corridor) | 10000 x 10000 overlap | " \
        "mosaic:seamlines | 1.0 | 2 |" in text and "| 12.6 | 656 |" not in text
    assert text.startswith("## Mosaics (`bench/mosaic_bench.py`)\n\n<!-- mosaic_bench: summary")
    assert text.count("2031-01-01") == 1  # the summary's facts; the seam parts share them
