"""dem:tin_linear - DEM from the planes of the Delaunay TIN, breaklines kept (thesis eq. [43]-[44])."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from algorithms.dem.base import GriddingAlgorithm
from algorithms.dem.gridding import (
    STATISTICS,
    GridRun,
    NeighbourPlanner,
    TileTask,
    execution_parameters,
    grid_parameters,
)
from algorithms.dem.idw_kernel import nearest_grid
from algorithms.dem.inputs import source_parameters
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.registry import register


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
    from algorithms.tin.kernels import crossing_heights, triangulate, triangulate_pslg

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
    from algorithms.tin.kernels import rasterize_tin

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


@register
class TinLinearGrid(GriddingAlgorithm):
    """DEM from a TIN: the data points (INPUT points, vertices of LINES and BREAKLINES) are
    triangulated by Delaunay (Shewchuk's Triangle, as tin:delaunay), constrained so that every
    BREAKLINES edge is a triangle edge; each cell centre takes the height of the plane through
    the three nodes of its triangle (S002 par. 2.5.1 eq. [43]-[44], linear interpolation of
    par. 2.5.2; ../shared/docs/domain.md section 14). Planes are reproduced exactly; the
    surface is continuous, with slope breaks along triangle edges and breaklines.

    Cells outside the TIN (the convex hull of the data) are nodata (EXTRAPOLATE does not
    apply); MASK and MAX_DISTANCE (distance to the nearest data point) also make nodata.
    Breaklines crossing without a shared vertex are split at the crossing, whose height is
    interpolated along the crossing segments (their mean, with a warning, if they disagree).

    The triangulation is built once; each output tile then rasterises only the triangles
    touching it, on local threads or a Dask cluster (SCHEDULER), in bounded memory. Duplicate
    XY, grid and template are as for dem:nearest (see `toolbox help dem:nearest`). QUALITY
    writes a leave-one-out report (each point predicted from the TIN of the others).
    """

    id = "dem:tin_linear"
    display_name = "DEM by TIN linear interpolation"
    short_help = "DEM GeoTIFF from the planes of the Delaunay TIN, breaklines kept (eq. 43-44)."
    method = "tin_linear"
    parameters = source_parameters() + grid_parameters() + execution_parameters()
    outputs = [STATISTICS]

    def tasks(self, run: GridRun, options: dict[str, Any],
              feedback: Feedback) -> Iterator[TileTask]:
        from algorithms.tin.kernels import triangles_by_tile

        segments = run.data.segments if len(run.data.segments) else None
        with feedback.timed("triangulate"):
            try:
                local, triangles, info = constrained_tin(run.data.local, segments)
            except ValueError as exc:
                raise InputDataError(f"cannot triangulate the data points: {exc}") from None
        self.tin_info = {"triangles": len(triangles), **info}
        if info.get("crossing_z_disagreement", 0) > 0:
            feedback.push_warning(f"{info['crossings']} breakline crossings without a shared "
                                  "vertex; the crossing breaklines disagree in Z by up to "
                                  f"{info['crossing_z_disagreement']:.3f} (mean used)")
        grid = run.grid
        t = grid.transform
        ox, oy = run.data.origin
        x0, y0 = t.c - ox, t.f - oy
        cell_x, cell_y = t.a, -t.e
        with feedback.timed("tiles_index"):
            order, start, _ = triangles_by_tile(local[:, :2], triangles, x0, y0, cell_x, cell_y,
                                                grid.width, grid.height, run.tile)
        max_distance = options["max_distance"]
        near = NeighbourPlanner(run.data.local, 1, max_distance, run.data.bins) \
            if math.isfinite(max_distance) else None
        return self._tasks(run, local, triangles, order, start, near, options)

    def _tasks(self, run, local, triangles, order, start, near, options):
        t = run.grid.transform
        ox, oy = run.data.origin
        for index, tw in enumerate(run.windows()):
            xs, ys = run.centres(tw.core)
            ids = order[start[index]:start[index + 1]]
            mask = run.cell_mask(tw.core, xs, ys) if len(ids) else None
            if mask is None or not mask.any():
                yield TileTask(index, None, xs, ys, None, None)
                continue
            tri = triangles[ids]
            nodes, inverse = np.unique(tri.ravel(), return_inverse=True)
            extra: dict[str, Any] = {"triangles": inverse.reshape(-1, 3).astype(np.int64)}
            if near is not None:
                extra["near"] = near.payload(xs.min(), ys.min(), xs.max(), ys.max(),
                                             max(run.grid.cell_size))
            opts = dict(options) | {
                "x0": (t.c - ox) + tw.core.col_off * t.a, "y0": (t.f - oy) + tw.core.row_off * t.e,
                "cell_x": t.a, "cell_y": -t.e}
            yield TileTask(index, tin_tile, xs, ys, mask, np.ascontiguousarray(local[nodes]),
                           opts, extra)

    def process(self, params, feedback):
        if params.get("EXTRAPOLATE"):
            feedback.push_warning("EXTRAPOLATE does not apply to dem:tin_linear: cells outside "
                                  "the TIN stay nodata")
        result = super().process(params, feedback)
        result["STATISTICS"]["method"].update(getattr(self, "tin_info", {}))
        return result
