"""Sample terrain over the Siena case-study block (EPSG:3003, Monte Mario / Italy zone 1).

The relief is matplotlib's real ``jacksboro_fault_dem.npz`` (USGS 3 arc-second DEM), rescaled to
the Siena heights (287-343 m a.s.l., as the thesis' control points) and laid on a 4 m grid whose
1612 m x 1376 m cover the six Siena photos' ground area. Mass points are sampled from it
bilinearly with a fixed seed, so the demo is reproducible and every product has a known truth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

CRS = "EPSG:3003"
CELL = 4.0
XMIN, YMAX = 1687500.0, 4800350.0
Z_LOW, Z_HIGH = 287.0, 343.0


def terrain() -> tuple[np.ndarray, object]:
    """(rows, cols) float32 heights and the affine transform of the sample DEM."""
    import matplotlib.cbook as cbook
    from affine import Affine

    data = cbook.get_sample_data("jacksboro_fault_dem.npz")
    elevation = np.asarray(data["elevation"], dtype="float64")
    z = Z_LOW + (elevation - elevation.min()) / np.ptp(elevation) * (Z_HIGH - Z_LOW)
    return z.astype("float32"), Affine(CELL, 0, XMIN, 0, -CELL, YMAX)


def sample_heights(z: np.ndarray, transform, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear heights of the DEM at map points (cell values at cell centres)."""
    from scipy.interpolate import RegularGridInterpolator

    rows, cols = z.shape
    xc = transform.c + (np.arange(cols) + 0.5) * transform.a
    yc = transform.f + (np.arange(rows) + 0.5) * transform.e
    interp = RegularGridInterpolator((yc[::-1], xc), z[::-1].astype("float64"))
    return interp(np.column_stack([y, x]))


def make(folder: Path, made: dict) -> dict:
    import geopandas as gpd
    import shapely

    from toolbox.io.vector_write import write_layers
    from toolbox.raster.writer import write_raster

    z, transform = terrain()
    dem = folder / "siena_dem.tif"
    write_raster(dem, z, transform, CRS, nodata=-9999.0)
    rng = np.random.default_rng(20090331)
    rows, cols = z.shape
    n = 4000
    x = rng.uniform(XMIN + CELL, XMIN + (cols - 1) * CELL, n)
    y = rng.uniform(YMAX - (rows - 1) * CELL, YMAX - CELL, n)
    h = sample_heights(z, transform, x, y)
    points = gpd.GeoDataFrame({"id": np.arange(1, n + 1), "z": np.round(h, 3)},
                              geometry=shapely.points(x, y, np.round(h, 3)), crs=CRS)
    mass = folder / "mass_points.gpkg"
    if mass.exists():
        mass.unlink()
    write_layers(mass, {"mass_points": points})
    return {"dem": dem, "mass_points": mass}
