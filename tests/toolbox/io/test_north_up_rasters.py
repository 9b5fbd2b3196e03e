"""Rasters stored other than north-up: where an algorithm cannot read them right it refuses them
with one line naming the parameter and the gdalwarp command (it fell back to a plane per photo
with warnings, cut sheets 44 m off in silence, or stopped with an internal error); where it can
(contours, profiles, check points on an ortho: south-up or east to west) only a rotated raster
is refused. The refusals come before any output."""

from __future__ import annotations

import sys
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely
from affine import Affine

import toolbox

sys.path.insert(0, str(Path(__file__).parents[2] / "algorithms" / "ortho"))
import ortho_scene  # noqa: E402

X0, Y0 = 1688000.0, 4800000.0
STORAGE = {"south_up": Affine(2, 0, X0, 0, 2, Y0 - 200), "east_to_west": Affine(-2, 0, X0 + 200,
                                                                                 0, -2, Y0),
           "rotated": Affine(2, 0.2, X0, 0.1, -2, Y0)}


def raster(tmp_path, storage, bands=1):
    path = tmp_path / f"{storage}.tif"
    r, c = np.indices((100, 100))
    z = (100 + 0.3 * c + 0.1 * r).astype("float32")
    with rasterio.open(path, "w", driver="GTiff", width=100, height=100, count=bands,
                       dtype="float32", crs="EPSG:3003", transform=STORAGE[storage]) as dst:
        for b in range(1, bands + 1):
            dst.write(z, b)
    return path


@pytest.mark.parametrize("storage", ["south_up", "east_to_west", "rotated"])
def test_footprints_and_cut_refuse_a_raster_not_north_up(tmp_path, storage):
    scene = ortho_scene.make_scene(tmp_path)
    dem = raster(tmp_path, storage)
    with pytest.raises(toolbox.ParameterError, match=r"DEM .*(south-up|east to west|rotated)"
                                                     r".*gdalwarp"):
        toolbox.run("orientation:footprints", {"PROJECT": scene.project_path, "DEM": dem,
                                               "OUTPUT": tmp_path / "fp.gpkg"})
    with pytest.raises(toolbox.ParameterError, match=r"INPUT .*(south-up|east to west|rotated)"):
        toolbox.run("mosaic:cut", {"INPUT": dem, "SCALE": 1000, "SHEET_WIDTH": 50,
                                   "SHEET_HEIGHT": 50, "OUTPUT": tmp_path / "cut"})
    assert not (tmp_path / "fp.gpkg").exists() and not (tmp_path / "cut").exists()


def test_contours_and_profiles_refuse_only_a_rotated_dem(tmp_path):
    line = tmp_path / "line.gpkg"
    gpd.GeoDataFrame(geometry=[shapely.LineString([(X0 + 20, Y0 - 20), (X0 + 150, Y0 - 150)])],
                     crs="EPSG:3003").to_file(line)
    for storage in ("south_up", "rotated"):
        dem = raster(tmp_path, storage)
        runs = [("carto:contours", {"INPUT": dem, "INTERVAL": 5.0,
                                    "OUTPUT": tmp_path / f"c_{storage}.gpkg"}, "INPUT"),
                ("carto:profile", {"INPUT": line, "DEM": dem,
                                   "OUTPUT": tmp_path / f"p_{storage}.gpkg"}, "DEM")]
        for algorithm, params, name in runs:
            if storage == "rotated":
                with pytest.raises(toolbox.ParameterError, match=f"{name} .*rotated"):
                    toolbox.run(algorithm, params)
                assert not params["OUTPUT"].exists()
            else:
                toolbox.run(algorithm, params)
                assert params["OUTPUT"].exists()
