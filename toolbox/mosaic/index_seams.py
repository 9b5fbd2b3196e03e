"""Seamlines as the mosaic has them: the cell edges between different sources of a label raster.

A mosaic cell takes one source (its *label*, :func:`toolbox.mosaic.build.window_labels`); the seam
between sources ``i`` and ``j`` is the set of cell edges with label ``i`` on one side and ``j`` on
the other (both >= 0; edges next to "no data" are not seams). The lines therefore follow the
cell edges exactly (steps of one cell where the seam runs diagonally): rasterised again they give
back the label raster's edges, and a zero-area sliver of a cut polygon, which holds no cell,
gives no seam.

:func:`label_edges` is the kernel (a label array in, segments out); :func:`seam_lines` joins the
segments of each pair into lines; :func:`partition_labels` computes the labels of a cut partition
on the mosaic grid window by window, exactly as ``mosaic:build`` does; :func:`index_raster_seams`
reads a source-index raster (``label + 1``, 0 = no data) in strips.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

STRIP_ROWS = 1024
STRIP_CELLS = 4_000_000  # cells of a strip at most (a band of float32 is 16 MB)


def label_edges(labels: np.ndarray, transform: Any, row_offset: int = 0,
                last_row: int | None = None) -> dict[tuple[int, int], np.ndarray]:
    """Cell edges between different labels, ``{(i, j): (k, 4) x0, y0, x1, y1}`` with i < j.

    Parameters
    ----------
    labels : (rows, cols) integer labels, < 0 = no data.
    transform : affine transform of the *whole* grid (north-up).
    row_offset : grid row of ``labels[0]`` (strips of a larger grid).
    last_row : edges *within* rows are taken for ``labels[:last_row]`` only (a strip read with
        one extra row gives the edges between that row and the previous one, not its own).
    """
    labels = np.asarray(labels)
    out: dict[tuple[int, int], list[np.ndarray]] = {}
    a, e, c, f = transform.a, transform.e, transform.c, transform.f
    rows_own = labels.shape[0] if last_row is None else last_row

    def add(la: np.ndarray, lb: np.ndarray, segs: np.ndarray) -> None:
        lo, hi = np.minimum(la, lb), np.maximum(la, lb)
        for i, j in set(zip(lo.tolist(), hi.tolist(), strict=True)):
            sel = (lo == i) & (hi == j)
            out.setdefault((i, j), []).append(segs[sel])

    # neighbours left/right: a vertical edge at x of column c + 1
    left, right = labels[:rows_own, :-1], labels[:rows_own, 1:]
    r, cc, la, lb = _label_changes(left, right)
    if len(r):
        x = c + (cc + 1) * a
        y0 = f + (r + row_offset) * e
        add(la, lb, np.column_stack([x, y0, x, y0 + e]))
    # neighbours up/down: a horizontal edge at y of row r + 1
    up, down = labels[:-1], labels[1:]
    r, cc, la, lb = _label_changes(up, down)
    if len(r):
        y = f + (r + 1 + row_offset) * e
        x0 = c + cc * a
        add(la, lb, np.column_stack([x0, y, x0 + a, y]))
    return {k: np.concatenate(v) for k, v in out.items()}


def _label_changes(first: np.ndarray, second: np.ndarray) -> tuple:
    """``(rows, cols, first labels, second labels)`` of the cells where the two label arrays
    (views of one shape) differ and both hold a label (>= 0), in row-major order: the labels
    compared over the whole arrays once, the few cells that differ then tested for "no data"
    (the same cells as ``(first != second) & (first >= 0) & (second >= 0)``, without its two
    full-size comparisons and two full-size ANDs: 1.8 -> 0.6 ms on 1500 x 1000 cells)."""
    flat = np.flatnonzero(first != second)
    r, cc = np.divmod(flat, first.shape[1])
    la, lb = first[r, cc], second[r, cc]
    keep = (la >= 0) & (lb >= 0)
    if not keep.all():
        r, cc, la, lb = r[keep], cc[keep], la[keep], lb[keep]
    return r, cc, la, lb


def merge_edges(into: dict, more: dict) -> None:
    """Append the segments of ``more`` to ``into`` (both as from :func:`label_edges`)."""
    for key, segs in more.items():
        into.setdefault(key, []).append(segs)


def seam_lines(edges: dict) -> list[tuple[int, int, Any]]:
    """``(i, j, MultiLineString)`` per pair, sorted: the segments joined end to end, collinear
    vertices removed (the geometry is unchanged)."""
    import shapely

    out = []
    for (i, j) in sorted(edges):
        segs = edges[(i, j)]
        segs = np.concatenate(segs) if isinstance(segs, list) else segs
        lines = shapely.linestrings(segs.reshape(-1, 2, 2))
        merged = shapely.line_merge(shapely.multilinestrings(lines))
        merged = shapely.simplify(merged, 0.0)  # drops collinear vertices only
        parts = list(getattr(merged, "geoms", [merged]))
        out.append((i, j, shapely.MultiLineString(parts)))
    return out


def strips(height: int, width: int) -> Iterator[tuple[int, int]]:
    """``(first row, rows owned)`` of the strips covering ``height`` rows: at most
    :data:`STRIP_ROWS` rows and about :data:`STRIP_CELLS` cells each."""
    rows = max(16, min(STRIP_ROWS, STRIP_CELLS // max(width, 1)))
    for r0 in range(0, height, rows):
        yield r0, min(rows, height - r0)


def index_raster_seams(path: Any) -> tuple[list, float]:
    """Seams of a source-index raster (``label + 1``, 0 = no data) read in strips; returns
    ``(seam_lines, cell size)``."""
    import rasterio
    from rasterio.windows import Window

    edges: dict = {}
    with rasterio.open(path) as src:
        for r0, n in strips(src.height, src.width):
            extra = 1 if r0 + n < src.height else 0
            block = src.read(1, window=Window(0, r0, src.width, n + extra)).astype("int32") - 1
            merge_edges(edges, label_edges(block, src.transform, r0, n))
        cell = abs(src.transform.a)
    return seam_lines(edges), cell


def partition_labels(plan: Any) -> Iterator[tuple[int, int, np.ndarray]]:
    """``(first row, rows owned, labels)`` strips of the mosaic labels of ``plan`` (a
    :class:`toolbox.mosaic.build.MosaicPlan`): the cut polygons rasterised on the mosaic grid,
    completed where a polygon's source has no data, as ``mosaic:build`` labels its cells. Each
    strip but the last has one extra row."""
    from rasterio.windows import Window

    from toolbox.mosaic.build import _intersects, window_bounds, window_labels
    from toolbox.mosaic.sources import read_valid

    grid = plan.grid
    for r0, n in strips(grid.height, grid.width):
        extra = 1 if r0 + n < grid.height else 0
        window = Window(0, r0, grid.width, n + extra)
        bounds = window_bounds(grid, window)
        valid = np.zeros((len(plan.sources), n + extra, grid.width), dtype=bool)
        for k, src in enumerate(plan.sources):
            if _intersects(src.bounds, bounds):
                read_valid(src, grid.transform, grid.crs, window, out=valid[k])
        yield r0, n, window_labels(plan, window, valid)


def partition_seams(plan: Any) -> list:
    """Seams of the mosaic that ``plan`` would build (:func:`partition_labels`)."""
    edges: dict = {}
    for r0, n, labels in partition_labels(plan):
        merge_edges(edges, label_edges(labels, plan.grid.transform, r0, n))
    return seam_lines(edges)
