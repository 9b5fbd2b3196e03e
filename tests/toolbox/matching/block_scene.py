"""A rendered 3 x 2 block for the tie-point tests: analytic terrain with 200 m of relief, a
textured ground, six frame photos in two strips (the second flown back, kappa = 180 degrees),
with radial distortion, rendered through the collinearity equations by ray marching
(:func:`toolbox.photogrammetry.synthetic.render_photo`), so the truth never uses the matcher."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.photogrammetry.camera import RadialDistortion
from toolbox.photogrammetry.synthetic import frame_photo, hills_dem, render_photo, write_photo

CRS = "EPSG:3003"
X0, Y0 = 1688000.0, 4799000.0
SIZE = 480  # px per side; 230 mm frame -> 0.479 mm pixels
C = 153.0
HEIGHT = 1750.0  # flying height (Z0); terrain 250..450 m
BASE, STRIP_GAP = 800.0, 1400.0  # m: ~60 % forward, ~30 % side overlap
K1 = -4e-8  # mm^-2: 0.4 mm (~0.9 px) at the frame corner
BOUNDS = (X0 - 2200.0, Y0 - 2600.0, X0 + 2200.0 + 2 * BASE, Y0 + 1400.0 + STRIP_GAP)


def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ground radiometry: band-limited noise (sum of many random plane waves, 25-250 m, longer
    ones stronger), with no period that a descriptor could confuse."""
    rng = np.random.default_rng(11)
    n = 60
    angle = rng.uniform(0, np.pi, n)
    wavelength = rng.uniform(25.0, 250.0, n)
    k = 2 * np.pi / wavelength
    phase = rng.uniform(0, 2 * np.pi, n)
    amp = rng.uniform(0.5, 1.0, n) * np.sqrt(wavelength / 100.0)
    x = np.asarray(x, dtype="float64") - X0
    y = np.asarray(y, dtype="float64") - Y0
    v = np.zeros_like(x)
    for a, kk, p, m in zip(angle, k, phase, amp, strict=True):
        v += m * np.sin(kk * (np.cos(a) * x + np.sin(a) * y) + p)
    return np.clip(128.0 + 90.0 * v / np.sqrt(n / 2.0) / 2.2, 0, 255)


@dataclass
class Block:
    folder: Path
    project: Path
    photos: list  # true oriented Photo objects
    images: list[Path]


def true_photos() -> list:
    rng = np.random.default_rng(5)
    photos = []
    for s in range(2):
        for i in range(3):
            x = X0 + i * BASE if s == 0 else X0 + (2 - i) * BASE
            y = Y0 + s * STRIP_GAP
            kappa = (0.0 if s == 0 else np.pi) + rng.uniform(-0.03, 0.03)
            angles = (rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), kappa)
            photos.append(frame_photo((x, y, HEIGHT), angles, width=SIZE, height=SIZE,
                                      principal_distance_mm=C, crs=CRS,
                                      distortion=RadialDistortion.from_polynomial(K1),
                                      photo_id=f"s{s + 1}_{i + 1}"))
    return photos


def project_yaml(path: Path, photos: list, images: list[Path]) -> Path:
    import yaml

    cam = photos[0].camera
    doc = {"format": "orientation-project", "version": 1, "crs": CRS, "angle_unit": "rad",
           "cameras": [{"name": "synthetic", "principal_distance_mm": C,
                        "image_size_px": [SIZE, SIZE], "pixel_size_mm": cam.pixel_size_mm,
                        "frame_size_mm": [230.0, 230.0],
                        "distortion": {"polynomial": {"k1": K1, "k2": 0.0}}}],
           "photos": [{"id": p.id, "camera": "synthetic", "image": img.name,
                       "exterior": {"X0": p.exterior.x0, "Y0": p.exterior.y0,
                                    "Z0": p.exterior.z0, "omega": p.exterior.omega,
                                    "phi": p.exterior.phi, "kappa": p.exterior.kappa}}
                      for p, img in zip(photos, images, strict=True)]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def make_block(folder: Path) -> Block:
    folder = Path(folder)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    z, transform = hills_dem(BOUNDS, cell=20.0, relief=200.0, base=250.0, seed=4)
    photos = true_photos()
    images = []
    for p in photos:
        image = render_photo(p, z, transform, texture, dtype="uint8")
        images.append(write_photo(folder / "images" / f"{p.id}.tif", image))
    project = project_yaml(folder / "images" / "block.yaml", photos, images)
    return Block(folder, project, photos, images)
