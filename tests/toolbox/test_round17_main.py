"""Round 17: DEM outputs say what their band holds (QGIS shows it in the layer's properties)."""

import geopandas as gpd
import numpy as np
import rasterio

import toolbox


def test_gridded_and_tin_dems_describe_their_band(tmp_path):
    rng = np.random.default_rng(5)
    x, y = rng.uniform(0, 100, 60) + 1688000, rng.uniform(0, 100, 60) + 4799000
    z = 200 + 0.1 * (x - 1688000)
    gpd.GeoDataFrame(geometry=gpd.points_from_xy(x, y, z), crs="EPSG:3003").to_file(
        tmp_path / "p.gpkg")
    toolbox.run("dem:nearest", {"INPUT": tmp_path / "p.gpkg", "CELL_SIZE": 5.0,
                                "OUTPUT": tmp_path / "nearest.tif"})
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "p.gpkg", "OUTPUT": tmp_path / "tin.gpkg"})
    toolbox.run("tin:to_raster", {"TIN": tmp_path / "tin.gpkg", "CELL_SIZE": 5.0,
                                  "OUTPUT": tmp_path / "tin.tif"})
    with rasterio.open(tmp_path / "nearest.tif") as src:
        assert src.descriptions == ("height (gridded from the points)",)
    with rasterio.open(tmp_path / "tin.tif") as src:
        assert src.descriptions == ("height (TIN, the plane of each triangle)",)
