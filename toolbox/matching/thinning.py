"""Thinning tie points to a well-distributed set, Gruber-like: every model (photo pair) gets a
grid of cells over its overlap, and each cell keeps its best track, multi-ray tracks first (a
point on 3+ photos ties several models at once), then the smallest residual.

A track kept by one model counts in every model it belongs to, so the cells of later models
are first filled by tracks already kept.
"""

from __future__ import annotations

import math

import numpy as np


def grid_cells(xy: np.ndarray, target: int) -> np.ndarray:
    """Cell index of each point on a grid of about ``target`` cells over the points' bounding
    box, cells as square as the box allows."""
    lo = xy.min(axis=0)
    span = np.maximum(xy.max(axis=0) - lo, 1e-9)
    aspect = span[0] / span[1]
    nx = max(1, round(math.sqrt(target * aspect)))
    ny = max(1, round(target / nx))
    ix = np.minimum((nx * (xy[:, 0] - lo[0]) / span[0]).astype(int), nx - 1)
    iy = np.minimum((ny * (xy[:, 1] - lo[1]) / span[1]).astype(int), ny - 1)
    return iy * nx + ix


def coverage_3x3(xy: np.ndarray, box_lo: np.ndarray, box_hi: np.ndarray) -> int:
    """How many of the 3 x 3 Gruber cells of the box (lo, hi) hold at least one point."""
    if len(xy) == 0:
        return 0
    span = np.maximum(box_hi - box_lo, 1e-9)
    cell = np.clip(((xy - box_lo) / span * 3).astype(int), 0, 2)
    return len({(int(a), int(b)) for a, b in cell})


def thin(models: list[tuple[np.ndarray, np.ndarray]], n_rays: np.ndarray, residual: np.ndarray,
         target: int) -> np.ndarray:
    """Tracks to keep (bool mask over tracks).

    ``models``: per photo pair, ``(track indices, xy of those tracks on the pair's first
    photo)``; ``n_rays`` and ``residual`` per track. Each model gets ``target`` cells.
    """
    keep = np.zeros(len(n_rays), bool)
    # quality order: more rays first, then smaller residual
    rank = np.empty(len(n_rays), int)
    rank[np.lexsort((residual, -n_rays))] = np.arange(len(n_rays))
    for tracks, xy in models:
        if len(tracks) == 0:
            continue
        cells = grid_cells(xy, target)
        filled = set(cells[keep[tracks]].tolist())
        order = np.argsort(rank[tracks])
        for k in order:
            c = int(cells[k])
            if c not in filled:
                filled.add(c)
                keep[tracks[k]] = True
    return keep
