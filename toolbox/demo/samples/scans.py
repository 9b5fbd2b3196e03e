"""Rendered scans of a frame with fiducial marks, for the orientation:fiducials demo and tests.

The truth: mark ``(x, y)`` mm sits at pixel ``c0 + G·A·(x, -y)/s`` (``s`` the scan pixel, ``A``
a small rotation + affinity, ``G`` the scan orientation, ``c0`` the scan centre plus an
offset). Each pixel near a mark takes the area average (4 x 4 samples) of the mark shape at its
exact mm position (the inverse of that mapping), then the scan is blurred and noised; the
marks' pixel centres are thus known without the code under test."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.matching.marks import mark_function

#: an asymmetric certificate: 4 corner and 4 side marks, the left one off the axis
MARKS = {"1": (-106.0, 106.0), "2": (106.0, 106.0), "3": (106.0, -106.0), "4": (-106.0, -106.0),
         "5": (0.0, 110.0), "6": (110.0, 0.0), "7": (0.0, -110.0), "8": (-112.0, 4.0)}
PIXEL = 0.1  # mm
SIZE = 2400  # px
MARK, LINE = 2.0, 0.3  # mm: cross length and line width


@dataclass
class Scan:
    path: Path
    centres: dict[str, np.ndarray]  # true pixel centres (toolbox convention)


def mapping(angle_deg: float, scale=(1.0004, 0.9993), shear=0.0008, offset=(12.0, -7.0),
            orientation=None, pixel: float = PIXEL, size: int = SIZE):
    th = math.radians(angle_deg)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    g = np.eye(2) if orientation is None else orientation
    a = g @ rot @ np.array([[scale[0], shear], [0.0, scale[1]]]) / pixel
    c0 = np.array([size / 2.0, size / 2.0]) + offset
    return a, c0


def mark_patches(a: np.ndarray, c0: np.ndarray, marks: dict, family: str, size_mm: float,
                 line_mm: float, pixel: float, blur: float, contrast: float = 150.0):
    """Per mark: its true pixel centre and ``(row0, col0, patch)``, the mark's brightness
    (area average of 4 x 4 samples of the shape at their exact mm position, then blurred),
    to be added to the background."""
    import cv2

    from toolbox.matching.camera_marks import mark_kind

    inv = np.linalg.inv(a)
    reach = int(size_mm / pixel) + 4 + int(4 * blur)
    sub = (np.arange(4) + 0.5) / 4 - 0.5
    out = {}
    for mark, (x, y) in marks.items():
        f = mark_function(family, size_mm, line_mm, mark_kind(x, y))
        centre = c0 + a @ np.array([x, -y])
        c, r = int(centre[0]), int(centre[1])
        rows, cols = np.mgrid[r - reach:r + reach + 1, c - reach:c + reach + 1]
        acc = np.zeros(rows.shape)
        for dy in sub:
            for dx in sub:
                d = np.stack([cols + 0.5 + dx - centre[0], rows + 0.5 + dy - centre[1]])
                u = np.einsum("ij,jkl->ikl", inv, d)  # (x - x_m, -(y - y_m)) mm
                acc += f(u[0], -u[1])
        patch = (contrast * acc / 16).astype(np.float32)
        if blur:
            patch = cv2.GaussianBlur(patch, (0, 0), blur)
        out[mark] = (centre, (r - reach, c - reach, patch))
    return out


def render_scan(path: Path, angle_deg: float = 1.5, orientation=None, dtype="uint8",
                cover: str | None = None, blur: float = 1.0, noise: float = 4.0, seed: int = 0,
                family: str = "cross", size_mm: float = MARK, line_mm: float = LINE,
                marks: dict | None = None) -> Scan:
    import cv2

    from toolbox.photogrammetry.synthetic import write_photo

    rng = np.random.default_rng(seed)
    a, c0 = mapping(angle_deg, orientation=orientation)
    background = cv2.GaussianBlur(rng.normal(0, 1, (SIZE // 8, SIZE // 8)).astype(np.float32),
                                  (0, 0), 2)
    image = 45.0 + 60.0 * cv2.resize(background, (SIZE, SIZE), interpolation=cv2.INTER_CUBIC)
    if blur:
        image = cv2.GaussianBlur(image.astype(np.float32), (0, 0), blur)
    centres = {}
    for mark, (centre, (r0, c0_, patch)) in mark_patches(
            a, c0, marks or MARKS, family, size_mm, line_mm, PIXEL, blur).items():
        centres[mark] = centre
        image[r0:r0 + patch.shape[0], c0_:c0_ + patch.shape[1]] += patch
    if cover is not None:
        c, r = (int(v) for v in centres[cover])
        half = max(30, int(0.8 * size_mm / PIXEL))
        image[r - half:r + half + 1, c - half:c + half + 1] = 70.0
    image = image + rng.normal(0, noise, image.shape)
    if dtype == "uint16":
        image = np.clip(image * 257.0, 0, 65535).astype(np.uint16)
    else:
        image = np.clip(image, 0, 255).astype(np.uint8)
    write_photo(path, image)
    return Scan(path, centres)


def render_big_scan(path: Path, size: int = 16644, pixel: float = 0.014, dtype: str = "uint8",
                    family: str = "wild_rc8", size_mm: float = 3.2, line_mm: float = 0.06,
                    angle_deg: float = 0.8, orientation=None, cover: str | None = None,
                    seed: int = 0, rows_per_strip: int = 512) -> Scan:
    """A ``size`` x ``size`` scan (tiled, uncompressed GeoTIFF, BigTIFF if needed) rendered strip
    by strip: memory holds one strip, never the scan. Background: a 1024 x 1024 tile of blurred
    texture plus noise repeated over the scan; marks as :func:`render_scan` draws them (the
    same truth: ``centre = c0 + A·(x, -y)``)."""
    import warnings

    import cv2
    import rasterio
    from rasterio.windows import Window

    rng = np.random.default_rng(seed)
    a, c0 = mapping(angle_deg, offset=(40.0, -25.0), orientation=orientation, pixel=pixel,
                    size=size)
    tile = 1024
    texture = cv2.resize(rng.normal(0, 1, (tile // 8, tile // 8)).astype(np.float32),
                         (tile, tile), interpolation=cv2.INTER_CUBIC)
    texture = cv2.GaussianBlur(45.0 + 60.0 * texture, (0, 0), 1.0)
    texture += rng.normal(0, 4.0, texture.shape).astype(np.float32)
    patches = mark_patches(a, c0, MARKS, family, size_mm, line_mm, pixel, blur=1.0)
    covered = None
    if cover is not None:
        half = int(0.8 * size_mm / pixel)
        c, r = (int(v) for v in patches[cover][0])
        covered = (r - half, c - half, r + half + 1, c + half + 1)
    scale = 257.0 if dtype == "uint16" else 1.0
    top = 65535 if dtype == "uint16" else 255
    profile = {"driver": "GTiff", "width": size, "height": size, "count": 1, "dtype": dtype,
               "tiled": True, "blockxsize": 512, "blockysize": 512, "BIGTIFF": "IF_SAFER"}
    reps = size // tile + 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as dst:
            for r0 in range(0, size, rows_per_strip):
                rows = min(rows_per_strip, size - r0)
                idx = (np.arange(r0, r0 + rows)) % tile
                strip = np.tile(texture[idx], (1, reps))[:, :size].copy()
                for _, (pr, pc, patch) in patches.values():
                    _add(strip, patch, pr - r0, pc)
                if covered is not None:
                    cr0, cc0, cr1, cc1 = covered
                    lo, hi = max(cr0 - r0, 0), min(cr1 - r0, rows)
                    if lo < hi:
                        strip[lo:hi, cc0:cc1] = 70.0
                out = np.clip(strip * scale, 0, top).astype(dtype)
                dst.write(out[None], window=Window(0, r0, size, rows))
    return Scan(Path(path), {m: v[0] for m, v in patches.items()})


def _add(strip: np.ndarray, patch: np.ndarray, row: int, col: int) -> None:
    """Add ``patch`` (top-left at strip row ``row``, column ``col``) where it overlaps."""
    lo, hi = max(row, 0), min(row + patch.shape[0], strip.shape[0])
    if lo < hi:
        strip[lo:hi, col:col + patch.shape[1]] += patch[lo - row:hi - row]


def project_yaml(path: Path, scans: dict[str, str], pixel: float = PIXEL) -> Path:
    import yaml

    doc = {"format": "orientation-project", "version": 1, "crs": "EPSG:3003",
           "cameras": [{"name": "rc", "principal_distance_mm": 153.0,
                        "fiducials_mm": {k: list(v) for k, v in MARKS.items()},
                        "pixel_size_mm": pixel}],
           "photos": [{"id": pid, "camera": "rc", "image": image}
                      for pid, image in scans.items()]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def make(folder: Path, made: dict) -> dict:
    """Two scans of 2400 x 2400 px (0.1 mm): one upright, one turned by 90 degrees and mirrored
    (emulsion down), with ``scans/project.yaml`` naming them and the certificate's marks."""
    target = Path(folder) / "scans"
    target.mkdir(parents=True, exist_ok=True)
    turned = np.array([[0.0, -1.0], [1.0, 0.0]]) @ np.array([[-1.0, 0.0], [0.0, 1.0]])
    render_scan(target / "scan_upright.tif", angle_deg=1.5)
    render_scan(target / "scan_turned.tif", angle_deg=-0.8, orientation=turned, seed=3)
    project = project_yaml(target / "project.yaml", {"scan_upright": "scan_upright.tif",
                                                      "scan_turned": "scan_turned.tif"})
    return {"fiducial_scans_project": project}
