"""Dense matching of a normalised (epipolar) pair with OpenCV's semi-global matcher.

``cv2.StereoSGBM`` (Hirschmüller 2008; mode SGBM_3WAY) on 8-bit images, with its own checks:
``disp12MaxDiff`` (left-right consistency: the right image's disparity of the matched pixel
must agree within LR_MAX_DIFF pixels), ``uniquenessRatio`` (the best cost must beat the second
by this percentage: a cost threshold) and speckle filtering (connected regions of fewer than
SPECKLE_WINDOW pixels whose disparities vary by more than SPECKLE_RANGE are removed). Pixels
outside either photo (alpha 0) are invalid. The images are matched in strips of rows with a
halo, so memory is bounded by the strip. Disparities ``d = col_left - col_right`` (pixels,
1/16 px resolution) are NaN where invalid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

STRIP_ROWS = 1024
STRIP_HALO = 48


@dataclass(frozen=True)
class MatchOptions:
    """StereoSGBM settings (pixels)."""

    block_size: int = 5  # matched block side (odd)
    uniqueness: int = 10  # % by which the best cost must beat the second
    speckle_window: int = 100  # largest speckle region removed, pixels²
    speckle_range: float = 2.0  # disparity variation inside one region
    lr_max_diff: int = 1  # left-right consistency tolerance
    max_disparities: int = 512  # cap on the disparity search range


def to_uint8(image: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """One 8-bit band: the mean of the bands, stretched from the 0.5 to the 99.5 percentile of
    the valid pixels (already-8-bit images are kept as they are)."""
    band = image.mean(axis=0) if image.ndim == 3 else image
    if band.dtype == np.uint8 or (image.ndim == 3 and image.dtype == np.uint8):
        return np.clip(np.rint(band), 0, 255).astype(np.uint8)
    values = band[valid]
    if values.size == 0:
        return np.zeros(band.shape, np.uint8)
    lo, hi = np.percentile(values, [0.5, 99.5])
    scale = 255.0 / (hi - lo) if hi > lo else 1.0
    return np.clip((band - lo) * scale, 0, 255).astype(np.uint8)


def disparity_range(geometry: Any, left: Any, low: float, high: float,
                    margin: float = 4.0) -> tuple[int, int]:
    """``(min_disparity, num_disparities)`` of heights ``low``..``high`` over the left photo's
    frame (its outline and centre lines, at both heights), ``num`` a multiple of 16."""
    from toolbox.stereo.epipolar import OUTLINE_POINTS

    outline = left.frame_outline_mm(OUTLINE_POINTS)
    samples = np.vstack([outline, outline * 0.5, np.zeros((1, 2))])
    values = []
    for height in (low, high):
        ground = left.image_to_ground(samples, height, invalid="nan")
        ground = ground[np.isfinite(ground).all(axis=1)]
        a, b = geometry.ground_to_pixels(ground, 0), geometry.ground_to_pixels(ground, 1)
        values.append(a[:, 0] - b[:, 0])
    values = np.concatenate(values)
    values = values[np.isfinite(values)]
    if values.size == 0:
        raise InputDataError("the height range is not seen by the pair")
    d_min = math.floor(values.min() - margin)
    count = int(math.ceil((values.max() + margin - d_min) / 16.0)) * 16
    return d_min, max(count, 16)


def match_pair(left: np.ndarray, right: np.ndarray, left_valid: np.ndarray,
               right_valid: np.ndarray, min_disparity: int, num_disparities: int,
               options: MatchOptions = MatchOptions(), feedback: Any = None) -> np.ndarray:
    """Disparity (float32, NaN invalid) of the left image, same shape, by row strips.

    ``left``/``right`` uint8 (rows, cols) of the same height (their widths may differ: both are
    padded to the wider one).
    """
    import cv2

    height = left.shape[0]
    width = max(left.shape[1], right.shape[1])
    pad = [(0, 0), (0, 0)]
    imgs = []
    for img, ok in ((left, left_valid), (right, right_valid)):
        pad[1] = (0, width - img.shape[1])
        imgs.append((np.pad(img, pad), np.pad(ok, pad)))
    (lp, lv), (rp, rv) = imgs
    bs = options.block_size
    matcher = cv2.StereoSGBM.create(
        minDisparity=int(min_disparity), numDisparities=int(num_disparities), blockSize=bs,
        P1=8 * bs * bs, P2=32 * bs * bs, disp12MaxDiff=int(options.lr_max_diff),
        uniquenessRatio=int(options.uniqueness), speckleWindowSize=int(options.speckle_window),
        speckleRange=max(1, int(round(options.speckle_range))),
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    out = np.full((height, width), np.nan, dtype=np.float32)
    starts = list(range(0, height, STRIP_ROWS))
    for k, r0 in enumerate(starts):
        r1 = min(height, r0 + STRIP_ROWS)
        a, b = max(0, r0 - STRIP_HALO), min(height, r1 + STRIP_HALO)
        raw = matcher.compute(lp[a:b], rp[a:b]).astype(np.float32)
        disp = raw[r0 - a:r1 - a]
        invalid = raw[r0 - a:r1 - a] < (min_disparity * 16)  # OpenCV: (min - 1) * 16
        disp = disp / 16.0
        disp[invalid] = np.nan
        out[r0:r1] = disp
        if feedback is not None:
            feedback.set_progress(100.0 * (k + 1) / len(starts))
    out = out[:, :left.shape[1]]
    out[~left_valid] = np.nan
    # the matched right pixel must lie inside the right photo
    rows, cols = np.nonzero(np.isfinite(out))
    target = np.rint(cols - out[rows, cols]).astype(np.int64)
    bad = (target < 0) | (target >= right.shape[1])
    bad[~bad] = ~right_valid[rows[~bad], target[~bad]]
    out[rows[bad], cols[bad]] = np.nan
    return out


def disparity_points(geometry: Any, disparity: np.ndarray, row_offset: int = 0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Ground points (K, 3) of the valid disparities (pixel centres) and their flat indices."""
    rows, cols = np.nonzero(np.isfinite(disparity))
    d = disparity[rows, cols].astype(np.float64)
    xyz = geometry.triangulate(cols + 0.5, rows + row_offset + 0.5, d)
    ok = np.isfinite(xyz).all(axis=1)
    return xyz[ok], (rows * disparity.shape[1] + cols)[ok]
