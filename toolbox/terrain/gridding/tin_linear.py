"""TIN-linear gridding kernels: constrained TIN of the data, plane of the containing triangle per cell."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from toolbox.terrain.gridding.gridding import (
    TileTask,
)
from toolbox.terrain.gridding.idw_kernel import nearest_grid


def constrained_tin(xyz: np.ndarray, segments: np.ndarray | None
                    ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Delaunay TIN of ``xyz`` ((n, 3)), constrained by breakline ``segments`` ((s, 2) indices).

    Uses the TIN kernels of tin:delaunay (Triangle). Where breaklines cross without a shared
    vertex, Triangle splits them at the crossing; the new node takes the height interpolated
    linearly along each crossing segment (their mean where they disagree; the largest
    disagreement is reported).

    Returns
    -------
    nodes : (V, 3) float64
        ``xyz`` followed by the crossing nodes.
    triangles : (T, 3) int64
    info : dict
        ``crossings`` (count) and ``crossing_z_disagreement`` (m).
    """
    from toolbox.terrain.tin.kernels import crossing_heights, triangulate, triangulate_pslg

    seg = segments if segments is not None and len(segments) else None
    try:
        return xyz, triangulate(xyz[:, :2], seg).astype(np.int64), {"crossings": 0}
    except ValueError as exc:
        if seg is None or "cross" not in str(exc):
            raise
    tri = triangulate_pslg(xyz[:, :2], seg, neighbors=False)
    heights, spread = crossing_heights(tri, xyz, seg)
    nodes = np.vstack([xyz, np.column_stack([tri.vertices[tri.n_input:], heights])])
    return nodes, tri.triangles.astype(np.int64), {
        "crossings": tri.steiner_count, "crossing_z_disagreement": float(spread.max())}


def tin_tile(task: TileTask) -> tuple[np.ndarray, None]:
    """Tile kernel: plane of the containing triangle at each computed cell centre, NaN outside
    the TIN, the mask, or MAX_DISTANCE from the nearest data point."""
    from toolbox.terrain.tin.kernels import rasterize_tin

    o = task.options
    h, w = task.shape
    values = rasterize_tin(task.xyz, task.extra["triangles"], o["x0"], o["y0"], o["cell_x"],
                           o["cell_y"], w, h)
    values[~task.mask] = np.nan
    near = task.extra.get("near")
    if near is not None and math.isfinite(o["max_distance"]):
        within = nearest_grid(near, task.xs, task.ys, ~np.isnan(values), o["max_distance"])
        values[np.isnan(within)] = np.nan
    return values, None
