"""Round 25: a small TIN's R-trees are packed at the end, two at once
(``gpkg_bulk.write_rtrees_bulk``), a big TIN's each after its layer's rows. Both ways give the
same file contents, which GDAL's writer is the oracle of (test_round21_tinbulk); SQLite's R-tree
check accepts them; a refusal while they are written falls back to GDAL."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pyogrio
import pytest

from toolbox.io.crs import parse_crs
from toolbox.terrain.tin import store
from toolbox.terrain.tin.build import build_tin

X0, Y0 = 1688000.0, 4799000.0
LAYERS = ("triangles", "nodes", "edges")


def _model(n: int, seed: int):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 800, (n, 2)) + [X0, Y0]
    lines = np.array([[X0 + 50, Y0 + 50, 310.0], [X0 + 650, Y0 + 700, 330.0]])
    return build_tin(np.c_[xy, 300 + rng.normal(0, 1, n)], lines, np.array([0, 0]))


def _tables(path: Path) -> dict[str, list[tuple]]:
    """Every table's rows but the timestamps of gpkg_contents and the styles."""
    with sqlite3.connect(path) as db:
        names = [n for (n,) in db.execute("SELECT name FROM sqlite_master WHERE type = 'table' "
                                          "AND name NOT IN ('gpkg_contents', 'layer_styles')")]
        return {n: db.execute(f'SELECT * FROM "{n}" ORDER BY 1').fetchall() for n in names}


def test_rtrees_packed_together_or_one_by_one_are_the_same_file(tmp_path, monkeypatch):
    model, crs = _model(6000, 1), parse_crs("EPSG:3003")
    together, one_by_one = tmp_path / "together.gpkg", tmp_path / "one_by_one.gpkg"
    calls = []
    from toolbox.io import gpkg_bulk

    original = gpkg_bulk.write_rtrees_bulk

    def counted(path, rtrees):
        calls.append(sorted(r.rtree for r in rtrees))
        return original(path, rtrees)

    monkeypatch.setattr(gpkg_bulk, "write_rtrees_bulk", counted)
    store.write_tin(together, model, crs)
    assert calls == [sorted(f"rtree_{name}_geom" for name in LAYERS)]
    monkeypatch.setattr(store, "SMALL_TIN_TRIANGLES", 0)  # a "big" TIN's way
    store.write_tin(one_by_one, model, crs)
    assert len(calls) == 1
    expected = _tables(one_by_one)
    assert len(expected["rtree_edges_geom_rowid"]) > 10_000
    assert _tables(together) == expected
    with sqlite3.connect(together) as db:
        for name in LAYERS:
            assert db.execute(f"SELECT rtreecheck('rtree_{name}_geom')").fetchone() == ("ok",)
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)


def test_a_refusal_while_the_rtrees_are_written_falls_back_to_gdal(tmp_path, monkeypatch):
    from toolbox.io import gpkg_bulk
    from toolbox.io.sqlite_pages import UnsupportedDatabase

    def refuse(pages, rtree, tree):
        raise UnsupportedDatabase("a test's refusal")

    monkeypatch.setattr(gpkg_bulk, "_fill_rtree", refuse)
    model = _model(700, 2)
    path = tmp_path / "t.gpkg"
    counts = store.write_tin(path, model, parse_crs("EPSG:3003"))
    assert {name: pyogrio.read_info(path, layer=name)["features"] for name in LAYERS} == counts
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        for name in LAYERS:  # GDAL's own R-trees
            assert db.execute(f"SELECT count(*) FROM rtree_{name}_geom").fetchone() == \
                (counts[name],)


@pytest.mark.parametrize("spatial_index", [True, False])
def test_the_progress_names_each_step(tmp_path, spatial_index):
    """The feedback gets one step a layer, and one for the spatial indexes packed together."""
    from toolbox.feedback import Feedback

    steps = []
    feedback = Feedback(lambda percent, message: steps.append(message))
    store.write_tin(tmp_path / "t.gpkg", _model(500, 3), None, spatial_index,
                    feedback=feedback)
    expected = ["write triangles", "write nodes", "write edges"]
    assert [s for s in steps if s] == expected + (["write spatial indexes"] if spatial_index
                                                  else [])
