"""The mosaic, window by window: cut polygons -> labels -> (balanced) sources -> blend -> write.

:func:`mosaic_window` is the kernel of one output tile (arrays in, arrays out, apart from
reading the sources' windows); :func:`write_mosaic` runs it over the grid on the shared raster
engine (:func:`toolbox.raster.engine.process_raster`), so memory is bounded by a few tiles
whatever the mosaic size, into :class:`toolbox.raster.writer.RasterWriter` s (the source-index
raster is written from the engine's ``collect`` hook).

Labels: a cell takes the source whose cut polygon holds it (the lower source of the plan when its
centre lies on the edge two polygons share); where that source has no valid data (the polygons
are traced on decimated masks) or no polygon holds the cell, the first valid source of the plan
does, so the mosaic has no gap where any input has data. ``mosaic:build`` plans the orthos in
file-name order, so that no tie depends on the order they were given in. The source-index raster
stores the source's 1-based input number (``OrthoSource.index + 1``, 0 = no data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.mosaic.blend import feather_weights, multiband_blend
from toolbox.mosaic.sources import OrthoSource, read_window
from toolbox.raster.writer import keep_off_nodata


@dataclass
class MosaicPlan:
    """Everything one window needs (picklable)."""

    sources: list[OrthoSource]
    cells: list  # shapely cut polygon per source (may be empty)
    grid: Any  # toolbox.io.grid.GridSpec
    bands: int
    dtype: str
    blend: str = "none"
    feather_cells: float = 0.0
    levels: int = 4
    gains: np.ndarray | None = None  # (n, bands)
    offsets: np.ndarray | None = None
    resampling: str = "bilinear"
    _boxes: list = field(default_factory=list, repr=False)

    def window_cells(self, tile_size: int) -> int:
        """Cells of the largest haloed window a tile blends in memory (:func:`clipped_window`):
        a wide feather or a deep pyramid makes every 512-cell tile read far more around it."""
        side = tile_size + 2 * self.halo()
        return min(side, self.grid.width) * min(side, self.grid.height)

    def halo(self) -> int:
        if self.blend == "feather":
            return int(math.ceil(self.feather_cells / 2)) + 2
        if self.blend == "multiband":
            step = 2 ** self.levels
            return step * math.ceil((2 ** (self.levels + 2) + 8) / step)
        return 0


def window_bounds(grid: Any, window: Any) -> tuple[float, float, float, float]:
    t = grid.window_transform(window)
    return (t.c, t.f + t.e * int(window.height), t.c + t.a * int(window.width), t.f)


def _intersects(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


#: GDAL's block cache while the mosaic is written (MB): the written tiles and the orthos' blocks
#: that neighbouring tiles read again (the block's rasters stay open,
#: :func:`toolbox.mosaic.block.open_block`) share it
WRITE_CACHE_MB = 128

#: the mosaic's tiles (and GeoTIFF blocks), cells: each is blended with its halo in memory
TILE_SIZE = 512

#: up to this many sources with data in a window, :func:`window_labels` takes one pass per source
FEW_SOURCES = 6
#: cells of the strips of rows :func:`window_labels` makes its passes over (64 K: a strip's
#: labels, masks and result stay in a core's cache)
LABEL_STRIP_CELLS = 65_536


def window_labels(plan: MosaicPlan, window: Any, valid: np.ndarray) -> np.ndarray:
    """Label raster (int16, −1 = no data) of ``window`` from the cut polygons, completed from
    the first valid source where the polygon's source has no data there."""
    from rasterio.features import rasterize

    shape = (int(window.height), int(window.width))
    # drawn last to first: a cell centre on the edge two polygons share (GDAL burns it for
    # both, the last drawn wins) goes to the lower source, as the fallback below does
    shapes = [(cell, k) for k, cell in reversed(list(enumerate(plan.cells)))
              if cell is not None and not cell.is_empty]
    if shapes:
        labels = rasterize(shapes, out_shape=shape, transform=plan.grid.window_transform(window),
                           fill=-1, dtype="int16")
    else:
        labels = np.full(shape, -1, dtype="int16")
    present = [k for k in range(len(valid)) if valid[k].any()]
    if len(present) > FEW_SOURCES:  # many sources here: one gather over all of them
        rows, cols = np.indices(shape, sparse=True)
        own_valid = np.where(labels >= 0, valid[np.clip(labels, 0, None), rows, cols], False)
        first = np.where(valid.any(axis=0), valid.argmax(axis=0), -1).astype("int16")
        return np.where(own_valid, labels, first).astype("int16")
    first = np.full(shape, -1, dtype="int16")  # the first source with data, -1 = none
    # a few passes, faster than the gather (2-4x for 1-3 sources), over strips of rows that
    # stay in the CPU's cache from one pass to the next (1500 x 1000 cells: 12.9 -> 11.4 ms of
    # mosaic:seamlines' seams, the whole grid at once took each pass through memory)
    step = max(1, LABEL_STRIP_CELLS // max(shape[1], 1))
    own_strip = np.empty((min(step, shape[0]), shape[1]), dtype=bool)
    here_strip = np.empty_like(own_strip)
    for r0 in range(0, shape[0], step):
        rows = slice(r0, r0 + step)
        lab, out = labels[rows], first[rows]
        own_valid = own_strip[:len(lab)]  # the polygon's source has data
        here = here_strip[:len(lab)]
        own_valid.fill(False)
        for k in reversed(present):
            on = valid[k, rows]
            np.copyto(out, k, where=on)  # no index arrays, unlike first[valid[k]] = k
            np.equal(lab, k, out=here)
            here &= on
            own_valid |= here
        np.copyto(out, lab, where=own_valid)
    return first


def clipped_window(grid: Any, tile: Any) -> tuple[Any, tuple[slice, slice]]:
    """The haloed window of an engine :class:`~toolbox.raster.engine.Tile` clipped to the grid,
    and the slices cutting the tile out of an array over it (the mosaic blends only cells of
    the grid)."""
    from rasterio.windows import Window

    w, halo = tile.window, tile.halo
    col0, row0, cols, rows = int(w.col_off), int(w.row_off), int(w.width), int(w.height)
    c0, r0 = max(col0 - halo, 0), max(row0 - halo, 0)
    c1, r1 = min(col0 + cols + halo, grid.width), min(row0 + rows + halo, grid.height)
    inner = (slice(row0 - r0, row0 - r0 + rows), slice(col0 - c0, col0 - c0 + cols))
    return Window(c0, r0, c1 - c0, r1 - r0), inner


def mosaic_window(plan: MosaicPlan, tile: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(data (bands, rows, cols) in plan.dtype, labels (rows, cols) int16)`` of one engine
    :class:`~toolbox.raster.engine.Tile` (its halo, clipped to the grid, is the blending
    margin); data is 0 where ``labels == -1``."""
    padded, inner = clipped_window(plan.grid, tile)
    shape = (int(padded.height), int(padded.width))
    bounds = window_bounds(plan.grid, padded)
    n = len(plan.sources)
    images: list[np.ndarray | None] = [None] * n
    valid = np.zeros((n, *shape), dtype=bool)
    for k, src in enumerate(plan.sources):
        if not _intersects(src.bounds, bounds):
            continue
        data, ok = read_window(src, plan.grid.transform, plan.grid.crs, padded, plan.resampling)
        if plan.gains is not None:
            data = data * plan.gains[k][:, None, None].astype("float32") + \
                plan.offsets[k][:, None, None].astype("float32")
        images[k], valid[k] = data, ok
    labels = window_labels(plan, padded, valid)
    out = np.zeros((plan.bands, *shape), dtype="float32")
    present = [k for k in range(n) if images[k] is not None]
    if plan.blend == "multiband" and len(present) > 1:
        zero = np.zeros((plan.bands, *shape), dtype="float32")
        out = multiband_blend([images[k] if images[k] is not None else zero for k in range(n)],
                              valid, labels, plan.levels)
    elif plan.blend == "feather" and len(present) > 1:
        weights = feather_weights(labels, valid, plan.feather_cells)
        for k in present:
            out += weights[k] * images[k]
    else:
        for k in present:
            sel = labels == k
            out[:, sel] = images[k][:, sel]
    out[:, labels < 0] = 0
    core = (slice(None), *inner)
    return to_dtype(out[core], plan.dtype), labels[inner]


def to_dtype(values: np.ndarray, dtype: str) -> np.ndarray:
    """Round and clip to an integer dtype's range; plain cast for floats."""
    dt = np.dtype(dtype)
    if dt.kind in "iu":
        info = np.iinfo(dt)
        return np.clip(np.rint(values), info.min, info.max).astype(dt)
    return values.astype(dt)


def mosaic_tile(plan: MosaicPlan, alpha: bool, nodata: float | None, tile: Any,
                arrays: dict) -> tuple[np.ndarray, np.ndarray]:
    """The engine kernel: :func:`mosaic_window` with the alpha band appended (``alpha``) or
    ``nodata`` where no source has data (a valid cell's value equal to it, e.g. a dark pixel
    balanced down to 0, is moved one step off it: :func:`keep_off_nodata`); the labels go to
    ``collect`` as the tile's info."""
    data, labels = mosaic_window(plan, tile)
    missing = labels < 0
    if alpha:
        dt = np.dtype(plan.dtype)
        opaque = np.iinfo(dt).max if dt.kind in "iu" else 1
        data = np.concatenate([data, np.where(missing, 0, opaque).astype(dt)[None]], axis=0)
    elif nodata is not None:
        keep_off_nodata(data, ~missing, nodata)
        data[:, missing] = nodata
    return data, labels


def write_mosaic(plan: MosaicPlan, output: Path, index_path: Path | None, *, alpha: bool,
                 nodata: float | None, cog: bool = False, overviews: bool = True,
                 tile_size: int = TILE_SIZE, workers: int | None = None, executor: Any = None,
                 feedback: Any = None, index_finished: bool = True) -> dict:
    """Stream the mosaic into ``output`` (and the source-index raster into ``index_path``).

    The output has ``plan.bands`` data bands plus an alpha band (``alpha``) or ``nodata`` where
    no source has data; tiled DEFLATE GeoTIFF with overviews, or a COG (``cog``, the source
    index too unless ``index_finished`` is False: a scratch index read once for the seams gets
    neither, and no worker of a cluster touches it). Tiles run on ``executor`` (default: the
    cluster of ``DASK_SCHEDULER_ADDRESS``, else ``workers`` local threads).
    """
    from contextlib import ExitStack
    from functools import partial

    import rasterio

    from toolbox.executor import resolve_executor
    from toolbox.raster.engine import process_raster
    from toolbox.raster.writer import RasterWriter, copy_band_names

    grid = plan.grid
    index_dtype = "uint8" if len(plan.sources) < 255 else "uint16"
    counts = np.zeros(len(plan.sources), dtype="int64")
    empty = [0]
    executor = executor or resolve_executor(None, workers)
    with ExitStack() as stack:
        dst = stack.enter_context(RasterWriter(
            output, grid, plan.bands + (1 if alpha else 0), plan.dtype,
            None if alpha else nodata, alpha=alpha, cog=cog, overviews=overviews,
            executor=executor, cache_mb=WRITE_CACHE_MB))
        first = plan.sources[0]
        with rasterio.open(first.path) as src:  # the bands as the orthos name them
            copy_band_names(src, dst.dataset, first.data_bands)
        # label -> input number (the plan may hold the sources in another order)
        numbers = np.array([0] + [s.index + 1 for s in plan.sources], dtype=index_dtype)
        idx = None if index_path is None else stack.enter_context(RasterWriter(
            index_path, grid, 1, index_dtype, 0, cog=cog and index_finished,
            overviews=overviews and index_finished,
            band_descriptions=["source (1-based input number, 0 = no data; SOURCE_k tags)"],
            tags={f"SOURCE_{s.index + 1}": str(s.path)
                  for s in sorted(plan.sources, key=lambda s: s.index)},
            overview_resampling="nearest", executor=executor, cache_mb=WRITE_CACHE_MB))

        def collect(tile, data, labels):
            missing = labels < 0
            empty[0] += int(missing.sum())
            counts[:] += np.bincount(labels[~missing], minlength=len(counts))
            if idx is not None:
                idx.write(tile.window, numbers[labels + 1])

        result = process_raster(grid, None, partial(mosaic_tile, plan, alpha, nodata), dst,
                                tile_size=tile_size, halo=plan.halo(), executor=executor,
                                feedback=feedback, collect=collect, end=90)
    if feedback is not None:
        feedback.set_progress(100)
    by_input = sorted(zip(plan.sources, counts, strict=True), key=lambda sc: sc[0].index)
    return {"cells_per_source": {s.name: int(c) for s, c in by_input},
            "empty_cells": empty[0], "tiles": result["tiles"]}
