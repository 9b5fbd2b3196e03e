"""A synthetic block for the ortho tests: analytic terrain with 200 m of relief at Siena-like
coordinates (EPSG:3003), a tilted frame photo rendered through the collinearity equations
(:mod:`toolbox.photogrammetry.synthetic`: rays marched down to the DEM, so the truth does not use
the ortho's ground -> image code) and the texture it shows."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.photogrammetry.synthetic import frame_photo, hills_dem, render_photo, wave_texture, write_photo

CRS = "EPSG:3003"
BOUNDS = (1686600.0, 4797600.0, 1689800.0, 4800800.0)
CENTRE = (1688200.0, 4799200.0, 1700.0)
ANGLES = (0.02, -0.015, 0.4)  # rad
SIZE = 800  # px; 230 mm frame -> 0.2875 mm pixels, c = 153 mm, about 2.5 m on the ground
RELIEF = 200.0
BASE = 250.0


@dataclass
class Scene:
    folder: Path
    dem_path: Path
    photo_path: Path
    project_path: Path
    dem: np.ndarray
    transform: object
    photo: object
    texture: object


def project_yaml(path: Path, photo_name: str, centre=CENTRE, angles=ANGLES, distortion=None
                 ) -> Path:
    import yaml

    camera = {"name": "synthetic", "principal_distance_mm": 153.0,
              "image_size_px": [SIZE, SIZE], "pixel_size_mm": 230.0 / SIZE,
              "frame_size_mm": [230.0, 230.0]}
    if distortion is not None:
        camera["distortion"] = distortion
    doc = {"format": "orientation-project", "version": 1, "crs": CRS, "angle_unit": "rad",
           "cameras": [camera],
           "photos": [{"id": "p1", "camera": "synthetic", "image": photo_name,
                       "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                            [*centre, *angles], strict=True))}]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def write_dem(path: Path, z: np.ndarray, transform, crs=CRS) -> Path:
    from toolbox.raster.writer import write_raster

    write_raster(path, z.astype("float32"), transform, crs, nodata=-9999.0)
    return path


def make_scene(folder: Path, bands: int = 1) -> Scene:
    folder = Path(folder)
    z, transform = hills_dem(BOUNDS, cell=10.0, relief=RELIEF, base=BASE, seed=3)
    texture = wave_texture(seed=7, wavelength=(40.0, 120.0), bands=bands)
    photo = frame_photo(CENTRE, ANGLES, width=SIZE, height=SIZE, crs=CRS)
    image = render_photo(photo, z, transform, texture, dtype="uint8")
    photo_path = write_photo(folder / "p1.tif", image)
    dem_path = write_dem(folder / "dem.tif", z, transform)
    project = project_yaml(folder / "project.yaml", "p1.tif")
    return Scene(folder, dem_path, photo_path, project, z, transform, photo, texture)


def assert_on_lattice(path: Path, cell: float) -> None:
    """The raster at ``path`` has square ``cell`` cells and edges on multiples of the cell."""
    import rasterio

    with rasterio.open(path) as src:
        t = src.transform
    assert (t.a, -t.e) == (cell, cell)
    assert abs(t.c / cell - round(t.c / cell)) < 1e-6
    assert abs(t.f / cell - round(t.f / cell)) < 1e-6
