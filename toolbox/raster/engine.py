"""The tiled raster engine: one output grid, tiles with a halo, inputs read per tile, kernels
on arrays, one writer.

Every raster-producing algorithm follows the same flow::

    grid = GridRequest(cell_size, extent, template).grid(data_bounds, crs)  # grid rules
    with RasterWriter(output, grid, 1, "float32", nodata=-9999) as writer:
        process_raster(grid, {"dem": RasterInput(path)}, kernel, writer, halo=1,
                       executor=resolve_executor(scheduler), feedback=feedback)

(typed arguments: an algorithm translates its parameters into them in :mod:`toolbox.ui`).

- :class:`toolbox.raster.grid_request.GridRequest` holds the one set of grid rules (below).
- :func:`iter_tiles` cuts the grid into :class:`Tile` s (row by row, ``tile_size`` cells, a
  ``halo`` of extra cells on every side, also beyond the grid's edges).
- :func:`read_window` reads any raster (its own grid, CRS, resolution) onto a tile's haloed
  window: a direct windowed read when the raster is aligned with the grid, else a GDAL warp.
- :func:`process_raster` runs ``kernel(tile, arrays) -> array`` per tile on
  :func:`toolbox.executor.map_tiles` (local threads by default, a Dask cluster when asked), with
  bounded memory (a few tiles in flight), progress and cancellation, and writes the results in
  tile order (the file is the same whichever executor ran the tiles).
- the photo -> ground mode (:func:`toolbox.raster.warp.warp_raster`) runs on
  :func:`process_raster`: a coordinate map gives, for the cells of a tile, the source (col, row)
  to sample; the warp reads the source window they need and resamples it with OpenCV.

Grid rules
----------
- ``TEMPLATE``: the template's lattice (origin, cell size); its extent, or the cells of that
  lattice covering ``EXTENT`` when both are given (the template fixes the alignment). The CRS
  is the caller's, else the template's. ``CELL_SIZE`` with ``TEMPLATE`` is refused.
- ``EXTENT`` (no template): honoured as given. The origin is (xmin, ymax); columns and rows are
  ``ceil((xmax - xmin) / CELL_SIZE)`` and ``ceil((ymax - ymin) / CELL_SIZE)``, so only the far
  (east and south) edges may move outwards to whole cells.
- neither: the data bounds, snapped outwards to multiples of ``CELL_SIZE`` (grids of different
  runs then align); ``snap=False`` keeps the bounds' xmin/ymax as origin.
- ``MAX_CELLS`` (default ``TOOLBOX_MAX_CELLS`` or 1e9): larger grids are refused with a
  :class:`~toolbox.errors.ParameterError` before any array is allocated.

Conventions: arrays are ``(bands, rows, cols)`` (or ``(rows, cols)`` for one band), row 0 is
north; windows are rasterio ``Window(col_off, row_off, width, height)`` on the output grid; a
cell's value belongs to its centre (:mod:`toolbox.io.grid`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.io.grid import GridSpec
from toolbox.raster.datasets import ThreadDatasets, WorkerDatasets

__all__ = [
    "BOUNDARY_RULES", "GridSpec", "RasterInput", "Tile", "iter_tiles", "process_raster",
    "read_window", "tile_count",
]

BOUNDARY_RULES = ("nodata", "edge", "reflect")
_EPS = 1e-9  # relative tolerance of "a whole number of cells"


# -- tiles: toolbox.raster.tile (re-exported here) -------------------------------------------------
from toolbox.raster.tile import Tile, _window_transform, iter_tiles, tile_count  # noqa: E402,F401


# -- reading inputs onto the grid ------------------------------------------------------------------
@dataclass(frozen=True)
class RasterInput:
    """How :func:`process_raster` reads one input raster onto each tile (see
    :func:`read_window` for the meaning of the fields). ``source`` is a path or a
    :class:`~toolbox.io.raster.RasterInfo`."""

    source: Any
    bands: tuple[int, ...] | None = None
    resampling: str = "bilinear"
    boundary: str = "nodata"
    dtype: str | None = None
    fill: float | None = None

    def read(self, grid: GridSpec, tile: Tile) -> np.ndarray:
        return read_window(self.source, grid, tile.window, bands=self.bands,
                           resampling=self.resampling, halo=tile.halo, boundary=self.boundary,
                           dtype=self.dtype, fill=self.fill)


def _source_path(source: Any) -> Any:
    return getattr(source, "path", source)


class _OpenSources(ThreadDatasets):
    """Input rasters kept open per thread for the length of one local :func:`process_raster`
    call (:class:`~toolbox.raster.datasets.ThreadDatasets`), with their alignment on the grid;
    closed at the end. On Dask it travels as the worker's
    :class:`~toolbox.raster.datasets.WorkerDatasets`."""

    def __init__(self) -> None:
        super().__init__()
        self._offsets: dict[tuple, tuple[int, int] | None] = {}

    def aligned_offset(self, path: Any, dataset: Any, grid: GridSpec) -> tuple[int, int] | None:
        """:func:`_aligned_offset` of ``path`` on ``grid``, decided once per call (the CRS
        comparison costs more than a tile's read); one grid per :func:`process_raster` call."""
        key = (path, id(grid))
        if key not in self._offsets:
            self._offsets[key] = _aligned_offset(dataset, grid)
        return self._offsets[key]


@dataclass(frozen=True)
class _HeldInput:
    """A :class:`RasterInput` read through :class:`_OpenSources` (local threads) or a Dask
    worker's :class:`~toolbox.raster.datasets.WorkerDatasets`."""

    input: RasterInput
    sources: _OpenSources | WorkerDatasets

    def read(self, grid: GridSpec, tile: Tile) -> np.ndarray:
        inp = self.input
        source = _source_path(inp.source)
        offset = _UNKNOWN
        if isinstance(source, (str, Path)):
            path = str(source)
            source = self.sources.get(path)
            offset = self.sources.aligned_offset(path, source, grid) \
                if isinstance(self.sources, _OpenSources) else _UNKNOWN
        return read_window(source, grid, tile.window, bands=inp.bands,
                           resampling=inp.resampling, halo=tile.halo, boundary=inp.boundary,
                           dtype=inp.dtype, fill=inp.fill, _offset=offset)


_UNKNOWN = object()  # read_window's alignment not decided yet


def read_window(source: Any, grid: GridSpec, window: Any, *, bands: Any = None,
                resampling: str = "bilinear", halo: int = 0, boundary: str = "nodata",
                dtype: Any = None, fill: float | None = None,
                _offset: Any = _UNKNOWN) -> np.ndarray:
    """Read ``source`` onto ``window`` of ``grid`` grown by ``halo`` cells: (bands, h + 2·halo,
    w + 2·halo).

    Parameters
    ----------
    source : path, RasterInfo or open rasterio dataset
        Any raster GDAL reads, on any grid, CRS or resolution. When its grid is aligned with
        ``grid`` (same CRS, cell size and a whole-cell offset) the cells are read directly;
        otherwise they are resampled onto the grid by GDAL's warper (``resampling``); a raster
        or grid without CRS is taken to be in the other's CRS.
    bands : int or sequence of int, optional
        1-based band indexes (default: every band).
    resampling : str
        A rasterio resampling name (nearest, bilinear, cubic, lanczos, average...), used only
        when the grids differ.
    boundary : {"nodata", "edge", "reflect"}
        Cells of the haloed window beyond ``grid``'s edges: ``nodata`` reads them like any
        other cell (from the source if it covers them, else ``fill``); ``edge`` repeats the
        grid's edge cells; ``reflect`` mirrors the cells inside about the edge cell (numpy's
        ``reflect``: the edge cell is not repeated).
    dtype : dtype, optional
        Result type (default: the source's).
    fill : float, optional
        Value of cells without data (outside the source, or the source's nodata). Default: NaN
        for a float result, else the source's nodata (0 when it has none).
    """
    import rasterio

    if boundary not in BOUNDARY_RULES:
        raise ValueError(f"boundary must be one of {', '.join(BOUNDARY_RULES)}, got {boundary!r}")
    from rasterio.windows import Window

    col0, row0 = int(window.col_off) - halo, int(window.row_off) - halo
    width, height = int(window.width) + 2 * halo, int(window.height) + 2 * halo
    pads = (0, 0, 0, 0)
    if boundary != "nodata":  # read the part inside the grid, pad it afterwards
        c0, r0 = max(col0, 0), max(row0, 0)
        c1, r1 = min(col0 + width, grid.width), min(row0 + height, grid.height)
        pads = (r0 - row0, row0 + height - r1, c0 - col0, col0 + width - c1)
        col0, row0, width, height = c0, r0, c1 - c0, r1 - r0
    region = Window(col0, row0, width, height)
    own = not hasattr(source, "read")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        src = rasterio.open(_source_path(source)) if own else source
    try:
        indexes = list(range(1, src.count + 1)) if bands is None else (
            [int(bands)] if np.isscalar(bands) else [int(b) for b in bands])
        out_dtype = np.dtype(dtype or src.dtypes[indexes[0] - 1])
        if fill is None:
            first = src.nodatavals[indexes[0] - 1]
            fill = math.nan if out_dtype.kind == "f" else (
                first if first is not None and not math.isnan(first) else 0)
        offset = _aligned_offset(src, grid) if _offset is _UNKNOWN else _offset
        if offset is not None:
            data = _read_aligned(src, indexes, region, offset, out_dtype, fill)
        else:
            from toolbox.raster.reproject import read_onto

            data = read_onto(src, _window_transform(grid.transform, region), region.width,
                             region.height, grid.crs, indexes=indexes, resampling=resampling,
                             dtype=out_dtype, fill=fill)
    finally:
        if own:
            src.close()
    if any(pads):
        top, bottom, left, right = pads
        mode = "edge" if boundary == "edge" else "reflect"
        if mode == "reflect" and (data.shape[1] < 2 or data.shape[2] < 2):
            mode = "edge"
        data = np.pad(data, ((0, 0), (top, bottom), (left, right)), mode=mode)
    return data


def _aligned_offset(src: Any, grid: GridSpec) -> tuple[int, int] | None:
    """(col, row) of the grid's origin in the source's cells when both grids share CRS, cell
    size and orientation up to a whole-cell shift; None otherwise."""
    from toolbox.io.raster import dataset_transform

    s, g = dataset_transform(src), grid.transform
    if s.b != 0 or s.d != 0 or g.b != 0 or g.d != 0:
        return None
    if abs(s.a - g.a) > _EPS * abs(g.a) or abs(s.e - g.e) > _EPS * abs(g.e):
        return None
    if src.crs is not None and grid.crs is not None:
        from toolbox.io.crs import one_crs_of_wkt

        # two definitions of one CRS (an ESRI WKT and its EPSG code) share it
        if not one_crs_of_wkt(src.crs.to_wkt(), _pyproj(grid.crs).to_wkt(), tuple(src.bounds)):
            return None
    dc, dr = (g.c - s.c) / s.a, (g.f - s.f) / s.e
    if abs(dc - round(dc)) > 1e-6 or abs(dr - round(dr)) > 1e-6:
        return None
    return int(round(dc)), int(round(dr))


def _pyproj(crs: Any) -> Any:
    from pyproj import CRS

    if isinstance(crs, CRS):
        return crs
    return CRS.from_wkt(crs.to_wkt()) if hasattr(crs, "to_wkt") else CRS.from_user_input(crs)


def part_inside(col: int, row: int, width: int, height: int, source_width: int,
                source_height: int) -> tuple[Any, tuple[slice, slice]] | None:
    """The part of a ``width`` x ``height`` window whose top-left cell is (``col``, ``row``) in
    a source's cells that lies inside the source: ``(source Window, (row slice, col slice) of
    the window's array)``, or None when they do not meet (an aligned read, no boundless VRT)."""
    from rasterio.windows import Window

    c0, r0 = max(col, 0), max(row, 0)
    c1, r1 = min(col + width, source_width), min(row + height, source_height)
    if c1 <= c0 or r1 <= r0:
        return None
    return (Window(c0, r0, c1 - c0, r1 - r0),
            (slice(r0 - row, r1 - row), slice(c0 - col, c1 - col)))


def _read_aligned(src, indexes, region, offset, dtype, fill) -> np.ndarray:
    """Windowed read of an aligned source; cells outside it, at its nodata or masked out by
    its mask band or alpha band (GDAL's mask, as the warper of an unaligned read honours it)
    get ``fill``."""
    width, height = int(region.width), int(region.height)
    part = part_inside(int(region.col_off) + offset[0], int(region.row_off) + offset[1],
                       width, height, src.width, src.height)
    if part is None:
        return np.full((len(indexes), height, width), fill, dtype=dtype)
    inner, inside = part
    data = src.read(indexes, window=inner)
    missing = None
    nodatas = [src.nodatavals[band - 1] for band in indexes]  # each band's own (a VRT's differ)
    if all(v is not None for v in nodatas) and not (
            all(math.isnan(v) for v in nodatas) and dtype.kind == "f" and math.isnan(fill)):
        # a cell is no data when every band read is at its nodata (GDAL's dataset mask, as the
        # warper of an unaligned read decides): a valid pure-blue (0, 0, 255) pixel of an RGB
        # with nodata 0 lost its bands 1 and 2 (fill), unlike the same photo read unaligned.
        # Compared in the source's type, as GDAL stores it
        hit = np.logical_and.reduce([np.isnan(data[k]) if math.isnan(v) else data[k] == v
                                     for k, v in enumerate(nodatas)])
        if hit.any():
            missing = np.broadcast_to(hit, data.shape)
    masked = _masked_out(src, indexes, inner)
    if masked is not None:
        missing = masked if missing is None else missing | masked
    if data.shape[1:] == (height, width) and data.dtype == dtype:
        out = data  # the whole window inside the source, no conversion: no copy
    else:
        out = np.full((len(indexes), height, width), fill, dtype=dtype)
        out[(slice(None), *inside)] = data
    if missing is not None:
        out[(slice(None), *inside)][missing] = fill
    return out


def _masked_out(src, indexes, window) -> np.ndarray | None:
    """Where a mask band or an alpha band of ``src`` masks the bands ``indexes`` out (bool
    (bands, rows, cols)), None when every band's mask is its nodata value or nothing."""
    from toolbox.io.raster import masked_by_nodata_only

    if all(masked_by_nodata_only(src, i) for i in indexes):
        return None
    masked = src.read_masks(indexes, window=window) == 0
    return masked if masked.any() else None


# -- running kernels over the tiles ----------------------------------------------------------------
Kernel = Callable[[Tile, dict], Any]


@dataclass
class _TileJob:
    """One tile's work: the tile and its planned arrays (the kernel and the inputs, shared by
    every tile, travel to a Dask worker once: :func:`toolbox.executor.map_tiles`)."""

    tile: Tile
    grid: GridSpec
    run: bool
    planned: dict | None = None


def _run_job(kernel: Kernel, inputs: dict, job: _TileJob) -> tuple[np.ndarray | None, Any]:
    """Read the inputs onto the tile, run the kernel, crop the halo (on a worker)."""
    if not job.run:
        return None, None
    arrays = {name: inp.read(job.grid, job.tile) for name, inp in inputs.items()}
    if job.planned:
        arrays.update(job.planned)
    result = kernel(job.tile, arrays)
    info = None
    if isinstance(result, tuple):
        result, info = result
    return _crop(job.tile, result), info


def _crop(tile: Tile, array: np.ndarray | None) -> np.ndarray | None:
    if array is None:
        return None
    if array.shape[-2:] == tile.haloed_shape and tile.halo:
        return array[(...,) + tile.crop]
    if array.shape[-2:] != tile.shape:
        raise ValueError(f"kernel returned shape {array.shape} for a tile of {tile.shape} "
                         f"(haloed {tile.haloed_shape})")
    return array


def process_raster(grid: GridSpec, inputs: Mapping[str, RasterInput] | None, kernel: Kernel,
                   writer_or_output: Any, *, tile_size: int = 512, halo: int = 0,
                   executor: Any = None, feedback: Any = None,
                   plan: Callable[[Tile], dict | None] | None = None,
                   collect: Callable[[Tile, np.ndarray | None, Any], None] | None = None,
                   start: float = 0.0, end: float = 100.0) -> dict[str, Any]:
    """Run ``kernel`` on every tile of ``grid`` and write the results in tile order.

    Parameters
    ----------
    grid : GridSpec
        The output grid.
    inputs : dict name -> RasterInput
        Rasters read onto each tile's haloed window (see :func:`read_window`) and handed to the
        kernel as ``arrays[name]`` (bands, h + 2·halo, w + 2·halo).
    kernel : callable
        ``kernel(tile, arrays) -> array`` (or ``(array, info)``): numpy arrays in, a numpy
        array out, over the tile with or without its halo (the halo is cropped); (h, w) or
        (bands, h, w). No open files: it may run on a thread or a Dask worker (then it must be
        a module-level function or a ``functools.partial`` of one). Returning None writes the
        tile as blank (nodata, alpha 0).
    writer_or_output : RasterWriter or callable
        Where results go: ``writer.write(tile.window, array)``, or ``output(tile, array)``
        (array None for a blank tile).
    tile_size, halo : int
        Tile side and margin in cells.
    executor : toolbox.executor.Executor, optional
        Default: the Dask cluster of ``DASK_SCHEDULER_ADDRESS`` when it is set, else local
        threads, one per CPU (:func:`toolbox.executor.resolve_executor`); algorithms with a
        SCHEDULER parameter pass their own.
    feedback : Feedback, optional
        Progress from ``start`` to ``end`` % over the tiles; cancellation between tiles.
    plan : callable, optional
        ``plan(tile) -> dict | None``, run in this process, lazily as tiles are submitted:
        extra arrays for the kernel (e.g. the data points a tile needs), merged into
        ``arrays``; None skips the tile (written blank, the kernel is not called).
    collect : callable, optional
        ``collect(tile, array, info)`` in this process, in tile order, before the write
        (statistics).

    Returns ``{"tiles": n, "blank_tiles": m, "executor": "..."}``.
    """
    from toolbox.executor import map_tiles, resolve_executor

    executor = executor or resolve_executor(None)
    inputs = dict(inputs or {})
    # inputs kept open by this call's threads (closed at its end); sent to a Dask worker, the
    # holder arrives as the worker's WorkerDatasets, kept across its tasks
    held = _OpenSources()
    inputs = {name: _HeldInput(replace(inp, source=_source_path(inp.source)), held)
              if isinstance(inp, RasterInput) else inp for name, inp in inputs.items()}
    counters = {"tiles": 0, "blank_tiles": 0}

    def jobs() -> Iterator[_TileJob]:
        for tile in iter_tiles(grid, tile_size, halo):
            planned = plan(tile) if plan is not None else {}
            yield _TileJob(tile, grid, planned is not None, planned)

    write = writer_or_output.write if hasattr(writer_or_output, "write") else None
    if executor.kind == "dask" and getattr(writer_or_output, "executor", False) is None:
        writer_or_output.executor = executor  # its overviews / COG copy on the same cluster
    tiles = iter_tiles(grid, tile_size, halo)
    results = map_tiles(partial(_run_job, kernel, inputs), jobs(), executor=executor,
                        feedback=feedback,
                        total=tile_count(grid, tile_size), start=start, end=end)
    try:
        for tile, (array, info) in zip(tiles, results, strict=True):
            counters["tiles"] += 1
            if array is None:
                counters["blank_tiles"] += 1
            if collect is not None:
                collect(tile, array, info)
            if write is not None:
                write(tile.window, writer_or_output.blank(*tile.shape) if array is None
                      else array)
            else:
                writer_or_output(tile, array)
    finally:
        getattr(results, "close", lambda: None)()  # stop and join the tile threads first
        held.close()
    counters["executor"] = executor.describe()
    return counters
