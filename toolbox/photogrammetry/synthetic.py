"""Synthetic photos with a known truth, for tests, demos and benchmarks.

A synthetic photo is rendered the way a camera takes it: the ray of every pixel centre (pixel
convention of :mod:`toolbox.photogrammetry`: origin at the top-left corner, centres at +0.5) is
traced from the projection centre through the interior orientation, radial distortion and the
collinearity equations (domain brief section 4) down to the first surface point of a DEM/DSM
(:func:`toolbox.photogrammetry.collinearity.monoplot`, ``march``: rays marched from the top of the
surface, so what a tall object hides is hidden), and the pixel takes the value of a known
texture at that ground point. Orthorectifying the photo must give the texture back.

This is the *image -> ground* direction (ray marching), while orthorectification runs *ground ->
image*: the two share only the camera model, so a test comparing them checks the ortho's
geometry independently.

API
---
- :func:`frame_photo`: an oriented :class:`~toolbox.photogrammetry.photo.Photo` from plain numbers;
- :func:`render_photo`: the photo's pixels from a DEM array, its affine transform and a texture;
- :func:`wave_texture`: a smooth, band-limited, analytic texture ``f(X, Y)``;
- :func:`hills_dem`: an analytic DEM (a sum of Gaussian hills) with a chosen relief;
- :func:`box_dsm`: a flat DSM with rectangular buildings (for occlusion tests);
- :func:`write_photo`: the rendered array as a plain (not georeferenced) GeoTIFF.

Example
-------
>>> photo = frame_photo((1000.0, 2000.0, 1500.0), (0.01, -0.02, 0.3), width=400, height=300)
>>> z, transform = hills_dem((0.0, 500.0, 2000.0, 3500.0), cell=10.0, relief=200.0)
>>> image = render_photo(photo, z, transform, wave_texture(seed=1))
>>> image.shape
(300, 400)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

Texture = Callable[[np.ndarray, np.ndarray], np.ndarray]


def frame_photo(centre: Sequence[float], angles: Sequence[float], *, width: int = 1000,
                height: int = 1000, principal_distance_mm: float = 153.0,
                pixel_size_mm: float | None = None, frame_mm: float = 230.0,
                principal_point_mm: tuple[float, float] = (0.0, 0.0), distortion: Any = None,
                angle_unit: str = "rad", crs: Any = None, photo_id: str = "synthetic",
                image: Path | str | None = None) -> Any:
    """A digital frame photo: ``width`` x ``height`` pixels of ``pixel_size_mm`` (default: the
    longer side spans ``frame_mm``), projection centre ``(X0, Y0, Z0)``, attitude
    ``(omega, phi, kappa)`` in ``angle_unit``. The pixel -> image transform is the camera's
    (image centre = fiducial centre)."""
    from toolbox.photogrammetry.camera import Camera
    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.photo import Photo

    pixel = pixel_size_mm or frame_mm / max(width, height)
    camera = Camera(f"{photo_id} camera", float(principal_distance_mm),
                    tuple(map(float, principal_point_mm)), image_size_px=(int(width), int(height)),
                    pixel_size_mm=float(pixel), frame_size_mm=(width * pixel, height * pixel),
                    distortion=distortion)
    eo = ExteriorOrientation.from_angles(photo_id, *centre, *angles, unit=angle_unit, crs=crs)
    return Photo(photo_id, camera, eo, image=None if image is None else Path(image))


def render_photo(photo: Any, dem: np.ndarray, dem_transform: Any, texture: Texture,
                 width: int | None = None, height: int | None = None, *, supersample: int = 1,
                 fill: float = np.nan, dtype: Any = "float32") -> np.ndarray:
    """Render the photo of ``texture`` draped on a DEM.

    Parameters
    ----------
    photo : Photo-like
        Needs ``monoplot_pixels(points, surface)`` (an oriented
        :class:`~toolbox.photogrammetry.photo.Photo`) and, unless width/height are given,
        ``camera.image_size_px``.
    dem : (rows, cols) array
        Heights (NaN = nodata), north-up, bilinear between cell centres.
    dem_transform : affine.Affine
        The DEM's transform (pixel corner -> ground), ``e < 0``.
    texture : callable ``(X, Y) -> values``
        Ground radiometry; returns an array of X's shape (one band) or ``(bands,) + X.shape``.
    width, height : int, optional
        Photo size in pixels (default: the camera's ``image_size_px``).
    supersample : int
        Rays per pixel side; the pixel is their mean (a sensor's box filter). 1 = the value at
        the pixel centre.
    fill : float
        Value of pixels whose ray misses the DEM (outside it or on nodata).
    dtype : numpy dtype
        Output type; integers are rounded and clipped to their range.

    Returns
    -------
    (height, width) or (bands, height, width) array
    """
    from toolbox.photogrammetry.surface import DemSurface

    if width is None or height is None:
        width, height = photo.camera.image_size_px
    s = int(supersample)
    if s < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    surface = DemSurface.from_transform(np.asarray(dem, dtype="float64"), dem_transform)
    offsets = (np.arange(s) + 0.5) / s
    total = None
    for dy in offsets:
        for dx in offsets:
            cols, rows = np.meshgrid(np.arange(width) + dx, np.arange(height) + dy)
            hit = photo.monoplot_pixels((cols, rows), surface)
            ok = hit.ok
            x = np.where(ok, hit.xyz[..., 0], 0.0)
            y = np.where(ok, hit.xyz[..., 1], 0.0)
            value = np.asarray(texture(x, y), dtype="float64")
            value = np.where(ok, value, np.nan)
            total = value if total is None else total + value
    image = total / (s * s)
    image = np.where(np.isfinite(image), image, fill)
    out_type = np.dtype(dtype)
    if out_type.kind in "iu":
        info = np.iinfo(out_type)
        image = np.clip(np.rint(np.nan_to_num(image, nan=0.0)), info.min, info.max)
    return image.astype(out_type)


def wave_texture(seed: int = 0, wavelength: tuple[float, float] = (15.0, 60.0),
                 waves: int = 12, mean: float = 128.0, amplitude: float = 90.0,
                 bands: int = 1) -> Texture:
    """A smooth analytic texture: a sum of ``waves`` plane waves of random direction, phase and
    wavelength (uniform in ``wavelength``, ground units), scaled to ``mean ± amplitude``.

    Band-limited (no detail finer than the shortest wavelength), so a photo of it sampled at a
    few pixels per wavelength is free of aliasing, and it is textured everywhere (phase
    correlation finds a unique shift on any patch). ``bands`` > 1 gives independent bands with
    a leading band axis.
    """
    rng = np.random.default_rng(seed)
    params = []
    for _ in range(bands):
        angle = rng.uniform(0, np.pi, waves)
        k = 2 * np.pi / rng.uniform(*wavelength, waves)
        params.append((k * np.cos(angle), k * np.sin(angle), rng.uniform(0, 2 * np.pi, waves)))
    scale = amplitude / (3.0 * np.sqrt(waves / 2.0))  # std amplitude/3: clipping is rare

    def texture(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        # float64: phases k·X of projected coordinates (~1e6 m) keep ~1e-10 rad
        x = np.asarray(x, dtype="float64")
        y = np.asarray(y, dtype="float64")
        out = []
        for kx, ky, ph in params:
            v = np.zeros_like(x)
            for a, b, p in zip(kx, ky, ph, strict=True):
                v += np.sin(a * x + b * y + p)
            out.append(np.clip(mean + scale * v, mean - amplitude, mean + amplitude))
        return out[0] if bands == 1 else np.stack(out)

    return texture


def hills_dem(bounds: tuple[float, float, float, float], cell: float, relief: float = 200.0,
              base: float = 300.0, hills: int = 6, seed: int = 0) -> tuple[np.ndarray, Any]:
    """An analytic DEM over ``bounds`` (xmin, ymin, xmax, ymax): ``base`` plus Gaussian hills
    scaled so the heights span exactly ``relief``. Returns (float32 heights, affine transform)."""
    from affine import Affine

    xmin, ymin, xmax, ymax = bounds
    cols = int(np.ceil((xmax - xmin) / cell))
    rows = int(np.ceil((ymax - ymin) / cell))
    transform = Affine(cell, 0.0, xmin, 0.0, -cell, ymin + rows * cell)
    x = xmin + (np.arange(cols) + 0.5) * cell
    y = ymin + rows * cell - (np.arange(rows) + 0.5) * cell
    xx, yy = np.meshgrid(x, y)
    rng = np.random.default_rng(seed)
    z = np.zeros_like(xx)
    span = min(xmax - xmin, ymax - ymin)
    for _ in range(hills):
        cx, cy = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
        sigma = rng.uniform(0.12, 0.3) * span
        z += rng.uniform(0.5, 1.0) * np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma ** 2))
    z = base + (z - z.min()) / np.ptp(z) * relief
    return z.astype("float32"), transform


def box_dsm(bounds: tuple[float, float, float, float], cell: float, ground: float,
            boxes: Sequence[tuple[float, float, float, float, float]]) -> tuple[np.ndarray, Any]:
    """A flat DSM at height ``ground`` with buildings: ``boxes`` of (xmin, ymin, xmax, ymax,
    height above ground); a cell belongs to a box when its centre is inside. Returns
    (float32 heights, affine transform)."""
    from affine import Affine

    xmin, ymin, xmax, ymax = bounds
    cols = int(round((xmax - xmin) / cell))
    rows = int(round((ymax - ymin) / cell))
    transform = Affine(cell, 0.0, xmin, 0.0, -cell, ymin + rows * cell)
    x = xmin + (np.arange(cols) + 0.5) * cell
    y = ymin + rows * cell - (np.arange(rows) + 0.5) * cell
    xx, yy = np.meshgrid(x, y)
    z = np.full(xx.shape, float(ground))
    for bx0, by0, bx1, by1, h in boxes:
        z[(xx > bx0) & (xx < bx1) & (yy > by0) & (yy < by1)] = ground + h
    return z.astype("float32"), transform


def write_photo(path: Path | str, image: np.ndarray) -> Path:
    """Write a rendered photo ((h, w) or (bands, h, w)) as a tiled GeoTIFF without
    georeferencing (as a scan is delivered)."""
    import warnings

    import rasterio

    data = image if image.ndim == 3 else image[None]
    profile = {"driver": "GTiff", "width": data.shape[2], "height": data.shape[1],
               "count": data.shape[0], "dtype": data.dtype.name, "tiled": True,
               "blockxsize": 256, "blockysize": 256, "compress": "deflate"}
    if data.shape[0] == 3 and data.dtype == np.uint8:
        profile["photometric"] = "RGB"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as dst:
            dst.write(data)
    return Path(path)
