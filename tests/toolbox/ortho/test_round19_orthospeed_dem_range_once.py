"""dem_range computes a DEM's height range once per process also when ortho:batch plans its
photos on two threads at once: each thread computed it (the DEM opened and its statistics
computed twice). The value is GDAL's approximate statistics, checked against NumPy's min/max
of the (small, overview-less) DEM."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import numpy as np
import rasterio
from affine import Affine

import toolbox.photogrammetry.surface as surface
from tests.helpers_threads import run_in_threads
from toolbox.ortho import plan


def test_two_threads_compute_the_range_once(tmp_path, monkeypatch):
    heights = np.random.default_rng(19).uniform(120.0, 480.0, (60, 80)).astype("float32")
    path = tmp_path / "dem.tif"
    with rasterio.open(path, "w", driver="GTiff", width=80, height=60, count=1,
                       dtype="float32", crs="EPSG:32633",
                       transform=Affine(10, 0, 500000, 0, -10, 5000000)) as dst:
        dst.write(heights, 1)
    calls = []
    real = surface.dem_height_range

    def slow(info, band=1):  # long enough that both threads ask before either has the answer
        calls.append(band)
        time.sleep(0.2)
        return real(info, band)

    monkeypatch.setattr(surface, "dem_height_range", slow)
    info = SimpleNamespace(path=str(path))
    start = threading.Barrier(2)
    got = []

    def plan_one():
        start.wait()
        got.append(plan.dem_range(info, 1))

    run_in_threads(plan_one, plan_one)
    assert len(calls) == 1
    assert got[0] == got[1] == (float(heights.min()), float(heights.max()))
