"""Round 16 (clusterdem): a DEM converted to the photos' height datum on a Dask cluster.

``ortho:photo`` with a DEM in EGM96 heights and photos in ellipsoidal heights converts the DEM
once into a temporary file. It was written in the client's system temp (/tmp/toolbox-heights-*):
workers on other machines, which read a DEM too large to preload themselves, would look for a
file only the client has. With a Dask executor it now goes in the output's staging folder (on
the storage the README requires to be shared) and is removed with the run; the ortho is the
local run's.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
import rasterio
from pyproj import CRS
from pyproj.transformer import TransformerGroup

import toolbox
from toolbox.ortho.dem import DemSampler
from toolbox.ortho.vertical import use_system_grids

UTM, EGM96 = "EPSG:32632", "EPSG:32632+5773"
BOUNDS = (686000.0, 4795000.0, 687600.0, 4796600.0)
CENTRE, ANGLES = (686800.0, 4795800.0, 1200.0), (0.02, -0.015, 0.4)


def egm96_available() -> bool:
    use_system_grids()
    return TransformerGroup(CRS(EGM96), CRS(UTM).to_3d(), always_xy=True).best_available


def _scene(folder: Path) -> dict:
    from tests.algorithms.ortho.test_ortho_vertical_datum import vertical_scene

    vertical_scene(folder, size=300, relief=150.0, dem_name="dem.tif", bounds=BOUNDS,
                   centre=CENTRE)
    return {"INPUT": folder / "p1.tif", "PROJECT": folder / "project.yaml",
            "DEM": folder / "dem.tif", "HEIGHTS": "ellipsoidal", "CELL_SIZE": 5.0,
            "OVERVIEWS": False}


@pytest.mark.distributed
@pytest.mark.skipif(not egm96_available(), reason="the EGM96 geoid grid is not installed")
def test_converted_dem_lives_beside_the_output_on_a_cluster(cluster, monkeypatch, tmp_path):
    params = _scene(tmp_path)
    read: dict[str, list[Path]] = {}
    preload = DemSampler.preload

    def no_preload(self, bounds, max_cells=1 << 24):  # the workers read the DEM themselves
        read.setdefault(where, []).append(Path(self.path))
        assert Path(self.path).exists()
        return preload(self, bounds, max_cells=1)

    monkeypatch.setattr(DemSampler, "preload", no_preload)
    arrays = {}
    for where in ("local", cluster):
        out = tmp_path / ("local" if where == "local" else "dask") / "ortho.tif"
        stats = toolbox.run("ortho:photo", params | {"OUTPUT": out, "SCHEDULER": where})
        assert stats["STATISTICS"]["heights"]["converted"]
        with rasterio.open(out) as src:
            arrays[where] = src.read()
        assert not [p for p in out.parent.rglob("*") if "heights" in p.name]  # removed
    system_temp = Path(tempfile.gettempdir()).resolve()
    (dask_dem,) = read[cluster]
    assert dask_dem.name == "dem_heights.tif"
    assert dask_dem.resolve().is_relative_to((tmp_path / "dask").resolve())
    assert not dask_dem.resolve().parent.parent == system_temp
    assert arrays["local"][-1].any()
    assert np.array_equal(arrays["local"], arrays[cluster])
