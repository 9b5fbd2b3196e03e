"""Keypoints and descriptors (OpenCV) on a grey image, tile by tile.

Detecting tile by tile bounds SIFT's memory (its scale space is ~40 bytes per pixel) and spreads
the features: every tile gets at most ``per_tile`` of its strongest keypoints. Keypoints are
kept only in their tile's core (tiles overlap by ``margin`` so that none is lost at a seam).
Positions are returned in the toolbox pixel convention (top-left pixel centre at (0.5, 0.5));
OpenCV's have the centre at (0, 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: AKAZE (and KAZE, BRISK) left OpenCV's main modules in OpenCV 5 (now in opencv-contrib):
#: offered only where the installed OpenCV has it
DETECTORS = ("sift", "orb", "akaze")


def available(detector: str) -> bool:
    import cv2

    return detector != "akaze" or hasattr(cv2, "AKAZE_create")


@dataclass
class Features:
    """``xy`` (N, 2) positions (col, row; pixel centres at +0.5), ``size`` (N,) and ``angle``
    (N,, degrees) of the keypoints, ``descriptors`` (N, D) float32 or uint8 (binary)."""

    xy: np.ndarray
    size: np.ndarray
    angle: np.ndarray
    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.xy)

    def subset(self, keep: np.ndarray) -> Features:
        return Features(self.xy[keep], self.size[keep], self.angle[keep], self.descriptors[keep])

    def scaled(self, sx: float, sy: float) -> Features:
        """Positions and sizes in a frame ``(sx, sy)`` times larger (level -> full resolution)."""
        return Features(self.xy * np.array([sx, sy]), self.size * np.sqrt(sx * sy), self.angle,
                        self.descriptors)


def binary(detector: str) -> bool:
    """True when the detector's descriptors are binary (Hamming distance)."""
    return detector in ("akaze", "orb")


def _create(detector: str, budget: int):
    import cv2

    if detector == "sift":
        # precise upscale: without it the doubled first octave shifts keypoints by about a
        # quarter pixel, which cancels between photos of one strip but not across strips
        return cv2.SIFT_create(nfeatures=budget, enable_precise_upscale=True)
    if detector == "akaze":
        return cv2.AKAZE_create(threshold=0.0005)
    if detector == "orb":
        return cv2.ORB_create(nfeatures=budget, fastThreshold=5)
    raise ValueError(f"unknown detector {detector!r} (expected one of {', '.join(DETECTORS)})")


def detect(image: np.ndarray, mask: np.ndarray | None = None, detector: str = "sift",
           tile: int = 1024, per_tile: int = 2000, margin: int = 32) -> Features:
    """Keypoints and descriptors of a grey uint8 ``image`` (H, W), where ``mask`` (H, W, bool;
    None = everywhere) is True, ``tile`` x ``tile`` pixels at a time."""
    h, w = image.shape
    det = _create(detector, per_tile)
    xy, size, angle, desc = [], [], [], []
    for r0 in range(0, h, tile):
        for c0 in range(0, w, tile):
            r1, c1 = min(h, r0 + tile), min(w, c0 + tile)
            a0, b0 = max(0, r0 - margin), max(0, c0 - margin)
            a1, b1 = min(h, r1 + margin), min(w, c1 + margin)
            sub = np.ascontiguousarray(image[a0:a1, b0:b1])
            sub_mask = None if mask is None else \
                np.ascontiguousarray(mask[a0:a1, b0:b1]).astype(np.uint8) * 255
            if sub_mask is not None and not sub_mask.any():
                continue
            kps, d = det.detectAndCompute(sub, sub_mask)
            if not kps or d is None:
                continue
            pts = np.array([k.pt for k in kps], dtype="float64") + [b0, a0]
            core = (pts[:, 0] >= c0) & (pts[:, 0] < c1) & (pts[:, 1] >= r0) & (pts[:, 1] < r1)
            if detector != "sift" and core.sum() > per_tile:  # AKAZE has no budget of its own
                response = np.array([k.response for k in kps])
                order = np.argsort(-np.where(core, response, -np.inf))[:per_tile]
                core = np.zeros(len(kps), bool)
                core[order] = True
            xy.append(pts[core] + 0.5)
            size.append(np.array([k.size for k in kps])[core])
            angle.append(np.array([k.angle for k in kps])[core])
            desc.append(d[core])
    if not xy:
        width = 61 if detector == "akaze" else 32 if detector == "orb" else 128
        return Features(np.zeros((0, 2)), np.zeros(0), np.zeros(0),
                        np.zeros((0, width), np.uint8 if binary(detector) else np.float32))
    return Features(np.vstack(xy), np.concatenate(size), np.concatenate(angle), np.vstack(desc))


def border_mask(height: int, width: int, margin_px: float) -> np.ndarray | None:
    """True inside the image less a border of ``margin_px`` pixels (fiducial marks, data strip);
    None when there is no margin."""
    m = int(round(margin_px))
    if m <= 0:
        return None
    mask = np.zeros((height, width), bool)
    mask[m:height - m, m:width - m] = True
    return mask
