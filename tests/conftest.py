"""Shared fixtures: tiny synthetic datasets with a known truth."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SIENA = ROOT / "toolbox" / "demo" / "data" / "siena"
# Orthority's test data (real NGI aerial frames with a DEM, ODM drone frames with an OpenSfM
# reconstruction, a QuickBird RPC image): not redistributable here (no licence stated for the data),
# so read from a checkout: TOOLBOX_ORTHORITY_DATA=<orthority>/tests/data, else the places below.
ORTHORITY_DATA_PLACES = ("/work/data/orthority/tests/data",)


def orthority_data_folder() -> Path | None:
    """The folder of Orthority's tests/data, or None when it is not on this machine."""
    import os

    for place in (os.environ.get("TOOLBOX_ORTHORITY_DATA"), *ORTHORITY_DATA_PLACES):
        if place and (Path(place) / "ngi" / "dem.tif").exists():
            return Path(place)
    return None


@pytest.fixture(scope="session")
def orthority_data() -> Path:
    """Orthority's tests/data folder (real photos with published orientations); the test is
    skipped, with the reason, where it is not on this machine."""
    folder = orthority_data_folder()
    if folder is None:
        pytest.skip("Orthority's test data not found: set TOOLBOX_ORTHORITY_DATA to the tests/data "
                    "folder of an Orthority checkout (real NGI and ODM photos)")
    return folder


@pytest.fixture
def plane_dem(tmp_path):
    """A 60 x 50 DEM of the plane z = 100 + 0.2·x' - 0.1·y' (x', y' from the grid corner),
    2 m cells, EPSG:3003, origin at the Siena block. Returns (path, slope_x, slope_y)."""
    from affine import Affine

    from toolbox.raster.writer import write_raster

    cell, x0, y0 = 2.0, 1688000.0, 4800000.0
    rows, cols = 50, 60
    xc = (np.arange(cols) + 0.5) * cell
    yc = y0 - (np.arange(rows) + 0.5) * cell
    z = 100 + 0.2 * xc[None, :] - 0.1 * (yc[:, None] - y0)
    path = tmp_path / "plane.tif"
    write_raster(path, z.astype("float32"), Affine(cell, 0, x0, 0, -cell, y0), "EPSG:3003",
                 nodata=-9999.0)
    return path, 0.2, -0.1


@pytest.fixture
def points_gpkg(tmp_path):
    """10 PointZ in EPSG:3003 with a 'height' field equal to Z + 1, layer 'pts'."""
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(0)
    x = 1688000 + rng.uniform(0, 100, 10)
    y = 4800000 + rng.uniform(0, 100, 10)
    z = rng.uniform(280, 340, 10)
    frame = gpd.GeoDataFrame({"name": [f"p{i}" for i in range(10)], "height": z + 1},
                             geometry=shapely.points(x, y, z), crs="EPSG:3003")
    path = tmp_path / "points.gpkg"
    frame.to_file(path, layer="pts", driver="GPKG")
    return path


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory):
    """``toolbox demo`` run once per session (shared with the error-contract, fuzz and signal
    tests): (its output folder, its summary). Read-only: a test that writes there copies it
    first."""
    sys.path.insert(0, str(Path(__file__).parent / "toolbox"))
    from trust_data import demo, demo_summary

    out, _ = demo()
    return out, demo_summary()


def run_cli(*args, cwd=None):
    """Run the toolbox CLI in a subprocess; returns the CompletedProcess (text)."""
    import subprocess

    return subprocess.run([sys.executable, "-m", "toolbox.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=300)


def siena_interior_cases() -> list[tuple[tuple[str, str], list[dict], dict]]:
    """Per (photo, source) of the Siena fiducials.csv (the Figure-42 table left out): the four
    mark rows and the printed interior-orientation report row (interior_reports.csv)."""
    import csv
    from collections import defaultdict

    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    with open(SIENA / "fiducials.csv") as f:
        for row in csv.DictReader(f):
            if row["source"] != "fig42_table":
                groups[(row["photo"], row["source"])].append(row)
    with open(SIENA / "interior_reports.csv") as f:
        reports = {(r["photo"], r["source"]): r for r in csv.DictReader(f)}
    return [(key, rows, reports[key]) for key, rows in sorted(groups.items())]


# -- the mosaic tests' standard scene (tests/algorithms/mosaic/mosaic_scene.py; here rather than
# in a conftest.py of that folder, which would shadow this module for `from conftest import`)
@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    return _mosaic_scene().standard_pair(tmp_path_factory)


@pytest.fixture(scope="module")
def seams(tmp_path_factory):
    return _mosaic_scene().standard_seams(tmp_path_factory)


def _mosaic_scene():
    """tests/algorithms/mosaic/mosaic_scene.py, importable from any test folder."""
    folder = str(Path(__file__).parent / "algorithms" / "mosaic")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    import mosaic_scene

    return mosaic_scene


@pytest.fixture(scope="module")
def cluster():
    """A Dask LocalCluster of two worker processes (one thread each) for the module's runs: its
    scheduler address."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as c:
        yield c.scheduler_address
