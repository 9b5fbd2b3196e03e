"""Synthetic scenes with a known truth for the rectification tests (not a test module).

A camera (c = 100 mm, 0.1 mm pixels, 500 m above a plane, tilted ω = 0.15, φ = -0.10,
κ = 0.30 rad) looks at a ground plane near the Siena block; the photo is 400 x 300 pixels and
each pixel shows the ground point of its centre (source pixel convention: centres at +0.5).
The ground texture is analytic (smooth waves plus Gaussian blobs at known points), so the
ideal rectified raster and every blob's exact position are known.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

WIDTH, HEIGHT = 400, 300
C_MM, PIXEL_MM, FLYING_HEIGHT = 100.0, 0.1, 500.0
ORIGIN = np.array([1688000.0, 4799500.0])
TILTS = (0.15, -0.10, 0.30)
BLOB_PIXELS = np.array([[200.0, 150.0], [100.0, 80.0], [300.0, 220.0], [320.0, 90.0],
                        [90.0, 230.0]])  # where the blobs appear in the photo (approximately)
BLOB_SIGMA = 2.0
BLOB_HEIGHT = 400.0


def rotation(omega: float, phi: float, kappa: float) -> np.ndarray:
    co, so, cp, sp, ck, sk = (np.cos(omega), np.sin(omega), np.cos(phi), np.sin(phi),
                              np.cos(kappa), np.sin(kappa))
    return (np.array([[1, 0, 0], [0, co, -so], [0, so, co]])
            @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
            @ np.array([[ck, -sk, 0], [sk, ck, 0], [0, 0, 1]]))


def camera_homography(width: int, height: int, pixel_mm: float, c_mm: float, flying_m: float,
                      tilts=TILTS, origin=ORIGIN) -> np.ndarray:
    """Exact homography ground (X, Y) -> photo (col, row) of a tilted camera ``flying_m`` above
    the plane Z = 0 at ``origin``, from collinearity (bench/rectify_bench.py uses it too)."""
    r = rotation(*tilts)
    shift = np.array([[1, 0, -origin[0]], [0, 1, -origin[1]], [0, 0, -flying_m]])
    mm = np.diag([-c_mm, -c_mm, 1.0]) @ r.T @ shift
    k = np.array([[1 / pixel_mm, 0, width / 2], [0, -1 / pixel_mm, height / 2], [0, 0, 1]])
    m = k @ mm
    return m / m[2, 2]


def ground_to_pixel(tilts=TILTS) -> np.ndarray:
    """Exact homography: ground (X, Y) -> photo (col, row) of this scene's camera."""
    return camera_homography(WIDTH, HEIGHT, PIXEL_MM, C_MM, FLYING_HEIGHT, tilts)


def apply(matrix: np.ndarray, xy: np.ndarray) -> np.ndarray:
    p = np.column_stack([xy, np.ones(len(xy))]) @ np.asarray(matrix).T
    return p[:, :2] / p[:, 2:]


def blobs() -> np.ndarray:
    """Ground X, Y of the Gaussian blobs (rounded to the cm), (5, 2)."""
    return np.round(apply(np.linalg.inv(ground_to_pixel()), BLOB_PIXELS), 2)


def texture(x: np.ndarray, y: np.ndarray, with_blobs: bool = True) -> np.ndarray:
    """Ground radiometry at map points (float64)."""
    u, v = x - ORIGIN[0], y - ORIGIN[1]
    f = 600.0 + 150.0 * np.sin(2 * np.pi * u / 37.0 + 0.3) * np.cos(2 * np.pi * v / 53.0) \
        + 100.0 * np.sin(2 * np.pi * (u + 2 * v) / 71.0)
    if with_blobs:
        for bx, by in blobs():
            f = f + BLOB_HEIGHT * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2 * BLOB_SIGMA ** 2))
    return f


def photo(bands: int = 1, dtype: str = "float32", tilts=TILTS) -> np.ndarray:
    """(bands, HEIGHT, WIDTH) photo of :func:`texture` (band k = texture + 50·k)."""
    to_ground = np.linalg.inv(ground_to_pixel(tilts))
    cc, rr = np.meshgrid(np.arange(WIDTH) + 0.5, np.arange(HEIGHT) + 0.5)
    g = apply(to_ground, np.column_stack([cc.ravel(), rr.ravel()]))
    base = texture(g[:, 0], g[:, 1]).reshape(HEIGHT, WIDTH)
    data = np.stack([base + 50.0 * k for k in range(bands)])
    if np.dtype(dtype).kind in "iu":
        data = np.clip(np.rint(data / (4.0 if np.dtype(dtype).itemsize == 1 else 1.0)),
                       0, np.iinfo(dtype).max)
    return data.astype(dtype)


def write_photo(path: Path, data: np.ndarray, **extra) -> Path:
    """Write a non-georeferenced raster (GTiff or PNG by suffix)."""
    import warnings

    import rasterio

    driver = {".png": "PNG", ".jpg": "JPEG"}.get(path.suffix.lower(), "GTiff")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver=driver, width=data.shape[2], height=data.shape[1],
                           count=data.shape[0], dtype=data.dtype.name, **extra) as dst:
            dst.write(data)
    return path


def gcp_table(n: int = 20, noise: float = 0.0, gross: dict[str, tuple[float, float]] | None = None,
              checks: tuple[str, ...] = (), seed: int = 7, tilts=TILTS):
    """Ids, image (col, row) with noise and gross errors, exact ground X, Y, roles."""
    rng = np.random.default_rng(seed)
    image_true = np.column_stack([rng.uniform(15, WIDTH - 15, n), rng.uniform(15, HEIGHT - 15, n)])
    ground = apply(np.linalg.inv(ground_to_pixel(tilts)), image_true)
    image = image_true + rng.normal(0.0, noise, image_true.shape) if noise else image_true.copy()
    ids = [f"G{i + 1:02d}" for i in range(n)]
    for ident, (dc, dr) in (gross or {}).items():
        image[ids.index(ident)] += (dc, dr)
    roles = ["check" if i in checks else "control" for i in ids]
    return ids, image, ground, roles


def write_gcp_csv(path: Path, ids, image, ground, roles, z=None, image_names=("col", "row"),
                  role_name: str = "role") -> Path:
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", *image_names, "X", "Y", *(["Z"] if z is not None else []),
                         role_name])
        for k, ident in enumerate(ids):
            writer.writerow([ident, repr(float(image[k, 0])), repr(float(image[k, 1])),
                             repr(float(ground[k, 0])), repr(float(ground[k, 1])),
                             *([repr(float(z[k]))] if z is not None else []), roles[k]])
    return path


def photo_and_transform(folder: Path, dtype: str, name: str = "photo.tif") -> tuple[Path, Path]:
    """A one-band photo of ``dtype`` in ``folder`` and its exact transform ``t.json``, estimated
    from 12 noise-free GCPs through rectify:estimate."""
    import toolbox

    path = write_photo(folder / name, photo(1, dtype))
    ids, image, ground, roles = gcp_table(12)
    gcps = write_gcp_csv(folder / "gcps.csv", ids, image, ground, roles)
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "ROBUST": "none",
                                     "OUTPUT": folder / "t.json"})
    return path, folder / "t.json"
