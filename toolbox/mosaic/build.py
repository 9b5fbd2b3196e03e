"""The mosaic, window by window: cut polygons -> labels -> (balanced) sources -> blend -> write.

:func:`mosaic_window` is the kernel of one output window (arrays in, arrays out, apart from
reading the sources' windows); :func:`write_mosaic` streams it over the grid with
:func:`toolbox.tiles.map_tiles`, so memory is bounded by a few windows whatever the mosaic size,
into :class:`WindowWriter` s (the raster engine's ``RasterWriter`` contract).

Labels: a cell takes the source whose cut polygon holds it; where that source has no valid data
(the polygons are traced on decimated masks) or no polygon holds the cell, the first valid source
in input order does, so the mosaic has no gap where any input has data. The source-index raster
stores ``label + 1`` (0 = no data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.io.raster import TileWindow
from toolbox.mosaic.blend import feather_weights, multiband_blend
from toolbox.mosaic.sources import OrthoSource, read_window


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


def window_labels(plan: MosaicPlan, window: Any, valid: np.ndarray) -> np.ndarray:
    """Label raster (int16, −1 = no data) of ``window`` from the cut polygons, completed from
    the first valid source where the polygon's source has no data there."""
    from rasterio.features import rasterize

    shape = (int(window.height), int(window.width))
    shapes = [(cell, k) for k, cell in enumerate(plan.cells)
              if cell is not None and not cell.is_empty]
    labels = np.full(shape, -1, dtype="int16")
    if shapes:
        labels = rasterize(shapes, out_shape=shape, transform=plan.grid.window_transform(window),
                           fill=-1, dtype="int16")
    rows, cols = np.indices(shape, sparse=True)
    own_valid = np.where(labels >= 0, valid[np.clip(labels, 0, None), rows, cols], False)
    first = np.where(valid.any(axis=0), valid.argmax(axis=0), -1).astype("int16")
    return np.where(own_valid, labels, first).astype("int16")


def mosaic_window(plan: MosaicPlan, tile: TileWindow) -> tuple[np.ndarray, np.ndarray]:
    """``(data (bands, rows, cols) in plan.dtype, labels (rows, cols) int16)`` of one core
    window; data is 0 where ``labels == -1``."""
    padded = tile.padded
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
    core = (slice(None), *tile.inner)
    return to_dtype(out[core], plan.dtype), labels[tile.inner]


def to_dtype(values: np.ndarray, dtype: str) -> np.ndarray:
    """Round and clip to an integer dtype's range; plain cast for floats."""
    dt = np.dtype(dtype)
    if dt.kind in "iu":
        info = np.iinfo(dt)
        return np.clip(np.rint(values), info.min, info.max).astype(dt)
    return values.astype(dt)


def _window_task(args):
    plan, tile = args
    return tile, *mosaic_window(plan, tile)


