"""Round 16 leftovers: defects left by the last round, each with the test that failed before."""

from __future__ import annotations

import json

import geopandas as gpd
import numpy as np
import shapely

import toolbox
from toolbox.feedback import Feedback
from toolbox.topology.build import build_topology
from toolbox.topology.tolerances import Tolerances


# -- 1. topology: a snap tolerance large for the features is warned about ------------------------
def _buildings(n=4, size=10.0, spacing=20.0):
    """n x n closed square outlines of ``size`` m (bounding-box diagonal size*sqrt(2))."""
    return np.array([shapely.LineString([(x, y), (x + size, y), (x + size, y + size),
                                         (x, y + size), (x, y)])
                     for i in range(n) for j in range(n)
                     for x, y in [(1_500_000 + spacing * i, 5_000_000 + spacing * j)]],
                    dtype=object)


def test_large_snap_tolerance_warns_naming_parameter_value_and_size():
    fb = Feedback()
    out = build_topology(_buildings(), tolerances=Tolerances(snap=200.0), feedback=fb)
    [warning] = [w for w in fb.warnings if "SNAP_TOLERANCE" in w]
    assert "200" in warning and "14.1" in warning  # 10 m squares: diagonal 14.14 m
    assert len(out.areas) != 16  # the buildings are mangled indeed: the warning is deserved


def test_usual_snap_tolerance_is_silent():
    fb = Feedback()
    out = build_topology(_buildings(), tolerances=Tolerances(snap=0.2), feedback=fb)
    assert len(out.areas) == 16
    assert not [w for w in fb.warnings if "SNAP_TOLERANCE" in w]
    fb = Feedback()  # 3 m: just under a quarter of the 14.14 m diagonal, still silent
    build_topology(_buildings(), tolerances=Tolerances(snap=3.0), feedback=fb)
    assert not [w for w in fb.warnings if "SNAP_TOLERANCE" in w]


def test_large_snap_warning_reaches_the_run_report(tmp_path):
    src = tmp_path / "b.gpkg"
    gpd.GeoDataFrame({"code": ["FAB"] * 16}, geometry=list(_buildings()),
                     crs="EPSG:3003").to_file(src)
    report = tmp_path / "run.json"
    toolbox.run("topology:build_areas", {"INPUT": str(src), "SNAP_TOLERANCE": 200,
                                         "OUTPUT": str(tmp_path / "o.gpkg")}, report=report)
    doc = json.loads(report.read_text())
    assert any("SNAP_TOLERANCE 200" in w for w in doc["warnings"])
