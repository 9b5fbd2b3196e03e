"""Round 16, the merger's own fixes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

laspy = pytest.importorskip("laspy")


def _noisy_cloud(path):
    """25 ground points at 100 m on a 10 m lattice, one of class 7 at -50 m (a low-noise
    pit) and one of class 18 at 900 m (a bird): the ASPRS noise classes."""
    xs, ys = np.meshgrid(500000.0 + 10 * np.arange(5), 4500000.0 + 10 * np.arange(5))
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([500000.0, 4500000.0, 0.0])
    from pyproj import CRS

    header.add_crs(CRS.from_user_input("EPSG:32633"))
    las = laspy.LasData(header)
    las.x = np.r_[xs.ravel(), 500015.0, 500025.0]
    las.y = np.r_[ys.ravel(), 4500015.0, 4500025.0]
    las.z = np.r_[np.full(25, 100.0), -50.0, 900.0]
    las.classification = np.r_[np.full(25, 2), 7, 18].astype(np.uint8)
    las.return_number = np.ones(27, np.uint8)
    las.number_of_returns = np.ones(27, np.uint8)
    las.write(path)


@pytest.mark.parametrize("classes", [None, "2"])
def test_noise_classes_used_without_classes_are_warned(tmp_path, classes):
    """The noise classes 7 and 18 were gridded in silence when CLASSES was not given (a -50 m
    pit and a 900 m spike in a DEM of a flat 100 m field, exit 0): the run now warns with the
    counts; with CLASSES 2 they are left out and nothing is said."""
    _noisy_cloud(tmp_path / "c.las")
    report = tmp_path / "r.json"
    cmd = [sys.executable, "-m", "toolbox", "run", "dem:nearest", "--INPUT",
           str(tmp_path / "c.las"), "--CELL_SIZE", "5", "--OUTPUT", str(tmp_path / "d.tif"),
           "--run-report", str(report)]
    if classes:
        cmd += ["--CLASSES", classes]
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    warnings = [w for w in json.loads(report.read_text())["warnings"] if "noise" in w]
    import rasterio

    with rasterio.open(tmp_path / "d.tif") as src:
        z = src.read(1, masked=True)
    if classes:
        assert warnings == [] and float(z.min()) == float(z.max()) == 100.0
    else:
        assert len(warnings) == 1 and "1 of class 7 (low noise) and 1 of class 18" in warnings[0]
        assert "CLASSES" in warnings[0]
        assert float(z.min()) == -50.0 and float(z.max()) == 900.0  # what the warning is about


def test_streamed_cloud_warns_noise_once(tmp_path, monkeypatch):
    """The streamed path (above TOOLBOX_STREAM_POINTS) reads the cloud twice: one warning."""
    _noisy_cloud(tmp_path / "c.las")
    report = tmp_path / "r.json"
    env = {"TOOLBOX_STREAM_POINTS": "10"}
    import os

    done = subprocess.run([sys.executable, "-m", "toolbox", "run", "dem:nearest", "--INPUT",
                           str(tmp_path / "c.las"), "--CELL_SIZE", "5", "--OUTPUT",
                           str(tmp_path / "d.tif"), "--run-report", str(report)],
                          capture_output=True, text=True, env={**os.environ, **env})
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("class 18 (high noise)") == 1
    assert sum("noise" in w for w in json.loads(report.read_text())["warnings"]) == 1


def test_caller_feedback_gets_the_warnings_logged_outside_feedback(tmp_path):
    """A warning a reader logs on the toolbox logger (here the noise classes) reached the run
    report and the console but not the Feedback a Python caller passed to toolbox.run."""
    import toolbox
    from toolbox.feedback import Feedback

    _noisy_cloud(tmp_path / "c.las")
    feedback = Feedback()
    toolbox.run("dem:nearest", {"INPUT": str(tmp_path / "c.las"), "CELL_SIZE": 5,
                                "OUTPUT": str(tmp_path / "d.tif")}, feedback=feedback)
    assert sum("class 18 (high noise)" in w for w in feedback.warnings) == 1


def test_seam_split_where_the_path_ends_on_a_spike_of_the_overlap():
    """The Siena demo's seam 1_7151 / 1_7152 (since its orthos reach the DEM's outer half cell)
    ended on a vertex of the overlap's boundary pointing into the overlap: prolonged straight on,
    the path's end stayed inside and shapely's split gave one piece, so the least-cost seam was
    dropped for the Voronoi line ("the path did not split the overlap"). The end now turns off
    the boundary when straight on does not cross it: two pieces, covering the overlap."""
    from shapely import box, wkt

    from toolbox.mosaic.seams import split_between

    doc = json.loads((Path(__file__).parents[1] / "data" / "seam_split_spike.json").read_text())
    region, path, tol = wkt.loads(doc["region"]), doc["path"], doc["tol"]
    x0, y0, x1, y1 = region.bounds
    cells = {0: region.union(box(x0 - 100, y0, x0, y1)), 1: region.union(box(x1, y0, x1 + 100, y1))}
    new = split_between(cells, 0, 1, path, region, tol)
    assert new is not None
    a, b = (g.intersection(region) for g in new)
    assert abs(a.area + b.area - region.area) < 1e-6 * region.area
    assert a.intersection(b).area < 1e-6 * region.area
