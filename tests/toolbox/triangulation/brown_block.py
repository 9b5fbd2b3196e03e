"""A synthetic digital block photographed by a Brown camera, rendered with OpenCV's
``projectPoints`` (independent of the bundle's own model): 3 strips x 5 photos, 4000 x 3000 px,
f = 3000 px, 120 m above hilly ground (relief 40 m), 60 % forward / 25 % side overlap, strips
flown in alternate directions; tie points on a 15 m grid, Gaussian pixel noise."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from toolbox.triangulation.model import rotations

SIZE = (4000, 3000)
#: the true camera: (f, cx, cy, k1, k2, k3, p1, p2), px and OpenCV's unitless terms
TRUE = np.array([3000.0, 2012.0, 1492.0, -0.08, 0.03, 0.0, 5e-4, -3e-4])
#: the nominal camera the adjustment starts from
NOMINAL = np.array([2950.0, 2000.0, 1500.0, 0.0, 0.0, 0.0, 0.0, 0.0])
ORIGIN = np.array([1_688_000.0, 4_799_500.0, 0.0])


def ground_height(x, y):
    return 40.0 * (np.sin(x / 70.0) * np.cos(y / 55.0) + 0.5)


def project(calib: np.ndarray, exterior: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Product pixels (top-left centre 0.5) of ground ``pts`` on a photo, by cv2.projectPoints."""
    f, cx, cy, k1, k2, k3, p1, p2 = calib
    k = np.array([[f, 0, cx - 0.5], [0, f, cy - 0.5], [0, 0, 1.0]])
    r_cv = np.diag([1.0, -1.0, -1.0]) @ rotations(exterior[None, 3:])[0][0].T
    rvec, _ = cv2.Rodrigues(r_cv)
    tvec = -r_cv @ exterior[:3]
    px, _ = cv2.projectPoints(pts[:, None, :], rvec, tvec, k, np.array([k1, k2, p1, p2, k3]))
    return px.reshape(-1, 2) + 0.5


@dataclass
class BrownBlock:
    photo_ids: list[str]
    exterior: np.ndarray  # (n, 6) true, global
    point_ids: list[str]
    points: np.ndarray  # (P, 3) true, global
    obs_photo: np.ndarray
    obs_point: np.ndarray
    px: np.ndarray  # noisy pixels
    control: list[int]  # indices of full control points


def make_brown_block(sigma_px: float = 0.3, seed: int = 0, grid: float = 15.0) -> BrownBlock:
    rng = np.random.default_rng(seed)
    h = 120.0
    width, height = SIZE[0] / TRUE[0] * h, SIZE[1] / TRUE[0] * h  # footprint, m
    base, gap = 0.4 * width, 0.75 * height
    ext, ids = [], []
    for s in range(3):
        for j in range(5):
            kappa = 0.0 if s % 2 == 0 else np.pi
            ext.append([j * base, s * gap, h + 20.0, *rng.normal(0, 0.02, 2), kappa
                        + rng.normal(0, 0.02)])
            ids.append(f"{s + 1}_{j + 1}")
    ext = np.array(ext)
    gx, gy = np.meshgrid(np.arange(-width / 2, 4 * base + width / 2, grid),
                         np.arange(-height / 2, 2 * gap + height / 2, grid))
    pts = np.column_stack([gx.ravel(), gy.ravel(), ground_height(gx.ravel(), gy.ravel())])
    pts[:, :2] += rng.uniform(-grid / 3, grid / 3, (len(pts), 2))
    pts[:, 2] = ground_height(pts[:, 0], pts[:, 1])
    obs_photo, obs_point, px = [], [], []
    for j, e in enumerate(ext):
        p = project(TRUE, e, pts)
        inside = np.flatnonzero((p[:, 0] > 20) & (p[:, 0] < SIZE[0] - 20) & (p[:, 1] > 20)
                                & (p[:, 1] < SIZE[1] - 20))
        obs_photo += [j] * len(inside)
        obs_point += inside.tolist()
        px.append(p[inside])
    obs_photo, obs_point, px = np.array(obs_photo), np.array(obs_point), np.vstack(px)
    rays = np.bincount(obs_point, minlength=len(pts))
    keep = np.flatnonzero(rays >= 2)
    new = np.full(len(pts), -1)
    new[keep] = np.arange(len(keep))
    sel = rays[obs_point] >= 2
    obs_photo, obs_point, px = obs_photo[sel], new[obs_point[sel]], px[sel]
    pts = pts[keep]
    px = px + rng.normal(0, sigma_px, px.shape)
    # 8 control points near the block's corners and edge middles
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    targets = [(a, b) for a in (0.05, 0.5, 0.95) for b in (0.05, 0.95)] + [(0.25, 0.5),
                                                                             (0.75, 0.5)]
    control = [int(np.argmin(np.hypot(*(pts[:, :2] - (lo + t * (hi - lo))).T)))
               for t in np.array(targets)]
    return BrownBlock(ids, ext + np.r_[ORIGIN, 0, 0, 0], [f"t{k}" for k in range(len(pts))],
                      pts + ORIGIN, obs_photo, obs_point, px, control)
