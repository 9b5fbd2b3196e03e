"""dem:tin_linear - DEM from the planes of the Delaunay TIN, breaklines kept (thesis eq. [43]-[44])."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.registry import register
from toolbox.terrain.gridding.base import GriddingAlgorithm
from toolbox.terrain.gridding.gridding import (
    STATISTICS,
    GridRun,
    NeighbourPlanner,
    TileTask,
    execution_parameters,
    grid_parameters,
)
from toolbox.terrain.gridding.inputs import source_parameters
from toolbox.terrain.gridding.tin_linear import (  # noqa: F401
    constrained_tin,
    tin_tile,
)


@register
class TinLinearGrid(GriddingAlgorithm):
    """DEM from a TIN: the data points (INPUT points, vertices of LINES and BREAKLINES) are
    triangulated by Delaunay (Shewchuk's Triangle, as tin:delaunay), constrained so that every
    BREAKLINES edge is a triangle edge; each cell centre takes the height of the plane through
    the three nodes of its triangle (S002 par. 2.5.1 eq. [43]-[44], linear interpolation of
    par. 2.5.2). Planes are reproduced exactly; the
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
        from toolbox.terrain.tin.kernels import triangles_by_tile

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
