"""Blending across seams: feathering weights and multi-band (Laplacian pyramid) blending.

Inputs are a label raster (``labels[r, c]`` = the source whose cut polygon holds the cell, −1 for
none) and per-source images with validity masks. Away from the seams (farther than half the
feather width, or than the pyramid's reach ``2**(levels+1)`` cells) every output cell equals its
source cell, whichever method is used.
"""

from __future__ import annotations

import numpy as np

BLEND_METHODS = ("none", "feather", "multiband")


def signed_distance(inside: np.ndarray) -> np.ndarray:
    """Distance (cells) from each cell centre to the edge of the region ``inside``: positive
    inside, negative outside; the edge runs between cell centres (±0.5 next to it)."""
    from scipy import ndimage

    if inside.all():
        return np.full(inside.shape, np.inf, dtype="float32")
    if not inside.any():
        return np.full(inside.shape, -np.inf, dtype="float32")
    d_in = ndimage.distance_transform_edt(inside)
    d_out = ndimage.distance_transform_edt(~inside)
    return np.where(inside, d_in - 0.5, 0.5 - d_out).astype("float32")


def feather_weights(labels: np.ndarray, valid: np.ndarray, width: float) -> np.ndarray:
    """Feathering weights ``(n, rows, cols)`` for ``n`` sources, summing to 1 wherever a source
    is valid (0 elsewhere; a valid cell no ramp reaches goes to its first valid source).

    Source k's raw weight ramps linearly from 0 to 1 across its cut polygon's edge over ``width``
    cells, centred on the edge: ``clip(0.5 + d_k / width, 0, 1)`` with ``d_k`` the signed
    distance to the edge, times its validity; the raw weights are then divided by their sum.
    """
    n = valid.shape[0]
    raw = np.zeros(valid.shape, dtype="float32")
    for k in range(n):
        if not valid[k].any():
            continue
        if width <= 0:
            raw[k] = labels == k
        else:
            raw[k] = np.clip(0.5 + signed_distance(labels == k) / width, 0.0, 1.0)
        raw[k] *= valid[k]
    total = raw.sum(axis=0)
    orphan = (total == 0) & valid.any(axis=0)  # valid, but no label ramp reaches it
    if orphan.any():
        first = valid.argmax(axis=0)
        for k in range(n):
            raw[k][orphan & (first == k)] = 1.0
        total = raw.sum(axis=0)
    np.divide(raw, total, out=raw, where=total > 0)
    return raw


def fill_invalid(image: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Copy of ``image (bands, rows, cols)`` with invalid cells set to the nearest valid cell's
    value (so pyramid levels do not mix in nodata)."""
    from scipy import ndimage

    if valid.all() or not valid.any():
        return image
    _, (ri, ci) = ndimage.distance_transform_edt(~valid, return_indices=True)
    return image[:, ri, ci]


def _gaussian_pyramid(image: np.ndarray, levels: int) -> list[np.ndarray]:
    import cv2

    pyramid = [image]
    for _ in range(levels):
        pyramid.append(cv2.pyrDown(pyramid[-1]))
    return pyramid


def _up(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    import cv2

    return cv2.pyrUp(image, dstsize=(shape[1], shape[0]))


def multiband_blend(images: list[np.ndarray], valid: np.ndarray, labels: np.ndarray,
                    levels: int = 4) -> np.ndarray:
    """Laplacian-pyramid blending (Burt & Adelson 1983) of ``images`` ``[(bands, rows, cols)]``.

    Each source's Laplacian pyramid is weighted by the Gaussian pyramid of its label mask
    (normalised to sum to 1 per level) and the blended pyramid is collapsed. Low frequencies
    blend over ``~2**levels`` cells, fine detail over a few, so seams vanish without ghosting.
    Returns float32 ``(bands, rows, cols)``; cells no source covers are 0.
    """
    bands, rows, cols = images[0].shape
    levels = max(0, min(levels, int(np.log2(max(1, min(rows, cols)))) - 1))
    out = np.zeros((bands, rows, cols), dtype="float32")
    masks = [_gaussian_pyramid((labels == k).astype("float32"), levels)
             for k in range(len(images))]
    totals = [sum(m[lv] for m in masks) for lv in range(levels + 1)]
    used = [k for k in range(len(images)) if (labels == k).any()]
    filled = {k: fill_invalid(images[k], valid[k]) for k in used}
    for b in range(bands):
        blended = None
        for k in used:
            g = _gaussian_pyramid(np.ascontiguousarray(filled[k][b]), levels)
            lap = [g[lv] - _up(g[lv + 1], g[lv].shape) for lv in range(levels)] + [g[levels]]
            weighted = [lap[lv] * _safe_ratio(masks[k][lv], totals[lv])
                        for lv in range(levels + 1)]
            blended = weighted if blended is None else [x + y for x, y in
                                                        zip(blended, weighted, strict=True)]
        if blended is None:
            continue
        result = blended[levels]
        for lv in range(levels - 1, -1, -1):
            result = _up(result, blended[lv].shape) + blended[lv]
        out[b] = result
    return out


def _safe_ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros_like(a)
    np.divide(a, b, out=out, where=b > 1e-6)
    return out
