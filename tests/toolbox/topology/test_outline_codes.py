"""Areas coded by a closed coded outline as well as by a label point (toolbox.topology.labels)."""

from __future__ import annotations

import numpy as np
import shapely

from toolbox.topology.area_codes import AreaCodes
from toolbox.topology.build import build_topology


def _run(labels, area_codes=None):
    # a block edge (open, road code) around two buildings plotted closed with their code
    lines = np.array([
        shapely.LineString([(0, 0), (50, 0), (50, 30), (0, 30), (0, 0.1)]),  # closed by closure
        shapely.LineString([(5, 5), (15, 5), (15, 15), (5, 15), (5, 5)]),
        shapely.LineString([(25, 5), (35, 5), (35, 15), (25, 15), (25, 5)]),
    ], dtype=object)
    codes = np.array([None, "FAB01002", "FAB01003"], dtype=object)
    pts = np.array([shapely.Point(x, y) for _, (x, y) in labels], dtype=object)
    label_codes = np.array([c for c, _ in labels], dtype=object)
    return build_topology(lines, codes, pts, label_codes, area_codes=area_codes)


def _code_at(out, x, y):
    inside = shapely.contains_xy(out.areas.geometry, x, y)
    return out.areas.columns["code"][np.flatnonzero(inside)[0]]


def test_closed_coded_outline_codes_its_area():
    out = _run([("MAR01001", (40, 25))])  # only the pavement has a label
    assert _code_at(out, 10, 10) == "FAB01002" and _code_at(out, 30, 10) == "FAB01003"
    assert _code_at(out, 40, 25) == "MAR01001"
    types = list(out.errors.columns["type"])
    assert "unlabelled_area" not in types and "conflicting_labels" not in types
    assert out.statistics["labels"]["unlabelled_areas"] == 2  # no point inside; coded anyway


def test_outline_and_label_disagree_is_an_error():
    # the code file declares the building codes area (polygon) codes: they can disagree
    area_codes = AreaCodes(polygon=frozenset({"FAB01002", "FAB01003", "VER01001", "MAR01001"}))
    out = _run([("MAR01001", (40, 25)), ("FAB01002", (10, 10)), ("VER01001", (30, 10))],
               area_codes)
    assert _code_at(out, 10, 10) == "FAB01002"  # agree: no issue
    conflicts = [(t, s, d) for t, s, d in zip(out.errors.columns["type"],
                                              out.errors.columns["severity"],
                                              out.errors.columns["detail"], strict=True)
                 if t == "conflicting_labels"]
    assert conflicts == [("conflicting_labels", "error", "closed line FAB01003 and label code "
                          "VER01001 disagree: the label's code is used")]
    assert _code_at(out, 30, 10) == "VER01001"  # the label's code is kept
