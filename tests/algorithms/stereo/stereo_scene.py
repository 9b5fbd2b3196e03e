"""A synthetic stereo pair for the stereo tests: two tilted frame photos (c = 153 mm, radial
distortion of about 1 px at the corners) over an analytic hilly surface at Siena-like
coordinates (EPSG:3003), rendered through the collinearity equations by ray marching
(:mod:`toolbox.photogrammetry.synthetic`: image -> ground, independent of the epipolar code,
which runs ground -> image), plus an orientation project that lists them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from toolbox.photogrammetry.camera import RadialDistortion
from toolbox.photogrammetry.synthetic import frame_photo, render_photo, write_photo

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_799_500.0
SIZE = 600  # px; 230 mm frame -> 0.383 mm pixels; ~1.8 m on the ground at 700 m
C_MM = 153.0
K1 = 3e-7  # dr = k1 r^3: 0.46 mm = 1.2 px at the frame corner
CENTRES = {"L": (X0 + 300.0, Y0 + 500.0, 1000.0), "R": (X0 + 720.0, Y0 + 510.0, 1010.0),
           "M": (X0 + 510.0, Y0 + 490.0, 1005.0), "far": (X0 + 3000.0, Y0 + 500.0, 1000.0)}
ANGLES = {"L": (0.02, -0.015, 0.03), "R": (-0.01, 0.02, -0.02), "M": (0.01, 0.01, 0.01),
          "far": (0.0, 0.0, 0.0)}


@dataclass
class Pair:
    folder: Path
    project: Path
    photos: dict
    surface: np.ndarray  # the rendered DSM
    transform: object


def photo(name: str):
    return frame_photo(CENTRES[name], ANGLES[name], width=SIZE, height=SIZE,
                       principal_distance_mm=C_MM,
                       distortion=RadialDistortion.from_polynomial(K1), crs=CRS, photo_id=name)


def project_yaml(path: Path, names=("L", "R", "M", "far")) -> Path:
    camera = {"name": "synthetic", "principal_distance_mm": C_MM,
              "image_size_px": [SIZE, SIZE], "pixel_size_mm": 230.0 / SIZE,
              "frame_size_mm": [230.0, 230.0], "distortion": {"polynomial": {"k1": K1}}}
    photos = [{"id": n, "camera": "synthetic", "image": f"{n}.tif",
               "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                    [*CENTRES[n], *ANGLES[n]], strict=True))} for n in names]
    photos.append({"id": "unoriented", "camera": "synthetic", "image": "L.tif"})
    doc = {"format": "orientation-project", "version": 1, "crs": CRS, "angle_unit": "rad",
           "cameras": [camera], "photos": photos}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def make_pair(folder: Path, surface: np.ndarray, transform, texture, names=("L", "R"),
              supersample: int = 2) -> Pair:
    folder = Path(folder)
    photos = {}
    for name in names:
        photos[name] = photo(name)
        image = render_photo(photos[name], surface, transform, texture, supersample=supersample,
                             dtype="uint8")
        write_photo(folder / f"{name}.tif", image)
    return Pair(folder, project_yaml(folder / "project.yaml"), photos, surface, transform)
