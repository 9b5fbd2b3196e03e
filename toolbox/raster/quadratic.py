"""Quadratic interpolation for image resampling (the thesis' Z-Map "quadratica", S002 §3.8).

The sources give no formula; this is Dodgson's interpolating quadratic kernel (N. A. Dodgson,
"Quadratic interpolation for image resampling", IEEE Trans. Image Processing 6(9), 1997)::

    h(s) = 1 - 2 s²                 for |s| <= 1/2
    h(s) = s² - 5/2 |s| + 3/2       for 1/2 < |s| <= 3/2
    h(s) = 0                        otherwise

three taps per axis around the nearest sample. It interpolates (samples are reproduced), sums to
one and reproduces linear ramps exactly; it is C0, between bilinear and cubic in sharpness and
cost. Coordinates follow OpenCV's ``remap`` (pixel centres at integers); outside the source the
value is 0, like ``cv2.BORDER_CONSTANT``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _weights(t):
    """Weights of the samples n-1, n, n+1 for the offset t = x - n in [-1/2, 1/2]."""
    a = 1.0 + t  # |s| of sample n-1
    b = 1.0 - t  # |s| of sample n+1
    return a * a - 2.5 * a + 1.5, 1.0 - 2.0 * t * t, b * b - 2.5 * b + 1.5


# duplicate-ok: the row and column loops of the separable 3-tap kernel look alike by nature
@njit(cache=True, nogil=True)
def _remap(source, map_x, map_y, out):
    rows, cols, bands = source.shape
    h, w = map_x.shape
    for i in range(h):
        for j in range(w):
            x = map_x[i, j]
            y = map_y[i, j]
            if not (math.isfinite(x) and math.isfinite(y)):
                for k in range(bands):
                    out[i, j, k] = 0.0
                continue
            nx = int(math.floor(x + 0.5))
            ny = int(math.floor(y + 0.5))
            wx0, wx1, wx2 = _weights(x - nx)
            wy0, wy1, wy2 = _weights(y - ny)
            for k in range(bands):
                total = 0.0
                for dy in range(3):
                    r = ny - 1 + dy
                    if r < 0 or r >= rows:
                        continue
                    wy = wy0 if dy == 0 else (wy1 if dy == 1 else wy2)
                    line = 0.0
                    for dx in range(3):
                        c = nx - 1 + dx
                        if c < 0 or c >= cols:
                            continue
                        wx = wx0 if dx == 0 else (wx1 if dx == 1 else wx2)
                        line += wx * source[r, c, k]
                    total += wy * line
                out[i, j, k] = total


def remap_quadratic(source: np.ndarray, map_x: np.ndarray, map_y: np.ndarray) -> np.ndarray:
    """Sample ``source`` ((rows, cols) or (rows, cols, bands), any numeric dtype) at the OpenCV
    map coordinates; integers are rounded and clipped to their range."""
    src = np.asarray(source)
    work = src if src.ndim == 3 else src[:, :, None]
    out = np.empty(map_x.shape + (work.shape[2],), dtype="float64")
    _remap(np.ascontiguousarray(work), np.asarray(map_x, dtype="float64"),
           np.asarray(map_y, dtype="float64"), out)
    if src.dtype.kind in "iu":
        info = np.iinfo(src.dtype)
        out = np.clip(np.rint(out), info.min, info.max)
    out = out.astype(src.dtype)
    return out if src.ndim == 3 else out[:, :, 0]
