"""Agreement of two orthos of one photo on one lattice (the product's and Orthority's): sub-pixel
shift by phase correlation on patches, and the mean absolute DN difference over the cells valid
in both. Used by ``bench/orthority_bench.py``; tested in tests/bench/test_orthority_agreement.py.

Conventions: shifts are in ortho cells, (dx, dy) = (columns right, rows down) to move ``b`` onto
``a``; the orthos must share the cell size and a lattice (edges on whole cells of each other).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

PATCH = 64  # phase-correlation patch, cells
UPSAMPLE = 200  # phase correlation refined to 1/UPSAMPLE cell
MARGIN = 4  # cells around a patch for the second estimate
MAX_PATCHES = 800  # patches tried per ortho at most (every k-th row and column of them)


@dataclass(frozen=True)
class Agreement:
    """Agreement of two orthos over their common valid cells."""

    cells: int  # cells valid in both
    mean_abs_dn: float  # mean |a - b| over those cells and all bands, DN
    mean_abs_dn_inner: float  # the same without cells within EDGE cells of an invalid one
    patches: int  # patches whose every cell is valid in both
    shift_median: tuple[float, float]  # median (dx, dy) of the patches, cells
    shift_max: float  # largest |(dx, dy)| of a patch, cells

    def as_dict(self) -> dict:
        return {"cells": self.cells, "mean_abs_dn": round(self.mean_abs_dn, 4),
                "mean_abs_dn_inner": round(self.mean_abs_dn_inner, 4),
                "patches": self.patches,
                "shift_median_px": [round(v, 4) for v in self.shift_median],
                "shift_max_px": round(self.shift_max, 4)}


EDGE = 2  # cells next to an invalid one left out of mean_abs_dn_inner (bilinear's footprint)


def patch_shifts(a: np.ndarray, b: np.ndarray, valid: np.ndarray,
                 patch: int = PATCH) -> np.ndarray:
    """(n, 2) shifts (dx, dy) in cells of ``b``'s content relative to ``a``'s on every ``patch``
    x ``patch`` patch of the (rows, cols) greyscale arrays that is valid throughout (with a
    margin of MARGIN cells) and not flat.

    Phase correlation (scikit-image, 1/UPSAMPLE cell) of the Hann-windowed patches, then once
    more after moving ``b``'s window back by that estimate (cubic spline, from the cells around
    the patch): a patch is not periodic, which biases the first estimate towards zero by a few
    percent of the shift; the second one measures only the small remainder.
    """
    from scipy.ndimage import shift as move
    from skimage.filters import window
    from skimage.registration import phase_cross_correlation

    hann = window("hann", (patch, patch))

    def estimate(pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
        got, _, _ = phase_cross_correlation((pa - pa.mean()) * hann, (pb - pb.mean()) * hann,
                                            upsample_factor=UPSAMPLE, normalization=None)
        return -got[::-1]  # skimage: the (row, col) move that registers b on a

    out = []
    m = MARGIN
    rows = range(m, a.shape[0] - patch - m + 1, patch)
    cols = range(m, a.shape[1] - patch - m + 1, patch)
    every = max(1, math.ceil(math.sqrt(len(rows) * len(cols) / MAX_PATCHES)))
    for r in rows[::every]:  # spread evenly over the ortho when there are too many
        for c in cols[::every]:
            sl = np.s_[r:r + patch, c:c + patch]
            pa = a[sl]
            if not valid[r - m:r + patch + m, c - m:c + patch + m].all() or pa.std() < 1.0:
                continue
            first = estimate(pa, b[sl])
            if np.abs(first).max() >= m - 1:  # too far to move back inside the margin
                out.append(first)
                continue
            around = b[r - m:r + patch + m, c - m:c + patch + m]
            back = move(around, (-first[1], -first[0]), order=3, mode="nearest")
            out.append(first + estimate(pa, back[m:m + patch, m:m + patch]))
    return np.array(out, dtype=float).reshape(-1, 2)


def compare_arrays(a: np.ndarray, b: np.ndarray, valid: np.ndarray,
                   patch: int = PATCH) -> Agreement:
    """Agreement of (bands, rows, cols) arrays ``a`` and ``b`` over the (rows, cols) ``valid``
    cells."""
    from scipy.ndimage import binary_erosion

    a, b = a.astype(np.float64), b.astype(np.float64)
    diff = np.abs(a - b)
    inner = binary_erosion(valid, iterations=EDGE, border_value=0)
    shifts = patch_shifts(a.mean(axis=0), b.mean(axis=0), valid, patch)
    norms = np.hypot(shifts[:, 0], shifts[:, 1]) if len(shifts) else np.array([np.nan])
    median = tuple(float(v) for v in np.median(shifts, axis=0)) if len(shifts) else \
        (float("nan"), float("nan"))
    return Agreement(cells=int(valid.sum()),
                     mean_abs_dn=float(diff[:, valid].mean()) if valid.any() else float("nan"),
                     mean_abs_dn_inner=float(diff[:, inner].mean()) if inner.any()
                     else float("nan"),
                     patches=len(shifts), shift_median=median, shift_max=float(norms.max()))


def compare_files(ours: Path, theirs: Path, patch: int = PATCH) -> Agreement:
    """Agreement of two ortho GeoTIFFs on one lattice: their common window, colour bands only
    (an alpha band is a mask), cells valid in both (GDAL's dataset masks: alpha or nodata)."""
    import rasterio
    from rasterio.enums import ColorInterp
    from rasterio.windows import from_bounds

    with rasterio.open(ours) as sa, rasterio.open(theirs) as sb:
        if not np.isclose(abs(sa.transform.a), abs(sb.transform.a)):
            raise ValueError(f"cell sizes differ: {sa.transform.a} and {sb.transform.a}")
        left, bottom = max(sa.bounds.left, sb.bounds.left), max(sa.bounds.bottom,
                                                                sb.bounds.bottom)
        right, top = min(sa.bounds.right, sb.bounds.right), min(sa.bounds.top, sb.bounds.top)
        arrays = []
        for src in (sa, sb):
            window = from_bounds(left, bottom, right, top, src.transform)
            if abs(window.col_off - round(window.col_off)) > 1e-6 or \
                    abs(window.row_off - round(window.row_off)) > 1e-6:
                raise ValueError(f"{src.name} is not on the other ortho's lattice")
            window = window.round_offsets().round_lengths()
            bands = [i + 1 for i, ci in enumerate(src.colorinterp) if ci != ColorInterp.alpha]
            arrays.append((src.read(bands, window=window),
                           src.dataset_mask(window=window) > 0))
    (da, ma), (db, mb) = arrays
    return compare_arrays(da, db, ma & mb, patch)
