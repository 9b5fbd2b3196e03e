"""Synthetic aerial blocks with a known truth (tests, demos, benchmarks).

A block of ``strips`` x ``photos_per_strip`` vertical photos (forward overlap ``forward``, side
overlap ``side``; strips flown in alternate directions, kappa 0 / pi), small random attitudes,
over hilly terrain ``Z = z0 + relief·(sin·cos hills)``. Tie points on a regular ground grid are
imaged through the toolbox's own camera chain (:class:`toolbox.photogrammetry.photo.Photo`:
collinearity, lens distortion, interior orientation), which the bundle does not use, and
Gaussian noise of known sigma is added. Film photos are measured in image mm, digital photos in
pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

FRAME_MM = 230.0


@dataclass
class SyntheticBlockSpec:
    """What block to make (ground units metres, image mm)."""

    strips: int = 2
    photos_per_strip: int = 4
    forward: float = 0.60
    side: float = 0.25
    principal_distance_mm: float = 153.0
    scale: float = 10000.0  # photo scale number: flying height = c·scale
    relief: float = 150.0
    z0: float = 300.0
    digital: bool = False  # pixels (pixel_size_mm) instead of image mm
    pixel_size_mm: float = 0.012
    sigma_mm: float = 0.003  # image noise (film; digital: sigma_px·pixel_size)
    sigma_px: float = 0.3
    grid_m: float | None = None  # tie-point spacing, default a fifth of the base
    attitude_sigma: float = 0.01  # rad
    origin: tuple[float, float] = (1_688_000.0, 4_799_500.0)
    distortion_k1: float = 0.0  # the camera's true k1 (mm⁻²)
    distortion_terms: dict[str, float] = field(default_factory=dict)  # true k1-k3, p1, p2 (mm)
    seed: int = 0
    crs: str = "EPSG:3003"


@dataclass
class SyntheticBlock:
    project: object  # toolbox.photogrammetry.project.Project with the true exteriors
    point_ids: list[str]
    points: np.ndarray  # (P, 3) true ground coordinates
    obs_point: list[str] = field(default_factory=list)
    obs_photo: list[str] = field(default_factory=list)
    xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # noisy, mm or px
    true_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    kind: str = "image"
    sigma: float = 0.0  # in the measurement unit


def terrain_height(x: np.ndarray, y: np.ndarray, z0: float, relief: float,
                   origin: tuple[float, float]) -> np.ndarray:
    u, v = (x - origin[0]) / 900.0, (y - origin[1]) / 700.0
    return z0 + relief * (0.6 * np.sin(u) * np.cos(v) + 0.4 * np.sin(0.7 * u + 1.3 * v + 0.5))


def make_block(spec: SyntheticBlockSpec) -> SyntheticBlock:
    from toolbox.io.crs import parse_crs
    from toolbox.photogrammetry.camera import Camera, RadialDistortion
    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.photo import Photo
    from toolbox.photogrammetry.project import Project

    rng = np.random.default_rng(spec.seed)
    crs = parse_crs(spec.crs)
    c = spec.principal_distance_mm
    footprint = FRAME_MM * spec.scale / 1000.0  # m
    base = (1.0 - spec.forward) * footprint
    spacing = (1.0 - spec.side) * footprint
    height = c * spec.scale / 1000.0 + spec.z0
    terms = {"k1": spec.distortion_k1, **spec.distortion_terms}
    distortion = RadialDistortion.from_polynomial(**terms) if any(terms.values()) else None
    if spec.digital:
        n_px = int(round(FRAME_MM / spec.pixel_size_mm))
        camera = Camera("digital", c, (0.0, 0.0), image_size_px=(n_px, n_px),
                        pixel_size_mm=spec.pixel_size_mm, frame_size_mm=(FRAME_MM, FRAME_MM),
                        distortion=distortion)
    else:
        marks = {"1": (-110.0, 110.0), "2": (110.0, 110.0), "3": (110.0, -110.0),
                 "4": (-110.0, -110.0)}
        camera = Camera("film", c, (0.0, 0.0), marks, frame_size_mm=(FRAME_MM, FRAME_MM),
                        distortion=distortion)
    photos = {}
    ox, oy = spec.origin
    for s in range(spec.strips):
        for k in range(spec.photos_per_strip):
            forward = k if s % 2 == 0 else spec.photos_per_strip - 1 - k
            x0 = ox + forward * base
            y0 = oy - s * spacing
            kappa = 0.0 if s % 2 == 0 else math.pi
            om, ph = rng.normal(0.0, spec.attitude_sigma, 2)
            ka = kappa + rng.normal(0.0, spec.attitude_sigma)
            pid = f"{s + 1}_{k + 1:02d}"
            eo = ExteriorOrientation(pid, x0 + rng.normal(0, 10), y0 + rng.normal(0, 10),
                                     height + rng.normal(0, 10), float(om), float(ph),
                                     float(ka), crs=crs)
            photos[pid] = Photo(pid, camera, eo, strip=str(s + 1))
    project = Project(crs, {camera.name: camera}, photos)
    grid = spec.grid_m or base / 4.0
    half = 0.5 * footprint
    xs = np.arange(ox - half + 0.3 * grid, ox + (spec.photos_per_strip - 1) * base + half, grid)
    ys = np.arange(oy - (spec.strips - 1) * spacing - half + 0.3 * grid, oy + half, grid)
    gx, gy = np.meshgrid(xs, ys)
    gx = gx.ravel() + rng.uniform(-0.2, 0.2, gx.size) * grid
    gy = gy.ravel() + rng.uniform(-0.2, 0.2, gy.size) * grid
    gz = terrain_height(gx, gy, spec.z0, spec.relief, spec.origin)
    ground = np.column_stack([gx, gy, gz])
    ids = [f"t{k:05d}" for k in range(len(ground))]
    limit = 0.47 * FRAME_MM
    obs_point, obs_photo, xy_true = [], [], []
    for pid, photo in photos.items():
        mm = photo.ground_to_image(ground, behind="nan")
        inside = np.flatnonzero((np.abs(mm) < limit).all(axis=1))
        vals = photo.ground_to_pixel(ground[inside]) if spec.digital else mm[inside]
        obs_point += [ids[i] for i in inside]
        obs_photo += [pid] * len(inside)
        xy_true.append(vals)
    true_xy = np.concatenate(xy_true)
    sigma = spec.sigma_px if spec.digital else spec.sigma_mm
    noisy = true_xy + rng.normal(0.0, sigma, true_xy.shape)
    seen = {}
    for p in obs_point:
        seen[p] = seen.get(p, 0) + 1
    keep = [k for k, p in enumerate(obs_point) if seen[p] >= 2]
    used = sorted({obs_point[k] for k in keep})
    index = {p: k for k, p in enumerate(ids)}
    return SyntheticBlock(project, used, ground[[index[p] for p in used]],
                          [obs_point[k] for k in keep], [obs_photo[k] for k in keep],
                          noisy[keep], true_xy[keep], "pixel" if spec.digital else "image", sigma)


def corner_control(block: SyntheticBlock, count: int = 4) -> list[int]:
    """Indices (into ``block.point_ids``) of the ``count`` points nearest the block's corners
    and, beyond 4, of points nearest the middles of its long sides."""
    pts = block.points[:, :2]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid = 0.5 * (lo + hi)
    targets = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1]),
               (mid[0], lo[1]), (mid[0], hi[1]), (mid[0], mid[1])][:count]
    chosen: list[int] = []
    for t in targets:
        d = np.hypot(*(pts - np.asarray(t)).T)
        d[chosen] = np.inf
        chosen.append(int(np.argmin(d)))
    return chosen
