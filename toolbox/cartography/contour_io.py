"""Contours from files: a DEM GeoTIFF traced tile by tile and stitched, or a TIN layer; written
as a LineString Z GeoPackage layer with elevation and index flags."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.cartography.contours import (
    Contour,
    Piece,
    block_pieces,
    block_windows,
    choose_tracer,
    contour_levels,
    index_flags,
    smooth_contours,
    spanned_cells_levels,
    stitch_pieces,
    tin_contours,
    to_map,
)
from toolbox.io.raster import read_filled


@dataclass
class GridFrame:
    """Cell-centre frame of a raster: centre of cell (0, 0) and the steps between centres."""

    x0: float
    y0: float
    dx: float
    dy: float

    @classmethod
    def of(cls, transform) -> GridFrame:
        if transform.b != 0 or transform.d != 0:
            raise ValueError("rotated rasters are not supported")
        return cls(transform.c + 0.5 * transform.a, transform.f + 0.5 * transform.e,
                   transform.a, transform.e)


@dataclass
class ContourResult:
    contours: list[Contour]
    levels: np.ndarray
    stats: dict[str, Any] = field(default_factory=dict)
    #: lines shorter than this (map units) are points, not lines: left out (contour_columns)
    min_length: float = 0.0


#: a DEM's contour line shorter than this fraction of a cell is left out: a cell exactly at a
#: level with its neighbours all below (a peak) or above (a pit) makes a "ring" of coinciding
#: vertices (length 0, or a few ulps of the coordinates after the georeferencing; an invalid
#: geometry for GEOS), while the isoline there is a point. A real ring that short would need
#: the cell to pass the level by less than a float32 height's resolution (gdal_contour writes
#: a ring of about 1e-5 of a cell there, from its offset of values equal to a level)
DEGENERATE_CELL_FRACTION = 1e-6


#: a DEM of at most this many cells traced on local threads is read once, whole (8 bytes a
#: cell, 64 MB at most), and its blocks traced from memory; a larger one (or one traced on a
#: cluster) is read twice, by blocks: its range, then each block where it is traced
IN_MEMORY_CELLS = 8_000_000


def raster_range(src, band: int, tile_size: int, interval: float = 1.0,
                 base: float = 0.0) -> tuple[float, float, float]:
    """Min and max of a band's valid cells, and their :func:`level_crossings` (at most the
    crossings on the edges between tiles fewer), read in tiles."""
    from toolbox.io.grid import GridSpec
    from toolbox.raster.tile import iter_tiles

    lo, hi, crossings = np.inf, -np.inf, 0.0
    for t in iter_tiles(GridSpec(src.transform, src.width, src.height), tile_size):
        z = read_filled(src, band, t.window)
        if np.isfinite(z).any():
            lo, hi = min(lo, np.nanmin(z)), max(hi, np.nanmax(z))
            crossings += level_crossings(z, interval, base)
    return float(lo), float(hi), crossings


def level_crossings(z: np.ndarray, interval: float, base: float, band: int = 512) -> float:
    """How many times the levels ``base + k·interval`` cross the edges between adjacent valid
    cells of ``z`` (NaN = no data): the vertices of the contours traced from it, one per edge
    a level crosses. A noisy or rough surface has many more than its range says (a DSM with
    3 m of noise at INTERVAL 1: 27 million over 2000 x 2000 cells, not 2 million). Computed in
    bands of ``band`` rows (a few arrays of a band at a time)."""
    total = 0.0
    with np.errstate(invalid="ignore", over="ignore"):
        for r0 in range(0, z.shape[0], band):
            k = np.floor((z[r0:r0 + band + 1].astype("float64") - base) / interval)
            for step in (np.diff(k[:band + 1], axis=0), np.diff(k[:band], axis=1)):
                step = np.abs(step)
                total += float(step[np.isfinite(step)].sum())
    return total


def grid_range(z: np.ndarray) -> tuple[float, float]:
    """:func:`raster_range` of a band already read (NaN = no data): no tiles needed."""
    if not np.isfinite(z).any():
        return float(np.inf), float(-np.inf)
    return float(np.nanmin(z)), float(np.nanmax(z))


def guard_levels(zmin: float, zmax: float, interval: float, base: float, span: float,
                 crossings: float = 0.0) -> None:
    """Refuse before tracing when the levels (``(zmax - zmin) / interval``) or their vertices
    (about ``span``, the grid's width + height in cells, per level, or the ``crossings`` of
    :func:`level_crossings` when more) are too many."""
    from toolbox.limits import check_size

    if not (math.isfinite(zmin) and math.isfinite(zmax)) or zmax < zmin:
        return
    levels = math.floor((zmax - base) / interval) - math.ceil((zmin - base) / interval) + 1
    what = f"{interval:g} over heights {zmin:g} .. {zmax:g}"
    hint = "use a larger INTERVAL (or check the heights and nodata of the surface)"
    check_size("features", levels, "INTERVAL", what, hint, "contour levels")
    check_size("vertices", max(levels * span, crossings), "INTERVAL",
               f"{what} ({levels:,} levels)", hint)


@dataclass(frozen=True)
class BlockTask:
    """One block of a DEM file to trace (picklable: it runs on a Dask worker as well)."""

    path: str
    band: int
    window: tuple[int, int, int, int]  # row, col, height, width
    levels: tuple[float, ...]
    tracer: str  # toolbox.cartography.contours.TRACERS
    on_worker: bool = False  # a Dask worker's task: the DEM stays open for its next blocks


def trace_block(task: BlockTask) -> list[Piece]:
    """Read one block of the DEM (nodata -> NaN) and trace its pieces. On a Dask worker the
    DEM stays open in the thread for its next blocks
    (:class:`~toolbox.raster.datasets.WorkerDatasets`: blocks share a row and column, so
    GDAL's cache serves their common tiles); in this process it is closed after the block."""
    import rasterio
    from rasterio.windows import Window

    from toolbox.raster.datasets import worker_datasets

    row, col, height, width = task.window
    window = Window(col, row, width, height)
    if task.on_worker:
        z = read_filled(worker_datasets().get(task.path), task.band, window)
    else:
        with rasterio.open(task.path) as src:
            z = read_filled(src, task.band, window)
    return block_pieces(z, task.levels, row, col, task.tracer)


@dataclass(frozen=True)
class GridBlock:
    """One block of a DEM already in memory (local threads only): its cells are a view."""

    z: np.ndarray
    row: int
    col: int
    levels: tuple[float, ...]
    tracer: str


def trace_grid_block(task: GridBlock) -> list[Piece]:
    """Trace the pieces of one in-memory block."""
    return block_pieces(task.z, task.levels, task.row, task.col, task.tracer)


def trace_raster(path: str | Path, band: int, rows: int, cols: int, tile: int,
                 levels: np.ndarray, executor: Any = None, feedback=None,
                 grid: np.ndarray | None = None, tracer: str | None = None
                 ) -> tuple[list[Contour], int]:
    """Contours of a DEM file traced block by block on ``executor`` (local threads or a Dask
    cluster: :mod:`toolbox.executor`; the pieces come back in block order, so the result is the
    same on either) by ``tracer`` (default :func:`~toolbox.cartography.contours.choose_tracer`
    for the whole grid) and stitched; grid coordinates. With ``grid`` (the band already read,
    NaN = no data; local threads) the blocks are its views, else each task reads its block.
    Returns the contours and the pieces' count."""
    from toolbox.executor import map_tiles, resolve_executor

    executor = executor or resolve_executor(None)
    windows = block_windows(rows, cols, tile)
    levels_tuple = tuple(float(v) for v in levels)
    if tracer is None:
        spanned = rows * cols * len(levels) if grid is None else \
            spanned_cells_levels(grid, np.asarray(levels, dtype="float64"), windows)
        tracer = choose_tracer(rows * cols, spanned)
    if grid is not None:
        func: Any = trace_grid_block
        tasks: Any = (GridBlock(grid[r:r + h, c:c + w], r, c, levels_tuple, tracer)
                      for r, c, h, w in windows)
    else:
        func = trace_block
        on_worker = executor.kind == "dask"
        tasks = (BlockTask(str(path), band, window, levels_tuple, tracer, on_worker)
                 for window in windows)
    pieces: list[Piece] = []
    for found in map_tiles(func, tasks, executor=executor, feedback=feedback,
                           total=len(windows), end=80):
        pieces += found
    return stitch_pieces(pieces, tile), len(pieces)


def raster_contours(path: str | Path, band: int, interval: float, base: float,
                    tile_size: int = 1024, smoothing: int = 0, feedback=None,
                    executor: Any = None) -> ContourResult:
    """Contours of a DEM, traced in ``tile_size`` blocks that share one row/column with their
    neighbours (each grid square belongs to one block) on ``executor`` (default: local threads,
    or the cluster of DASK_SCHEDULER_ADDRESS) and stitched across block edges. A DEM of at most
    :data:`IN_MEMORY_CELLS` on local threads is read once (the same cells either way)."""
    import rasterio

    from toolbox.executor import resolve_executor
    from toolbox.io.raster import dataset_transform

    executor = executor or resolve_executor(None)
    grid = None
    threads = executor.workers if executor.kind == "local" else 1  # GDAL decodes tiles at once
    with rasterio.Env(GDAL_NUM_THREADS=str(threads)), rasterio.open(path) as src:
        frame = GridFrame.of(dataset_transform(src))
        if executor.kind == "local" and src.width * src.height <= IN_MEMORY_CELLS:
            grid = read_filled(src, band)
            zmin, zmax = grid_range(grid)
            crossings = level_crossings(grid, interval, base)
        else:
            zmin, zmax, crossings = raster_range(src, band, tile_size, interval, base)
        guard_levels(zmin, zmax, interval, base, src.width + src.height, crossings)
        levels = contour_levels(zmin, zmax, interval, base)
        rows, cols = src.height, src.width
    windows = block_windows(rows, cols, tile_size)
    spanned = rows * cols * len(levels) if grid is None else \
        spanned_cells_levels(grid, levels, windows)  # (read by blocks: at most this)
    tracer = choose_tracer(rows * cols, spanned)
    contours, n_pieces = trace_raster(path, band, rows, cols, tile_size, levels, executor,
                                      feedback, grid, tracer)
    contours, reverted = smooth_contours(contours, smoothing)
    contours = to_map(contours, frame.x0, frame.y0, frame.dx, frame.dy)
    stats = {"tiles": len(windows),
             "pieces_before_stitching": n_pieces, "smoothing_reverted": reverted,
             "z_min": zmin, "z_max": zmax, "tracer": tracer,
             "kernel_build": kernel_build(tracer, executor), "executor": executor.describe()}
    return ContourResult(contours, levels, stats,
                         DEGENERATE_CELL_FRACTION * min(abs(frame.dx), abs(frame.dy)))


def kernel_build(tracer: str, executor: Any) -> str | None:
    """How the one-pass kernel ran, for the run's statistics: ``"ahead of time"``
    (:mod:`toolbox.aot`, no numba import), ``"numba JIT"``, each Dask worker's own, or None
    (contourpy traced)."""
    if tracer != "kernel":
        return None
    if executor.kind != "local":
        return "each worker's own (ahead of time where its warm-up built it, else numba JIT)"
    from toolbox.aot import load_compiled

    return "ahead of time" if load_compiled("contour_lines") is not None else "numba JIT"


def tin_layer_contours(xyz: np.ndarray, triangles: np.ndarray, interval: float,
                       base: float) -> ContourResult:
    """Contours of a TIN (nodes, triangles) at ``base + k·interval``."""
    z = xyz[:, 2]
    if len(z):
        k = np.floor((z.astype("float64") - base) / interval)[np.asarray(triangles)]
        # level crossings of the triangles' edges, each inner edge seen by its two triangles
        crossings = float(np.abs(k - np.roll(k, 1, axis=1)).sum()) / 2 if len(k) else 0.0
        guard_levels(float(z.min()), float(z.max()), interval, base,
                     2.0 * math.sqrt(len(triangles)), crossings)
    levels = contour_levels(float(z.min()), float(z.max()), interval, base) if len(z) else \
        np.empty(0)
    return ContourResult(tin_contours(xyz, triangles, levels), levels,
                         {"triangles": int(len(triangles))})


def canonical_order(xy: np.ndarray, counts: np.ndarray, levels: np.ndarray,
                    tolerance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The canonical order and form of lines given as one vertex buffer ``xy (N, 2)`` (line
    ``i``: ``counts[i]`` vertices after those of lines ``< i``) at ``levels`` (or any keys in
    the levels' order, one a line): the same whatever
    order the lines came in (TILE_SIZE, the executor, the tracer) and wherever a ring began.

    A closed line (first vertex = last, more than 2 vertices) starts at its least vertex (least
    x, then least y; orientation kept); the lines are sorted by level, then first vertex, then
    second vertex (x, then y), then vertex count. With ``tolerance`` > 0 these comparisons
    are of the coordinates counted in steps of ``tolerance`` from the least x and y (rounded),
    so coordinates that differ by rounding only (a few ulps: where the data lie decides
    which) compare equal and the next key decides: the same order and starts wherever the
    data lie (the same lines translated by (1,688,000, 4,799,500) swapped two rings, their
    starts' x equal near the origin, an ulp apart there). Returns ``order`` (line ``k`` of the
    result is line ``order[k]``) and ``source`` (vertex ``p`` of the result is
    ``xy[source[p]]``), all vectorised over the lines (a few passes over the buffer, no loop
    per line).
    """
    n = len(counts)
    if not n:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    ends = np.cumsum(counts)
    first = ends - counts
    flat = np.ascontiguousarray(xy).reshape(-1)  # x of vertex i at 2i, y at 2i + 1
    closed = (counts > 2) & (np.take(flat, 2 * first) == np.take(flat, 2 * ends - 2)) & \
        (np.take(flat, 2 * first + 1) == np.take(flat, 2 * ends - 1))
    if tolerance > 0:  # the keys: whole steps of tolerance from the least x, y
        x = xy[:, 0] - xy[:, 0].min()
        x *= 1.0 / tolerance
        np.rint(x, out=x)
        y_min, y_step = xy[:, 1].min(), 1.0 / tolerance

        def take_x(i):
            return np.take(x, i)

        def take_y(i):
            return np.rint((np.take(flat, 2 * i + 1) - y_min) * y_step)
    else:
        x = xy[:, 0]

        def take_x(i):
            return np.take(flat, 2 * i)

        def take_y(i):
            return np.take(flat, 2 * i + 1)

    # each ring's least vertex: the vertices at its line's least x (about one a line), then
    # the first of those at their least y; open lines keep their first vertex
    at_least_x = x == np.repeat(np.minimum.reduceat(x, first), counts)
    per_line = np.add.reduceat(at_least_x, first, dtype=np.int64)  # >= 1 each
    at = np.flatnonzero(at_least_x)
    y_at = take_y(at)
    hits = np.flatnonzero(y_at == np.repeat(np.minimum.reduceat(y_at, np.cumsum(per_line) -
                                                                per_line), per_line))
    line = np.repeat(np.arange(n), per_line)[hits]
    least = np.take(at, hits[np.r_[True, line[1:] != line[:-1]]])
    shift = np.where(closed, least - first, 0)
    period = np.where(closed, counts - 1, counts)  # a ring's last vertex repeats its first
    start = first + shift
    second = first + (shift + 1) % period
    # sorted by x of the first vertex, then (stable) by level; runs of equal level and x (lines
    # starting on one grid column) then sorted by the rest of the key
    x0 = take_x(start)
    order = np.argsort(x0)
    order = order[np.argsort(np.take(levels, order), kind="stable")]  # radix on uint16
    lev, xs = np.take(levels, order), np.take(x0, order)
    tie = np.flatnonzero((lev[1:] == lev[:-1]) & (xs[1:] == xs[:-1]))
    if len(tie):
        tied_next = np.zeros(n, dtype=bool)  # position i ties with i + 1
        tied_next[tie] = True
        pos = np.flatnonzero(tied_next | np.r_[False, tied_next[:-1]])
        run = np.cumsum(~np.r_[False, tied_next][pos])  # a run starts untied to the one before
        sub = order[pos]
        order[pos] = sub[np.lexsort((counts[sub], take_y(second[sub]), take_x(second[sub]),
                                     take_y(start[sub]), run))]
    # the source of every output vertex: consecutive within a line from its (rotated) start,
    # back by its period where a rotated ring wraps; built as steps summed up
    counts_out, shift_out, period_out = counts[order], shift[order], period[order]
    first_out = np.cumsum(counts_out) - counts_out
    step = np.ones(len(xy), dtype=np.int32 if len(xy) < 2**31 else np.int64)
    start_out = start[order]
    end_out = np.where(shift_out > 0, start_out, ends[order] - 1)  # a rotated ring: its start
    step[0] = start_out[0]
    step[first_out[1:]] = start_out[1:] - end_out[:-1]
    wraps = shift_out > 0
    step[(first_out + period_out - shift_out)[wraps]] -= period_out[wraps]
    return order, np.cumsum(step, dtype=step.dtype)


def contour_columns(contours: list[Contour], interval: float, base: float,
                    index_every: int, min_length: float = 0.0
                    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The LineString Z contours as ISO WKB (Z = the level), in :func:`canonical_order`, and
    their fields: ``elev`` (m), ``index`` (1 for index contours), ``closed`` (true for rings: a
    Boolean field), ``length`` (map units). Lines of length 0 or below ``min_length`` (their
    vertices coincide: :data:`DEGENERATE_CELL_FRACTION`) are left out.

    Built with numpy from all the vertices at once (no shapely: its import and its geometries
    were about a fifth of a 2000 x 2000 contour run's CPU after the tracing); every line's WKB
    is its 9-byte header and its x, y, z as little-endian doubles.
    """
    levels = np.array([c.level for c in contours], dtype="float64")
    counts = np.array([len(c.xy) for c in contours], dtype=np.int64)
    wkb = np.empty(len(contours), dtype=object)
    if not len(contours):
        lengths, closed = np.zeros(0), np.zeros(0, dtype=bool)
    else:
        xy = np.concatenate([c.xy for c in contours]).astype("<f8", copy=False)
        # the levels' numbers k (base + k·interval, contour_levels) as the sort's 16-bit keys
        # (numpy's radix sort) when they give the levels back exactly
        k = np.rint((levels - base) / interval)
        keys = (k - k.min()).astype(np.uint16) if np.ptp(k) < 2**16 and \
            np.array_equal(base + k * interval, levels) else levels
        order, source = canonical_order(xy, counts, keys, min_length)
        levels, counts = levels[order], counts[order]
        xyz = np.empty((len(xy), 3), dtype="<f8")
        xyz[:, :2] = np.take(xy, source, axis=0)
        xyz[:, 2] = np.repeat(levels, counts)
        xy = xyz[:, :2]
        last = np.cumsum(counts) - 1
        first = last - counts + 1
        seg = np.hypot(*np.diff(xy, axis=0).T)  # the segments, and one across each line break
        seg = np.append(seg, 0.0)
        seg[last] = 0.0
        lengths = np.add.reduceat(seg, first)
        closed = (counts > 2) & (xy[first] == xy[last]).all(axis=1)
        keep = (lengths > 0) & (lengths >= min_length)
        if not keep.all():  # points, not lines (the order of the others holds)
            xyz = xyz[np.repeat(keep, counts)]
            levels, counts, lengths, closed = levels[keep], counts[keep], lengths[keep], \
                closed[keep]
            last = np.cumsum(counts) - 1
            first = last - counts + 1
            wkb = np.empty(len(counts), dtype=object)
        body = memoryview(xyz).cast("B")  # sliced per line without copying it whole
        header = np.zeros(len(counts), dtype=[("order", "u1"), ("type", "<u4"), ("n", "<u4")])
        header["order"], header["type"], header["n"] = 1, 1002, counts  # 1002: LineString Z
        heads = header.tobytes()
        starts = (24 * first).tolist()
        for i, (a, b) in enumerate(zip(starts, (24 * (last + 1)).tolist(), strict=True)):
            wkb[i] = heads[9 * i:9 * i + 9] + body[a:b]
    fields = {"elev": levels,
              "index": index_flags(levels, interval, base, index_every).astype("int32"),
              "closed": closed,  # a Boolean field (GeoPackage: Integer(Boolean); QGIS: a checkbox)
              "length": lengths.astype("float64")}
    return wkb, fields


def write_contours(path: str | Path, contours: list[Contour], interval: float, base: float,
                   index_every: int, crs: Any, min_length: float = 0.0
                   ) -> dict[str, np.ndarray]:
    """Write the ``contours`` layer (LineString Z, :func:`contour_columns`) to ``path``;
    returns its fields."""
    from toolbox.io.vector_write import write_wkb_layer

    wkb, fields = contour_columns(contours, interval, base, index_every, min_length)
    write_wkb_layer(path, "contours", wkb, fields, "LineString Z", crs)
    return fields