class WindowWriter:
    """A GeoTIFF written window by window: tiled 512, DEFLATE with a predictor, overviews, an
    optional alpha band (last band) and an optional COG copy at close.

    The same constructor and ``write(window, array)`` as the raster engine's
    ``toolbox.raster.writer.RasterWriter``, so the engine's writer can replace it one for one.
    """

    def __init__(self, path: Path, grid: Any, count: int, dtype: Any,
                 nodata: float | None = None, *, alpha: bool = False, cog: bool = False,
                 overviews: bool = True, overview_resampling: str = "average"):
        self.path, self.grid, self.count, self.dtype = Path(path), grid, count, np.dtype(dtype)
        self.nodata, self.alpha, self.cog = nodata, alpha, cog
        self.overviews, self.overview_resampling = overviews, overview_resampling
        self._target = self.path.with_name(f".{self.path.name}.tiled.tif") if cog else self.path

    def __enter__(self) -> WindowWriter:
        import rasterio

        from toolbox.io.raster import geotiff_profile

        g = self.grid
        profile = geotiff_profile(g.width, g.height, self.count, self.dtype, g.crs, g.transform,
                                  None if self.alpha else self.nodata)
        self._env = rasterio.Env(COMPRESS_OVERVIEW="DEFLATE",
                                 PREDICTOR_OVERVIEW=profile["predictor"])
        self._env.__enter__()
        self.dataset = rasterio.open(self._target, "w", **profile)
        if self.alpha:
            from rasterio.enums import ColorInterp

            data = self.count - 1
            interp = [ColorInterp.red, ColorInterp.green, ColorInterp.blue] if data == 3 else \
                [ColorInterp.gray] * data
            self.dataset.colorinterp = [*interp, ColorInterp.alpha]
        return self

    def write(self, window: Any, array: np.ndarray) -> None:
        self.dataset.write(array if array.ndim == 3 else array[None], window=window)

    def __exit__(self, exc_type, exc, tb) -> None:
        from toolbox.io.raster import build_overviews

        try:
            if exc_type is None and (self.overviews or self.cog):
                build_overviews(self.dataset, self.overview_resampling)
        finally:
            self.dataset.close()
            self._env.__exit__(None, None, None)
        if exc_type is None and self.cog:
            from rasterio.shutil import copy

            copy(self._target, self.path, driver="COG", compress="DEFLATE", overviews="AUTO")
        if self.cog:
            self._target.unlink(missing_ok=True)


def write_mosaic(plan: MosaicPlan, output: Path, index_path: Path | None, *, alpha: bool,
                 nodata: float | None, cog: bool = False, overviews: bool = True,
                 tile_size: int = 512, workers: int | None = None,
                 feedback: Any = None) -> dict:
    """Stream the mosaic into ``output`` (and the source-index raster into ``index_path``).

    The output has ``plan.bands`` data bands plus an alpha band (``alpha``) or ``nodata`` where
    no source has data; tiled DEFLATE GeoTIFF with overviews, or a COG (``cog``).
    """
    from contextlib import ExitStack

    from toolbox.io.raster import iter_windows
    from toolbox.tiles import map_tiles

    grid = plan.grid
    dt = np.dtype(plan.dtype)
    alpha_value = np.iinfo(dt).max if dt.kind in "iu" else 1
    index_dtype = "uint8" if len(plan.sources) < 255 else "uint16"
    counts = np.zeros(len(plan.sources), dtype="int64")
    empty = 0
    tiles = list(iter_windows(grid.width, grid.height, tile_size, plan.halo()))
    with ExitStack() as stack:
        dst = stack.enter_context(WindowWriter(
            output, grid, plan.bands + (1 if alpha else 0), plan.dtype,
            None if alpha else nodata, alpha=alpha, cog=cog, overviews=overviews))
        idx = None if index_path is None else stack.enter_context(WindowWriter(
            index_path, grid, 1, index_dtype, 0, overviews=overviews,
            overview_resampling="nearest"))
        for tile, data, labels in map_tiles(_window_task, ((plan, t) for t in tiles),
                                            workers=workers, feedback=feedback,
                                            total=len(tiles), start=0, end=90):
            nodata_cells = labels < 0
            empty += int(nodata_cells.sum())
            counts += np.bincount(labels[~nodata_cells], minlength=len(counts))
            if alpha:
                a = np.where(nodata_cells, 0, alpha_value).astype(plan.dtype)
                data = np.concatenate([data, a[None]], axis=0)
            elif nodata is not None:
                data[:, nodata_cells] = nodata
            dst.write(tile.core, data)
            if idx is not None:
                idx.write(tile.core, (labels + 1).astype(index_dtype))
    if feedback is not None:
        feedback.set_progress(100)
    return {"cells_per_source": {s.name: int(c) for s, c in zip(plan.sources, counts,
                                                               strict=True)},
            "empty_cells": empty, "tiles": len(tiles)}
