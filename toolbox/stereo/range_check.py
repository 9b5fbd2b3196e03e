"""Does MIN_HEIGHT..MAX_HEIGHT hold the terrain a pair sees? A coarse match over a wider range.

Semi-global matching searches only the disparities of the height range it is given: a range
that misses the terrain does not fail, it returns wrong matches inside the range (a DSM of
plausible-looking garbage). So before the dense match, the epipolar pair is matched at
1/:data:`FACTOR` of its resolution over the range's disparities widened by their span on both
sides; the heights of those matches tell where the terrain is. Less than :data:`ERROR_INSIDE`
of them inside the range: an error naming the heights found; less than :data:`WARN_INSIDE`:
a warning (those parts get no height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

FACTOR = 4
ERROR_INSIDE = 0.5
WARN_INSIDE = 0.9
MIN_MATCHES = 200  # fewer coarse matches: nothing to judge (an untextured pair)


@dataclass
class RangeCheck:
    """Heights (m) of the coarse matches."""

    heights: np.ndarray

    def inside(self, low: float, high: float) -> float:
        return float(np.mean((self.heights >= low) & (self.heights <= high)))

    def describe(self, low: float, high: float) -> str:
        p5, p50, p95 = np.percentile(self.heights, [5, 50, 95])
        return (f"a match at 1/{FACTOR} resolution over up to 3 times the range's disparities puts "
                f"{100 * (1 - self.inside(low, high)):.0f} % of "
                f"the terrain outside MIN_HEIGHT {low:g} .. MAX_HEIGHT {high:g} (its heights: "
                f"5 % {p5:.0f}, median {p50:.0f}, 95 % {p95:.0f} m)")


def coarse_heights(geometry: Any, left: Any, images: tuple[np.ndarray, np.ndarray],
                   valids: tuple[np.ndarray, np.ndarray], low: float, high: float,
                   options: Any) -> RangeCheck:
    """Match the uint8 epipolar ``images`` (left, right; ``valids`` their masks) at 1/FACTOR
    over the widened disparities; the heights of the matches."""
    import cv2

    from toolbox.stereo.matching import disparity_range, match_pair

    d_min, count = disparity_range(geometry, left, low, high)
    small, masks = [], []
    for image, valid in zip(images, valids, strict=True):
        size = (max(1, image.shape[1] // FACTOR), max(1, image.shape[0] // FACTOR))
        small.append(cv2.resize(image, size, interpolation=cv2.INTER_AREA))
        masks.append(cv2.resize(valid.astype(np.uint8) * 255, size,
                                interpolation=cv2.INTER_AREA) == 255)
    height = min(s.shape[0] for s in small)
    small = [s[:height] for s in small]
    masks = [m[:height] for m in masks]
    # the range's disparities widened by their span on both sides, at most half the width
    cap = max(16, small[0].shape[1] // 32 * 16)
    c_count = min(int(math.ceil((3 * count / FACTOR + 2) / 16.0)) * 16, cap)
    extra = max(0.0, (c_count * FACTOR - count) / 2.0)  # full-resolution pixels a side
    c_min = math.floor((d_min - extra) / FACTOR)
    disparity = match_pair(small[0], small[1], masks[0], masks[1], c_min, c_count, options)
    rows, cols = np.nonzero(np.isfinite(disparity))
    d = disparity[rows, cols].astype(np.float64)
    xyz = geometry.triangulate((cols + 0.5) * FACTOR, (rows + 0.5) * FACTOR, d * FACTOR)
    z = xyz[:, 2][np.isfinite(xyz[:, 2])]
    return RangeCheck(z)


def check_terrain_range(check: RangeCheck, low: float, high: float, pair: str,
                        feedback: Any) -> None:
    """:class:`InputDataError` when less than half the coarse matches are inside the range; a
    warning when less than 90 %."""
    if len(check.heights) < MIN_MATCHES:
        return
    inside = check.inside(low, high)
    if inside < ERROR_INSIDE:
        raise InputDataError(f"pair {pair}: {check.describe(low, high)}: set MIN_HEIGHT and "
                             "MAX_HEIGHT to the terrain's (roofs and trees included)")
    if inside < WARN_INSIDE:
        feedback.push_warning(f"pair {pair}: {check.describe(low, high)}; those parts get no "
                              "height")
