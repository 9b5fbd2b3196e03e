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
            orientation=None):
    th = math.radians(angle_deg)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    g = np.eye(2) if orientation is None else orientation
    a = g @ rot @ np.array([[scale[0], shear], [0.0, scale[1]]]) / PIXEL
    c0 = np.array([SIZE / 2.0, SIZE / 2.0]) + offset
    return a, c0


def render_scan(path: Path, angle_deg: float = 1.5, orientation=None, dtype="uint8",
                cover: str | None = None, blur: float = 1.0, noise: float = 4.0, seed: int = 0
                ) -> Scan:
    import cv2

    from toolbox.photogrammetry.synthetic import write_photo

    rng = np.random.default_rng(seed)
    a, c0 = mapping(angle_deg, orientation=orientation)
    inv = np.linalg.inv(a)
    f = mark_function("cross", MARK, LINE)
    background = cv2.GaussianBlur(rng.normal(0, 1, (SIZE // 8, SIZE // 8)).astype(np.float32),
                                  (0, 0), 2)
    image = 45.0 + 60.0 * cv2.resize(background, (SIZE, SIZE), interpolation=cv2.INTER_CUBIC)
    centres = {}
    reach = int(MARK / PIXEL) + 4
    sub = (np.arange(4) + 0.5) / 4 - 0.5
    for mark, (x, y) in MARKS.items():
        centre = c0 + a @ np.array([x, -y])
        centres[mark] = centre
        c, r = int(centre[0]), int(centre[1])
        rows, cols = np.mgrid[r - reach:r + reach + 1, c - reach:c + reach + 1]
        acc = np.zeros(rows.shape)
        for dy in sub:
            for dx in sub:
                d = np.stack([cols + 0.5 + dx - centre[0], rows + 0.5 + dy - centre[1]])
                u = np.einsum("ij,jkl->ikl", inv, d)  # (x - x_m, -(y - y_m)) mm
                acc += f(u[0], -u[1])
        image[r - reach:r + reach + 1, c - reach:c + reach + 1] += 150.0 * acc / 16
    if cover is not None:
        c, r = (int(v) for v in centres[cover])
        image[r - 30:r + 31, c - 30:c + 31] = 70.0
    if blur:
        image = cv2.GaussianBlur(image.astype(np.float32), (0, 0), blur)
    image = image + rng.normal(0, noise, image.shape)
    if dtype == "uint16":
        image = np.clip(image * 257.0, 0, 65535).astype(np.uint16)
    else:
        image = np.clip(image, 0, 255).astype(np.uint8)
    write_photo(path, image)
    return Scan(path, centres)


def project_yaml(path: Path, scans: dict[str, str]) -> Path:
    import yaml

    doc = {"format": "orientation-project", "version": 1, "crs": "EPSG:3003",
           "cameras": [{"name": "rc", "principal_distance_mm": 153.0,
                        "fiducials_mm": {k: list(v) for k, v in MARKS.items()},
                        "pixel_size_mm": PIXEL}],
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
