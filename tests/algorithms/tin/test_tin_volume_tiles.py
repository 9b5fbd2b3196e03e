"""tin:volume against a DEM on the raster engine: a DEM of 3 x 3 engine tiles (512 cells)
with a nodata hole across a tile border, inside a mask crossing tiles; the truth is counted
independently with shapely at the DEM's cell centres."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely
from affine import Affine

import toolbox

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_799_500.0
SIZE = 1100  # cells of 1 m: 3 x 3 tiles of 512


def plane(x, y):
    return 250.0 + 0.03 * (np.asarray(x) - X0) + 0.01 * (np.asarray(y) - Y0)


def test_volume_over_many_tiles_with_a_hole(tmp_path):
    rng = np.random.default_rng(5)
    xy = np.vstack([[[X0, Y0], [X0 + SIZE, Y0], [X0 + SIZE, Y0 + SIZE], [X0, Y0 + SIZE]],
                    np.column_stack([rng.uniform(0, SIZE, 200) + X0,
                                     rng.uniform(0, SIZE, 200) + Y0])])
    z = plane(xy[:, 0], xy[:, 1])
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z), crs=CRS).to_file(
        tmp_path / "points.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "points.gpkg",
                                 "OUTPUT": tmp_path / "tin.gpkg"})
    centres = (np.arange(SIZE) + 0.5)
    gx, gy = np.meshgrid(X0 + centres, Y0 + SIZE - centres)
    dem = (plane(gx, gy) - 2.0).astype("float64")
    dem[490:530, 500:600] = -9999.0  # nodata across the tile borders at row and column 512
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=SIZE, height=SIZE,
                       count=1, dtype="float64", crs=CRS, nodata=-9999.0,
                       transform=Affine(1.0, 0, X0, 0, -1.0, Y0 + SIZE)) as dst:
        dst.write(dem, 1)
    mask = shapely.box(X0 + 300.3, Y0 + 250.2, X0 + 900.1, Y0 + 1000.4)
    gpd.GeoDataFrame({"n": [1]}, geometry=[mask], crs=CRS).to_file(tmp_path / "mask.gpkg")
    stats = toolbox.run("tin:volume", {"TIN": tmp_path / "tin.gpkg",
                                       "REFERENCE_DEM": tmp_path / "dem.tif",
                                       "MASK": tmp_path / "mask.gpkg"})["STATISTICS"]
    inside = shapely.contains_xy(mask, gx, gy)
    hole = dem == -9999.0
    assert stats["cells_without_dem"] == int((inside & hole).sum()) == 4000
    assert stats["cut_volume"] == pytest.approx(2.0 * (inside & ~hole).sum(), rel=1e-9)
    assert stats["fill_volume"] == 0.0
    assert stats["cut_area"] == pytest.approx((inside & ~hole).sum(), rel=1e-12)
