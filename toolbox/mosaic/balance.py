"""Block radiometric balancing: one gain and offset per image and band, solved together.

For every overlapping pair (i, j) with overlap means ``m`` and standard deviations ``s`` the
corrected images ``g·v + o`` should agree in the overlap:

    g_i·m_i + o_i = g_j·m_j + o_j        g_i·s_i = g_j·s_j

All pairs form one least-squares system (each pair weighted by the square root of its overlap
cell count). The system fixes the gains and offsets only up to a common linear change, so no
image is taken as the reference: the mean gain is held at 1 and the mean offset at 0 (heavily
weighted equations), and a weak pull towards (1, 0) keeps unconnected images unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class OverlapStats:
    """Statistics of images ``a`` and ``b`` over their common valid cells (per band)."""

    a: int
    b: int
    count: int
    mean_a: np.ndarray
    mean_b: np.ndarray
    std_a: np.ndarray
    std_b: np.ndarray


def overlap_stats(a: int, b: int, da: np.ndarray, db: np.ndarray,
                  common: np.ndarray) -> OverlapStats | None:
    """Statistics of ``da``, ``db`` ``(bands, rows, cols)`` over the mask ``common``."""
    n = int(common.sum())
    if n < 2:
        return None
    va, vb = da[:, common].astype("float64"), db[:, common].astype("float64")
    return OverlapStats(a, b, n, va.mean(axis=1), vb.mean(axis=1), va.std(axis=1),
                        vb.std(axis=1))


def solve_gain_offset(stats: list[OverlapStats], n_images: int,
                      bands: int) -> tuple[np.ndarray, np.ndarray]:
    """Gains and offsets ``(n_images, bands)`` for the block (see the module docstring)."""
    gains = np.ones((n_images, bands))
    offsets = np.zeros((n_images, bands))
    if not stats:
        return gains, offsets
    strong, weak = 1e3, 1e-3
    for band in range(bands):
        rows, rhs = [], []
        scale = max(float(np.mean([s.mean_a[band] for s in stats])), 1.0)
        for s in stats:
            w = np.sqrt(s.count)
            r = np.zeros(2 * n_images)  # unknowns: g_0..g_n-1, o_0..o_n-1 (offsets / scale)
            r[s.a], r[s.b] = s.mean_a[band] / scale, -s.mean_b[band] / scale
            r[n_images + s.a], r[n_images + s.b] = 1.0, -1.0
            rows.append(w * r)
            rhs.append(0.0)
            r = np.zeros(2 * n_images)
            r[s.a], r[s.b] = s.std_a[band] / scale, -s.std_b[band] / scale
            rows.append(w * r)
            rhs.append(0.0)
        total = np.sqrt(sum(s.count for s in stats))
        mean_gain = np.zeros(2 * n_images)
        mean_gain[:n_images] = 1.0 / n_images
        mean_offset = np.zeros(2 * n_images)
        mean_offset[n_images:] = 1.0 / n_images
        rows += [strong * total * mean_gain, strong * total * mean_offset]
        rhs += [strong * total, 0.0]
        prior = weak * np.eye(2 * n_images)
        rows += list(prior)
        rhs += [weak] * n_images + [0.0] * n_images
        x, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
        gains[:, band] = x[:n_images]
        offsets[:, band] = x[n_images:] * scale
    return gains, offsets


def block_statistics(sources: list, footprints: list, crs, max_cells: int = 512 * 512,
                     exclude: list | None = None) -> list[OverlapStats]:
    """Overlap statistics of every overlapping pair of ``sources`` (orthos), read on a grid of
    at most ``max_cells`` cells over each overlap; ``exclude`` polygons (e.g. buildings, whose
    relief displacement differs between the orthos) are left out of the statistics."""
    import math

    from affine import Affine
    from rasterio.features import rasterize
    from rasterio.windows import Window

    from toolbox.mosaic.sources import read_window

    out = []
    for i in range(len(sources)):
        for j in range(i + 1, len(sources)):
            overlap = footprints[i].intersection(footprints[j])
            if overlap.is_empty or overlap.area == 0:
                continue
            x0, y0, x1, y1 = overlap.bounds
            cell = max(min(sources[i].res[0], sources[j].res[0]),
                       math.sqrt((x1 - x0) * (y1 - y0) / max_cells))
            cols, rows = max(1, math.ceil((x1 - x0) / cell)), max(1, math.ceil((y1 - y0) / cell))
            t = Affine(cell, 0, x0, 0, -cell, y1)
            win = Window(0, 0, cols, rows)
            da, va = read_window(sources[i], t, crs, win)
            db, vb = read_window(sources[j], t, crs, win)
            common = va & vb & (rasterize([overlap], out_shape=(rows, cols), transform=t,
                                          dtype="uint8") > 0)
            if exclude:
                common &= rasterize(exclude, out_shape=(rows, cols), transform=t,
                                    all_touched=True, dtype="uint8") == 0
            s = overlap_stats(i, j, da, db, common)
            if s is not None:
                out.append(s)
    return out
