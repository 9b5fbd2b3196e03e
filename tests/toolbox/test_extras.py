"""Dependencies a company can ship: the core install runs every algorithm, the optional parts
(Triangle, Dask, psutil) are extras, and asking for a missing one names the extra to install."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

from toolbox.errors import ToolboxError
from toolbox.executor import Executor, map_tiles
from toolbox.extras import require

ROOT = Path(__file__).resolve().parents[2]
CORE = {"numpy", "scipy", "shapely", "pyproj", "rasterio", "geopandas", "pyogrio", "pyarrow",
        "pyyaml", "click", "numba", "opencv-python-headless", "matplotlib",
        "threadpoolctl", "pythoncdt"}
BLOCK_EXTRAS = """
import importlib.abc, sys
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split('.')[0] in ('triangle', 'dask', 'distributed', 'psutil'):
            raise ImportError(f'blocked: {name}')
sys.meta_path.insert(0, Block())
"""


def _name(requirement: str) -> str:
    for stop in "[<>=!~ ;":
        requirement = requirement.split(stop)[0]
    return requirement.strip().lower()


def test_pyproject_core_and_extras():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {_name(r) for r in project["dependencies"]}
    extras = project["optional-dependencies"]
    assert CORE <= core  # the design card's packages and the redistributable triangulator
    # scikit-image is the seam route's test oracle only (the route is compiled: bench/mosaic_bench.py)
    assert "scikit-image" not in core and "scikit-image" in {_name(r) for r in extras["dev"]}
    assert not core & {"triangle", "dask", "distributed", "psutil"}
    assert [_name(r) for r in extras["triangle"]] == ["triangle"]
    assert [_name(r) for r in extras["dask"]] == ["dask"] and "distributed" in extras["dask"][0]
    assert [_name(r) for r in extras["bench"]] == ["psutil"]
    # dev pulls in every extra, so the whole suite (Triangle and Dask tests included) runs in CI
    assert any(r.startswith("photogrammetry-toolbox[") and all(
        e in r for e in ("triangle", "dask", "bench")) for r in extras["dev"])


def test_require_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "psutil", None)
    with pytest.raises(ToolboxError, match=r"the benchmarks needs the optional package 'psutil': "
                                           r"pip install 'photogrammetry-toolbox\[bench\]'"):
        require("psutil", "bench", "the benchmarks")


def _square(x):
    return x * x


def test_dask_scheduler_without_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    executor = Executor("dask", 1, "tcp://127.0.0.1:1")
    with pytest.raises(ToolboxError, match=r"SCHEDULER \(a Dask cluster\) needs .*"
                                           r"photogrammetry-toolbox\[dask\]"):
        list(map_tiles(_square, [1, 2], executor=executor))
    assert list(map_tiles(_square, [1, 2, 3], executor=Executor("local", 2))) == [1, 4, 9]


@pytest.mark.slow
def test_tin_and_dem_run_on_the_core_install(tmp_path):
    """tin:delaunay, tin:to_raster and dem:tin_linear in a process where Triangle, Dask and
    psutil cannot be imported (the core install)."""
    script = BLOCK_EXTRAS + textwrap.dedent(f"""
        import numpy as np, geopandas as gpd, shapely, toolbox
        rng = np.random.default_rng(0)
        xy = rng.uniform(0, 100, (300, 2)) + (1688000, 4799500)
        z = 300 + 0.05 * (xy[:, 0] - 1688000)
        pts = gpd.GeoDataFrame(geometry=shapely.points(np.column_stack([xy, z])), crs=3003)
        out = r"{tmp_path}"
        toolbox.run("tin:delaunay", {{"INPUT": pts, "OUTPUT": out + "/tin.gpkg"}})
        toolbox.run("tin:to_raster", {{"TIN": out + "/tin.gpkg", "CELL_SIZE": 5,
                                       "OUTPUT": out + "/tin.tif"}})
        toolbox.run("dem:tin_linear", {{"INPUT": pts, "CELL_SIZE": 5, "OUTPUT": out + "/dem.tif"}})
        assert not {{"triangle", "dask", "distributed", "psutil"}} & set(sys.modules)
        print("ok")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            cwd=ROOT, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().endswith("ok")
    assert (tmp_path / "tin.tif").exists() and (tmp_path / "dem.tif").exists()
