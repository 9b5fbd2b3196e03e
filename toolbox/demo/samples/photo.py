"""Sample photo for the rectification demo: a synthetic, tilted aerial photo of flat terrain.

The ground truth is an orthoimage laid on the Siena sample block (EPSG:3003): the sample
terrain's hillshade tinted by height, field parcels every 100 m with slightly different tints,
roads along the 100 m grid lines and white survey targets at the control points. A known camera
(c = 303.55 mm as the Siena Wild RC30, 1140 m above the plane Z = 315 m, tilts ω = 0.030,
φ = -0.020, κ = 0.050 rad) photographs it as if the terrain were that plane, so photo and
ground are related exactly by a homography (:func:`ground_to_pixel`). The frame is 230 mm on a
side, scanned as 1200 x 1200 pixels (0.1917 mm, about 0.72 m on the ground), written as JPEG.

``photo_gcps.csv`` has 12 points: ``id, col, row, X, Y, Z, role`` with ground X, Y exact, Z from
the sample DEM (the real relief, for the relief-displacement rule), image positions with
σ = 0.3 px of measurement noise, three check points and one gross error (P07 mis-measured by
about 12 px, 8.6 m on the ground). Pixel convention: origin at the top-left corner of the photo,
rows down, pixel centres at +0.5.

Everything is deterministic (fixed seed); the module builds in well under a second.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from toolbox.transforms.plane import apply_homography

CRS = "EPSG:3003"
PRINCIPAL_DISTANCE_MM = 303.55
FRAME_MM = 230.0
SIZE_PX = 1200
PIXEL_MM = FRAME_MM / SIZE_PX
PLANE_Z = 315.0
FLYING_HEIGHT = 1140.0  # above the plane
PROJECTION_CENTRE = (1688306.0, 4799662.0, PLANE_Z + FLYING_HEIGHT)
OMEGA, PHI, KAPPA = 0.030, -0.020, 0.050  # radians
NOISE_PX = 0.3
GROSS_ERROR_ID = "P07"
GROSS_ERROR_PX = (9.0, -8.0)
CHECK_IDS = ("P03", "P06", "P10")


def rotation(omega: float, phi: float, kappa: float) -> np.ndarray:
    """R = Rx(ω)·Ry(φ)·Rz(κ) (domain brief section 3, S000 l.336)."""
    co, so = np.cos(omega), np.sin(omega)
    cp, sp = np.cos(phi), np.sin(phi)
    ck, sk = np.cos(kappa), np.sin(kappa)
    rx = np.array([[1, 0, 0], [0, co, -so], [0, so, co]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[ck, -sk, 0], [sk, ck, 0], [0, 0, 1]])
    return rx @ ry @ rz


def ground_to_pixel() -> np.ndarray:
    """Homography ground (X, Y on the plane Z = PLANE_Z) -> photo pixel (col, row), from the
    collinearity equations (domain brief section 4) with the principal point at the frame
    centre: ``ξ = -c·(r11·dX + r21·dY + r31·dZ)/(r13·dX + r23·dY + r33·dZ)``, same for η with
    the second column; ``col = W/2 + ξ/pixel``, ``row = H/2 - η/pixel``."""
    x0, y0, z0 = PROJECTION_CENTRE
    r = rotation(OMEGA, PHI, KAPPA)
    shift = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, PLANE_Z - z0]])
    image_mm = np.diag([-PRINCIPAL_DISTANCE_MM, -PRINCIPAL_DISTANCE_MM, 1.0]) @ r.T @ shift
    to_pixel = np.array([[1.0 / PIXEL_MM, 0.0, SIZE_PX / 2.0],
                         [0.0, -1.0 / PIXEL_MM, SIZE_PX / 2.0], [0.0, 0.0, 1.0]])
    matrix = to_pixel @ image_mm
    return matrix / matrix[2, 2]


def control_points() -> tuple[list[str], np.ndarray]:
    """Ids and exact ground X, Y of the 12 points (a jittered 4 x 3 layout inside the photo)."""
    rng = np.random.default_rng(4)
    to_ground = np.linalg.inv(ground_to_pixel())
    cols = np.array([0.12, 0.38, 0.62, 0.88]) * SIZE_PX
    rows = np.array([0.14, 0.5, 0.86]) * SIZE_PX
    pixels = np.array([[c, r] for r in rows for c in cols])
    pixels += rng.uniform(-40, 40, pixels.shape)
    ground = np.round(apply_homography(to_ground, pixels), 3)
    return [f"P{i + 1:02d}" for i in range(len(ground))], ground


def orthoimage(x: np.ndarray, y: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """RGB (uint8, shape x.shape + (3,)) of the ground truth at map points ``x``, ``y``."""
    import cv2

    from toolbox.demo.samples.terrain import CELL, XMIN, YMAX, Z_HIGH, Z_LOW, terrain
    from toolbox.terrain.shading import hillshade

    z, _ = terrain()
    shade = hillshade(np.pad(z.astype("float64"), 1, mode="edge"), CELL, CELL)
    t = (z - Z_LOW) / (Z_HIGH - Z_LOW)
    low, high = np.array([96, 140, 70.0]), np.array([190, 160, 110.0])
    tint = low + t[..., None] * (high - low)
    texture = (tint * (0.35 + 0.65 * shade[..., None])).astype("float32")
    map_x = ((x - XMIN) / CELL - 0.5).astype("float32")
    map_y = ((YMAX - y) / CELL - 0.5).astype("float32")
    rgb = cv2.remap(texture, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    parcel = (np.floor(x / 100.0) * 7 + np.floor(y / 100.0) * 13) % 5
    rgb *= (0.9 + 0.05 * parcel)[..., None]
    road = (np.abs((x + 50) % 100 - 50) < 2.5) | (np.abs((y + 50) % 100 - 50) < 2.5)
    rgb[road] = (150, 150, 145)
    for tx, ty in targets:
        dx, dy = np.abs(x - tx), np.abs(y - ty)
        rgb[(dx < 2.2) & (dy < 2.2)] = (250, 250, 250)
        rgb[((dx < 0.4) & (dy < 1.6)) | ((dy < 0.4) & (dx < 1.6))] = (20, 20, 20)
    return np.clip(np.rint(rgb), 0, 255).astype("uint8")


def render_photo(targets: np.ndarray) -> np.ndarray:
    """(3, SIZE_PX, SIZE_PX) uint8: the orthoimage seen through :func:`ground_to_pixel`
    (each photo pixel shows the ground point of its centre)."""
    to_ground = np.linalg.inv(ground_to_pixel())
    c = np.arange(SIZE_PX) + 0.5
    cc, rr = np.meshgrid(c, c)
    ground = apply_homography(to_ground, np.column_stack([cc.ravel(), rr.ravel()]))
    x = ground[:, 0].reshape(cc.shape)
    y = ground[:, 1].reshape(cc.shape)
    return np.moveaxis(orthoimage(x, y, targets), -1, 0)


def make(folder: Path, made: dict) -> dict:
    import warnings

    import rasterio

    from toolbox.demo.samples.terrain import sample_heights, terrain

    ids, ground = control_points()
    photo = folder / "photo.jpg"
    data = render_photo(ground)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(photo, "w", driver="JPEG", width=SIZE_PX, height=SIZE_PX, count=3,
                           dtype="uint8", quality=92) as dst:
            dst.write(data)
    rng = np.random.default_rng(20090331)
    pixels = apply_homography(ground_to_pixel(), ground) + rng.normal(0.0, NOISE_PX, ground.shape)
    pixels[ids.index(GROSS_ERROR_ID)] += GROSS_ERROR_PX
    z, transform = terrain()
    heights = sample_heights(z, transform, ground[:, 0], ground[:, 1])
    gcps = folder / "photo_gcps.csv"
    with open(gcps, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "col", "row", "X", "Y", "Z", "role"])
        for i, ident in enumerate(ids):
            writer.writerow([ident, f"{pixels[i, 0]:.2f}", f"{pixels[i, 1]:.2f}",
                             f"{ground[i, 0]:.3f}", f"{ground[i, 1]:.3f}", f"{heights[i]:.2f}",
                             "check" if ident in CHECK_IDS else "control"])
    return {"photo": photo, "photo_gcps": gcps}
