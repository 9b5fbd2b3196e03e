"""Normalised cross-correlation with a sub-pixel peak (kernel: arrays in, numbers out).

The score map is OpenCV's ``TM_CCOEFF_NORMED`` (zero-mean NCC in -1..1). The peak is refined by
fitting a parabola through the maximum and its two neighbours along each axis
(``δ = (s₋ - s₊) / (2·(s₋ - 2·s₀ + s₊))``, |δ| < 0.5). The runner-up is the best score farther
than ``exclusion`` pixels from the peak: a runner-up close to the peak means an ambiguous match
(a repeated pattern).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Peak:
    """Peak of a score map: ``x``, ``y`` (sub-pixel, in score-map cells: the template's top-left
    offset in the search image), ``score``, ``runner_up`` (NaN if none) and ``on_border`` (the
    maximum lies on the map's edge: the true peak may be outside)."""

    x: float
    y: float
    score: float
    runner_up: float
    on_border: bool


def scores(search: np.ndarray, template: np.ndarray) -> np.ndarray:
    """``TM_CCOEFF_NORMED`` map of ``template`` over ``search`` (both 2-D, same type)."""
    import cv2

    s = np.ascontiguousarray(search, dtype=np.float32)
    t = np.ascontiguousarray(template, dtype=np.float32)
    return cv2.matchTemplate(s, t, cv2.TM_CCOEFF_NORMED)


def _parabola(m: float, c: float, p: float) -> float:
    den = m - 2.0 * c + p
    if not np.isfinite(den) or den >= 0:
        return 0.0
    return float(np.clip(0.5 * (m - p) / den, -0.5, 0.5))


def peak(score: np.ndarray, exclusion: float = 3.0) -> Peak:
    """Sub-pixel maximum of a score map and the runner-up outside ``exclusion`` cells."""
    score = np.nan_to_num(score, nan=-1.0)
    h, w = score.shape
    r, c = np.unravel_index(int(np.argmax(score)), score.shape)
    s0 = float(score[r, c])
    border = r == 0 or c == 0 or r == h - 1 or c == w - 1
    dx = 0.0 if c in (0, w - 1) else _parabola(score[r, c - 1], s0, score[r, c + 1])
    dy = 0.0 if r in (0, h - 1) else _parabola(score[r - 1, c], s0, score[r + 1, c])
    yy, xx = np.ogrid[:h, :w]
    far = (xx - c) ** 2 + (yy - r) ** 2 > exclusion ** 2
    runner = float(score[far].max()) if far.any() else float("nan")
    return Peak(c + dx, r + dy, s0, runner, bool(border))
