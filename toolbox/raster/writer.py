"""The GeoTIFF writer of every raster output: tiled, compressed, with overviews, optionally a
Cloud Optimized GeoTIFF.

:class:`RasterWriter` writes windows of an output grid into a GeoTIFF with

- square tiles of ``tile`` pixels (512 by default, also for rasters smaller than a tile),
- DEFLATE (or another GDAL codec) with a predictor: 2 (horizontal differencing) for integers,
  3 (floating point) for floats; DEFLATE level 1 for 8-bit rasters, 6 otherwise,
- internal overviews built at close (``average`` by default), halving until the smallest level
  fits in one tile (GDAL's COG rule), compressed like the data,
- an alpha band (the last band, ``alpha=True``; also written as GDAL's internal mask where
  GDAL would not read it as one: :attr:`RasterWriter.mask_alpha`) or a nodata value (NaN in a
  float array, the kernels' "no value", is written as nodata); RGB photometry for three
  integer data bands,
- ``memory_mb``: an output of at most that many megabytes is gathered in a GDAL MEM dataset,
  its overviews built there and the whole copied once into the GeoTIFF (GDAL's
  ``COPY_SRC_OVERVIEWS``): same pixels, tiles, codec and overviews as the streamed file, a
  third of its CPU time (building the overviews of a written GTiff went through its tiles
  again: 0.25 against 0.09 s CPU for a 783 x 1399 RGBA ortho); larger outputs are streamed,
- ``cog=True``: a Cloud Optimized GeoTIFF, made by GDAL's COG driver from the tiled file (IFDs
  first, smallest overview's data first, the main image last), which GDAL's COG validator
  accepts; :func:`cog_problems` checks that layout without GDAL's Python bindings,
- ``executor`` a Dask cluster (the tiles' own, set by
  :func:`toolbox.raster.engine.process_raster`): the streamed file is closed on the client and
  its overviews, or its COG copy, are made on a worker (:func:`finish_geotiff`) when the worker
  sees the file as the client wrote it (shared storage: same size and modification time);
  otherwise on the client, as without a cluster. The same bytes either way (tests).

The file is written at the path given (inside an algorithm: the staged path the runner hands
over, renamed into place on success); a failed write removes what it wrote.
"""

from __future__ import annotations

import math
import os
import socket
import struct
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.io.raster import deflate_level, gdal_cache_max, overview_levels, predictor_for
from toolbox.io.write_failures import writing
from toolbox.raster.datasets import file_stamp

DEFAULT_TILE = 512
DEFAULT_CACHE_MB = 256  # GDAL block cache while writing (bounded, whatever the output size)
#: the profile's keys of the dataset itself (the others are GTiff creation options)
MEM_KEYS = ("driver", "width", "height", "count", "dtype", "crs", "transform", "nodata")
# GDAL block cache while building overviews: each level is read once, block row by block row, so
# a small cache costs no CPU (20000 x 20000 float32: 18.9 against 18.3 CPU s) and keeps the peak
# down (overviews alone 177 MB instead of 417 MB; the whole dem:nearest run: see bench/results)
OVERVIEW_CACHE_MB = 32


def overview_block(tile: int) -> int:
    """``GDAL_TIFF_OVR_BLOCKSIZE`` for a file of ``tile``-cell blocks. GDAL takes a power of two
    from 64 to 4096 (any other value: a warning, "Wrong value for GDAL_TIFF_OVR_BLOCKSIZE", and
    128): the largest not above ``tile``, within those bounds (``tile`` itself for the usual
    256 or 512)."""
    size = 1 << (max(int(tile), 1).bit_length() - 1)
    return min(max(size, 64), 4096)


class RasterWriter:
    """Context manager writing an output grid window by window.

    Parameters
    ----------
    path : path
        The GeoTIFF to write.
    grid : toolbox.io.grid.GridSpec
        Output grid (transform, width, height, crs; crs None for a local system).
    count : int
        Bands written by :meth:`write`, the alpha band included when ``alpha``.
    dtype : dtype
        Data type of every band.
    nodata : float, optional
        Nodata value of the data bands (not with ``alpha``).
    alpha : bool
        The last band is an alpha band (0 = transparent, the dtype's maximum = opaque).
    cog : bool
        Write a Cloud Optimized GeoTIFF (see the module notes).
    tile : int
        Block side in pixels (a multiple of 16).
    compress : str
        GDAL codec (DEFLATE, LZW, ZSTD, NONE...).
    overviews : bool
        Build internal overviews at close.
    band_descriptions : sequence of str, optional
        One description per band.
    band_units : sequence of str, optional
        One unit per band (GDAL's unit type: "m", "degree", "percent"; "" for none), so
        GDAL, QGIS and the toolbox's own readers (:func:`toolbox.io.raster.require_height_unit`)
        know what the values measure.
    photometric : str, optional
        TIFF photometric interpretation; default RGB for three integer data bands.
    tags : dict, optional
        Dataset metadata.
    overview_resampling : str
        Overview resampling (``average``; ``nearest`` for classes).
    creation_options : dict, optional
        More GTiff creation options (override the defaults).
    memory_mb : float
        Outputs up to this size (all bands, uncompressed) with overviews are gathered in memory
        and copied once into the GeoTIFF (see the module notes); 0: always streamed.
    gcps : sequence of rasterio.control.GroundControlPoint, optional
        Georeference the raster by these ground control points (in ``grid.crs``) instead of
        the grid's transform (a photo with its GCPs; the grid gives only the size).
    threads : int, optional
        GDAL's threads compressing an output gathered in memory (``memory_mb``), whose one
        copy into the GeoTIFF releases the GIL (default: all CPUs). 1 where the caller keeps
        every core busy with other outputs (ortho:batch's photos: 4 drone orthos 0.90 -> 0.87 s,
        less CPU). A streamed output keeps all CPUs whatever ``threads`` says: its tiles are
        compressed while rasterio's writes hold the GIL, so one thread there stalled the other
        photos (NGI 1 m: 6.97 -> 8.57 s, measured).
    executor : toolbox.executor.Executor, optional
        A Dask cluster makes the overviews or the COG copy of a streamed output on a worker
        (module notes); ``finished_on`` then says where (``host:pid``).

    Example
    -------
    >>> with RasterWriter(path, grid, 1, "float32", nodata=-9999.0) as w:  # doctest: +SKIP
    ...     for tile in iter_tiles(grid):
    ...         w.write(tile.window, values_of(tile))
    """

    def __init__(self, path: Any, grid: Any, count: int, dtype: Any, nodata: float | None = None,
                 *, alpha: bool = False, cog: bool = False, tile: int = DEFAULT_TILE,
                 compress: str = "DEFLATE", overviews: bool = True,
                 band_descriptions: Any = None, photometric: str | None = None,
                 tags: dict | None = None, band_units: Any = None, overview_resampling: str = "average",
                 creation_options: dict | None = None, cache_mb: int = DEFAULT_CACHE_MB,
                 memory_mb: float = 0, gcps: Any = None, threads: int | None = None,
                 executor: Any = None):
        if tile % 16:
            raise ValueError(f"tile must be a multiple of 16, got {tile}")
        if alpha and nodata is not None:
            raise ValueError("an output has either an alpha band or a nodata value, not both")
        from toolbox.io.raster import check_nodata_fits

        check_nodata_fits(nodata, dtype)  # a ParameterError naming NODATA, not GDAL's ValueError
        self.path = Path(path)
        self.grid = grid
        self.count = int(count)
        self.dtype = np.dtype(dtype)
        self.nodata = nodata
        self.alpha = bool(alpha)
        self.cog = bool(cog)
        self.tile = int(tile)
        self.compress = str(compress).upper()
        self.overviews = bool(overviews)
        self.band_descriptions = list(band_descriptions) if band_descriptions else None
        self.band_units = list(band_units) if band_units else None
        self.photometric = photometric
        self.tags = dict(tags or {})
        self.overview_resampling = overview_resampling
        self.creation_options = dict(creation_options or {})
        self.cache_mb = int(cache_mb)
        self.gcps = list(gcps) if gcps else None
        self._stack: ExitStack | None = None
        self._discarded = False
        self.dataset = None
        # a COG is copied from a plain tiled file written beside it
        self._tiled_path = self.path.with_name(f".{self.path.name}.tiled.tif") if cog else \
            self.path
        size_mb = grid.width * grid.height * self.count * self.dtype.itemsize / 2**20
        self.in_memory = (self.overviews and not self.cog and size_mb <= memory_mb
                          and bool(overview_levels(grid.width, grid.height, self.tile)))
        self.threads = "ALL_CPUS" if threads is None or not self.in_memory else \
            str(max(1, int(threads)))
        self.executor = executor
        self.finished_on: str | None = None  # host:pid that made the overviews or the COG

    # -- what is written -------------------------------------------------------------------------
    @property
    def predictor(self) -> int:
        return predictor_for(self.dtype)

    @property
    def mask_alpha(self) -> bool:
        """The alpha band is also written as GDAL's internal mask: GDAL (and so QGIS's
        gdalwarp, gdalbuildvrt and rasterio's ``dataset_mask``) reads an alpha band as the mask
        only as band 2 of 2 or band 4 of 4, and only a Byte or UInt16 one; with other counts
        (an RGBN photo's 4 bands + alpha) or types (an Int16 DEM + alpha) the pixels outside
        the photo were valid black data to them."""
        return self.alpha and (self.count not in (1, 2, 4)
                               or self.dtype.name not in ("uint8", "uint16"))

    @property
    def data_count(self) -> int:
        return self.count - (1 if self.alpha else 0)

    @property
    def fill(self) -> float:
        """Value of data cells without data: nodata, else 0."""
        return 0 if self.nodata is None else self.nodata

    def blank(self, height: int, width: int) -> np.ndarray:
        """A (count, height, width) block of no data: nodata (or 0) and alpha 0."""
        out = np.full((self.count, height, width), self.fill, dtype=self.dtype)
        if self.alpha:
            out[-1] = 0
        return out

    def profile(self) -> dict:
        from toolbox.io.raster import geotiff_profile

        g = self.grid
        profile = geotiff_profile(g.width, g.height, self.count, self.dtype, g.crs, g.transform,
                                  self.nodata, self.tile, self.compress,
                                  num_threads=self.threads.lower())
        photometric = self.photometric
        if photometric is None and self.data_count == 3 and self.dtype.kind in "iu":
            photometric = "RGB"
        if photometric is None and (self.alpha or self.count == 4):
            # GDAL would read 3-4 byte bands as RGB(A): four data bands (an RGB + NIR mosaic
            # or ortho with a nodata value) came out as red, green, blue and *alpha*
            photometric = "MINISBLACK"
        if photometric:
            profile["photometric"] = photometric
        if self.alpha and photometric == "RGB":
            profile["alpha"] = "YES"  # the first extra sample: band 4 of RGB only
        if self.gcps:  # georeferenced by the points (given at open), not by a transform
            del profile["transform"]
        profile.update(self.creation_options)
        return profile

    def _env(self) -> dict:
        return {"GDAL_CACHEMAX": gdal_cache_max(self.cache_mb), "COMPRESS_OVERVIEW": self.compress,
                "PREDICTOR_OVERVIEW": self.predictor,
                "GDAL_TIFF_OVR_BLOCKSIZE": overview_block(self.tile),
                "INTERLEAVE_OVERVIEW": "PIXEL" if self.count > 1 else "BAND",
                "GDAL_TIFF_INTERNAL_MASK": "YES",  # the mask of mask_alpha, in the file
                "ZLEVEL_OVERVIEW": deflate_level(self.dtype),
                "GDAL_NUM_THREADS": self.threads}

    # -- context ---------------------------------------------------------------------------------
    def __enter__(self) -> RasterWriter:
        import rasterio
        from rasterio.enums import ColorInterp

        self._stack = ExitStack()
        try:
            with writing(self.path):  # GDAL's failures: OutputWriteError
                self._stack.enter_context(rasterio.Env(**self._env()))
                profile = self.profile()
                if self.in_memory:  # the GeoTIFF's options are given to the copy at close
                    options = profile
                    profile = {k: profile[k] for k in MEM_KEYS if k in profile} | \
                        {"driver": "MEM"}
                if self.gcps:
                    profile["gcps"] = self.gcps
                self.dataset = self._stack.enter_context(rasterio.open(
                    "MEM" if self.in_memory else self._tiled_path, "w", **profile))
                if self.in_memory:  # the bands' colours as the GeoTIFF's photometry gives them
                    self.dataset.colorinterp = self._colours(options.get("photometric"))
                if self.tags:
                    self.dataset.update_tags(**self.tags)
                if self.band_descriptions:
                    for k, text in enumerate(self.band_descriptions, start=1):
                        self.dataset.set_band_description(k, str(text))
                for k, unit in enumerate(self.band_units or (), start=1):
                    if unit:
                        self.dataset.set_band_unit(k, str(unit))
                if self.alpha and self.count > 1:  # the last band alone is alpha
                    interp = list(self.dataset.colorinterp)
                    want = [ColorInterp.undefined if c == ColorInterp.alpha else c
                            for c in interp[:-1]] + [ColorInterp.alpha]
                    if want != interp:
                        self.dataset.colorinterp = want
        except BaseException:
            self._abort()
            raise
        return self

    def write(self, window: Any, array: np.ndarray) -> None:
        """Write ``array`` ((bands, h, w), or (h, w) for one band) at ``window`` (a rasterio
        Window or a :class:`~toolbox.raster.engine.Tile`) of the grid; cast to the dtype. NaN
        in a float array (the kernels' "no value") is written as ``nodata``."""
        window = getattr(window, "window", window)
        data = array[np.newaxis] if array.ndim == 2 else array
        if data.shape[0] != self.count:
            raise ValueError(f"{data.shape[0]} bands written to a {self.count}-band raster")
        if data.dtype.kind == "f" and self.nodata is not None and not math.isnan(self.nodata):
            missing = np.isnan(data)
            if missing.any():
                data = np.where(missing, data.dtype.type(self.nodata), data)
        if data.dtype != self.dtype:
            data = data.astype(self.dtype)
        with writing(self.path):
            self.dataset.write(data, window=window)
            if self.mask_alpha:
                self.dataset.write_mask(data[-1] > 0, window=window)

    def update_tags(self, **tags: Any) -> None:
        self.dataset.update_tags(**tags)

    def discard(self) -> None:
        """Keep no file: at the end of the ``with`` block the output is removed, as after an
        error, without an error (e.g. a map sheet that holds no valid cell)."""
        self._discarded = True

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None or self._discarded:
            self._abort()
            return
        try:
            with writing(self.path):  # GDAL's failures (flush, overviews): OutputWriteError
                remote = self._finish_task() if self._on_cluster() else None
                if self.overviews and not self.cog and remote is None:
                    self._build_overviews()
                if self.in_memory:
                    self._copy_from_memory()
                self._stack.close()
                self._stack = None
                self.dataset = None
                if remote is not None:
                    self._finish_on_cluster(remote)
                elif self.cog:
                    self._copy_to_cog()
        except BaseException:
            self._abort()
            raise

    def _on_cluster(self) -> bool:
        """A streamed output with overviews or a COG copy to make, and a Dask cluster."""
        return getattr(self.executor, "kind", "local") == "dask" and not self.in_memory and (
            self.cog or (self.overviews and bool(self._overview_factors())))

    def _overview_factors(self) -> list[int]:
        return overview_levels(self.grid.width, self.grid.height, self.tile)

    def _finish_task(self) -> FinishTask:
        """What :func:`finish_geotiff` needs (the file's stamp is taken once it is closed)."""
        return FinishTask(str(self.path), str(self._tiled_path), self.cog,
                          tuple(self._overview_factors()) if self.overviews else (),
                          self.overview_resampling, self._env(),
                          min(self.cache_mb, OVERVIEW_CACHE_MB), self._cog_options(),
                          self.cache_mb)

    def _finish_on_cluster(self, task: FinishTask) -> None:
        """The overviews or the COG copy on a worker of ``executor``, else here."""
        from toolbox.executor import map_tiles

        task.stamp = file_stamp(task.tiled_path)
        done = list(map_tiles(finish_geotiff, [task], executor=self.executor))[0]
        self.finished_on = done or finish_geotiff(task, check_stamp=False)

    def _build_overviews(self) -> None:
        factors = self._overview_factors()
        if factors:
            build_overviews(self.dataset, factors, self.overview_resampling,
                            min(self.cache_mb, OVERVIEW_CACHE_MB))

    def _colours(self, photometric: str | None) -> list:
        """The colour interpretation GDAL gives the bands of the GeoTIFF of :meth:`profile`
        (a MEM dataset's bands are grey/undefined; the alpha band weighs the overviews)."""
        from rasterio.enums import ColorInterp

        first = [ColorInterp.red, ColorInterp.green, ColorInterp.blue] \
            if photometric == "RGB" else [ColorInterp.gray]
        colours = (first + [ColorInterp.undefined] * self.count)[:self.count]
        if self.alpha and self.count > 1:
            colours[-1] = ColorInterp.alpha
        return colours

    def _copy_from_memory(self) -> None:
        """The MEM dataset and its overviews into the GeoTIFF, tiles and codec of
        :meth:`profile`, the overviews as they are (GDAL's ``COPY_SRC_OVERVIEWS``)."""
        import rasterio.shutil

        options = {k: v for k, v in self.profile().items() if k not in MEM_KEYS}
        rasterio.shutil.copy(self.dataset, self.path, copy_src_overviews=True, **options)

    def _cog_options(self) -> dict:
        options = {"COMPRESS": self.compress, "BLOCKSIZE": self.tile, "BIGTIFF": "IF_SAFER",
                   "NUM_THREADS": self.threads,
                   "OVERVIEWS": "AUTO" if self.overviews else "NONE",
                   "OVERVIEW_RESAMPLING": self.overview_resampling.upper()}
        if self.compress in ("DEFLATE", "LZW", "ZSTD", "LZMA"):
            options["PREDICTOR"] = self.predictor
        if self.compress == "DEFLATE":
            options["LEVEL"] = deflate_level(self.dtype)
        return options

    def _copy_to_cog(self) -> None:
        copy_to_cog(self._tiled_path, self.path, self._cog_options(), self.cache_mb)

    def _abort(self) -> None:
        if self._stack is not None:
            try:
                self._stack.close()
            except Exception:  # noqa: BLE001 - the original error matters, not this one
                pass
            self._stack = None
        self.dataset = None
        for p in {self._tiled_path, self.path}:
            p.unlink(missing_ok=True)


def empty_marker(dtype: Any) -> tuple[float | None, bool]:
    """How an output of a raster whose every value is valid (no nodata, no alpha band) marks
    its empty cells: ``(nodata, alpha)``, NaN for floats, else an alpha band (a nodata of 0
    would turn its valid zeros, sea level or black pixels, into no data)."""
    return (float("nan"), False) if np.dtype(dtype).kind == "f" else (None, True)


def _copy_descriptions_units(src: Any, dst: Any, bands: list[int]) -> None:
    """Band ``bands[k]``'s (1-based) description and unit type of the open raster ``src`` onto
    band ``k + 1`` of the open, writable ``dst`` (empty ones leave ``dst``'s as they are)."""
    for k, b in enumerate(bands, start=1):
        if src.descriptions[b - 1]:
            dst.set_band_description(k, src.descriptions[b - 1])
        if src.units[b - 1]:
            dst.set_band_unit(k, src.units[b - 1])


def copy_band_names(src: Any, dst: Any, bands: Any) -> None:
    """Copy each data band's description, unit type and colour interpretation from the open
    raster ``src`` (band ``bands[k]``, 1-based) to band ``k + 1`` of the open, writable ``dst``
    (a photo's bands resampled: ortho, rectified photo): an RGB + near-infrared photo's ortho
    came out as gray, undefined, undefined, undefined (and alpha), its band names ("nir")
    gone. Gray and undefined source bands leave the writer's interpretation as it is; an
    alpha band of ``dst`` stays alpha."""
    from rasterio.enums import ColorInterp

    bands = list(bands)
    _copy_descriptions_units(src, dst, bands)
    colours = list(dst.colorinterp)
    for k, b in enumerate(bands):
        ci = src.colorinterp[b - 1]
        if ci not in (ColorInterp.gray, ColorInterp.undefined, ColorInterp.alpha) \
                and colours[k] != ColorInterp.alpha:
            colours[k] = ci
    if colours != list(dst.colorinterp):
        dst.colorinterp = colours


def copy_band_metadata(src: Any, dst: Any, bands: Any = None) -> None:
    """Copy what the values of the open raster ``src`` mean onto the open, writable ``dst``
    (a raster passed through: cut, clipped): each band's description, unit type, scale and
    offset, colour table and metadata (GDAL's statistics left out: the copy holds other
    cells), and the dataset's metadata. ``bands``: the 1-based ``src`` band of each ``dst``
    band (default ``1..src.count``). Without it a scaled Int16 DEM (heights = code x scale +
    offset) was read as codes, a DEM in feet as metres, a classified raster lost its colours.
    """
    bands = list(range(1, src.count + 1)) if bands is None else list(bands)
    tags = src.tags()
    if tags:
        dst.update_tags(**tags)
    _copy_descriptions_units(src, dst, bands)
    for k, b in enumerate(bands, start=1):
        band_tags = {key: v for key, v in src.tags(b).items()
                     if not key.startswith("STATISTICS_")}
        if band_tags:
            dst.update_tags(k, **band_tags)
        try:
            dst.write_colormap(k, src.colormap(b))
        except ValueError:  # no colour table
            pass
    scales = [src.scales[b - 1] for b in bands] + [1.0] * (dst.count - len(bands))
    offsets = [src.offsets[b - 1] for b in bands] + [0.0] * (dst.count - len(bands))
    if any(s != 1.0 for s in scales) or any(o != 0.0 for o in offsets):
        dst.scales, dst.offsets = scales, offsets


def build_overviews(dataset: Any, factors: list[int], resampling: str, cache_mb: int) -> None:
    """GDAL's overviews of an open, writable ``dataset`` at ``factors``, with a block cache of
    ``cache_mb`` (each level is read once), and the resampling noted in its tags."""
    import rasterio
    from rasterio.enums import Resampling

    with rasterio.Env(GDAL_CACHEMAX=gdal_cache_max(cache_mb)):
        dataset.build_overviews(list(factors), Resampling[resampling])
    dataset.update_tags(ns="rio_overview", resampling=resampling)


def copy_to_cog(tiled_path: Path, path: Path, options: dict, cache_mb: int) -> None:
    """GDAL's COG driver makes ``path`` from the tiled GeoTIFF ``tiled_path``, then removes it."""
    import rasterio
    import rasterio.shutil

    try:
        with rasterio.Env(GDAL_CACHEMAX=gdal_cache_max(cache_mb)):
            rasterio.shutil.copy(tiled_path, path, driver="COG", **options)
    except Exception as exc:
        if not type(exc).__module__.startswith("rasterio"):
            raise
        # GDAL failing on the tiled file it just wrote (not written whole: a full disk) is a
        # failed write of the output, not an unreadable input
        import errno

        first = str(exc).splitlines()[0] if str(exc) else "I/O error"
        raise OSError(errno.EIO, f"the tiled GeoTIFF could not be made a COG ({first})",
                      str(path)) from exc
    Path(tiled_path).unlink(missing_ok=True)


@dataclass
class FinishTask:
    """The last step of a streamed GeoTIFF (picklable: it runs on a Dask worker): its overviews
    (``factors``; none for a COG) or its COG copy, with the writer's GDAL settings."""

    path: str
    tiled_path: str
    cog: bool
    factors: tuple[int, ...]
    resampling: str
    env: dict = field(default_factory=dict)
    overview_cache_mb: int = OVERVIEW_CACHE_MB
    cog_options: dict = field(default_factory=dict)
    cache_mb: int = DEFAULT_CACHE_MB
    stamp: tuple[int, int] | None = None  # file_stamp(tiled_path) once closed


def finish_geotiff(task: FinishTask, check_stamp: bool = True) -> str | None:
    """Make the overviews (in place) or the COG copy of a closed GeoTIFF; returns
    ``host:pid`` of the process that did it, or None (nothing done) when ``check_stamp`` and
    this process does not see the file the client closed (another machine without shared
    storage)."""
    import rasterio

    if check_stamp:
        try:
            if file_stamp(task.tiled_path) != task.stamp:
                return None
        except OSError:
            return None
    if task.cog:  # as the writer does it: after closing, outside its GDAL settings
        copy_to_cog(Path(task.tiled_path), Path(task.path), task.cog_options, task.cache_mb)
    elif task.factors:
        with rasterio.Env(**task.env), rasterio.open(task.path, "r+") as dataset:
            build_overviews(dataset, task.factors, task.resampling, task.overview_cache_mb)
    return f"{socket.gethostname()}:{os.getpid()}"


def write_raster(path: Any, array: np.ndarray, transform: Any, crs: Any,
                 nodata: float | None = None, overviews: bool = False,
                 overview_resampling: str = "average", **options: Any) -> Path:
    """Write a whole array ((bands, rows, cols), or (rows, cols) for one band) as a GeoTIFF
    with :class:`RasterWriter` (``options``: its keyword arguments, e.g. ``cog``, ``alpha``,
    ``tile``, ``creation_options``)."""
    from rasterio.windows import Window

    from toolbox.io.grid import GridSpec

    data = array[np.newaxis] if array.ndim == 2 else array
    grid = GridSpec(transform, data.shape[2], data.shape[1], crs)
    with RasterWriter(path, grid, data.shape[0], data.dtype, nodata, overviews=overviews,
                      overview_resampling=overview_resampling, **options) as dst:
        dst.write(Window(0, 0, grid.width, grid.height), data)
    return Path(path)


# -- COG layout check --------------------------------------------------------------------------
_GHOST = b"GDAL_STRUCTURAL_METADATA_SIZE="


def _ifds(data: bytes) -> tuple[list[dict], int, bool]:
    """Parse the IFD chain of a TIFF: ([{offset, tags}], header size, bigtiff)."""
    order = {b"II": "<", b"MM": ">"}.get(data[:2])
    if order is None:
        raise ValueError("not a TIFF file")
    magic = struct.unpack(order + "H", data[2:4])[0]
    big = magic == 43
    if big:
        first = struct.unpack(order + "Q", data[8:16])[0]
    elif magic == 42:
        first = struct.unpack(order + "I", data[4:8])[0]
    else:
        raise ValueError("not a TIFF file")
    sizes = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8, 16: 8,
             17: 8, 18: 8}
    codes = {1: "B", 2: "B", 3: "H", 4: "I", 6: "b", 7: "B", 8: "h", 9: "i", 16: "Q", 17: "q",
             18: "Q"}
    ifds, offset = [], first
    while offset and len(ifds) < 1000:
        if big:
            n = struct.unpack(order + "Q", data[offset:offset + 8])[0]
            entry0, entry_size, inline = offset + 8, 20, 8
        else:
            n = struct.unpack(order + "H", data[offset:offset + 2])[0]
            entry0, entry_size, inline = offset + 2, 12, 4
        tags = {}
        for k in range(n):
            e = entry0 + k * entry_size
            tag, typ = struct.unpack(order + "HH", data[e:e + 4])
            count = struct.unpack(order + ("Q" if big else "I"),
                                  data[e + 4:e + (12 if big else 8)])[0]
            if typ not in codes:
                continue
            size = sizes[typ] * count
            value_at = e + (12 if big else 8)
            if size > inline:
                value_at = struct.unpack(order + ("Q" if big else "I"),
                                         data[value_at:value_at + inline])[0]
            count_read = min(count, 4)  # the first values are enough here
            tags[tag] = struct.unpack(order + codes[typ] * count_read,
                                      data[value_at:value_at + sizes[typ] * count_read])
        ifds.append({"offset": offset, "tags": tags})
        end = entry0 + n * entry_size
        offset = struct.unpack(order + ("Q" if big else "I"), data[end:end + inline])[0]
    return ifds, (16 if big else 8), big


def cog_problems(path: Any) -> list[str]:
    """Why ``path`` is not a Cloud Optimized GeoTIFF (an empty list: it is one).

    The checks of GDAL's ``validate_cloud_optimized_geotiff.py``: the main image and every
    overview tiled; overviews present for an image larger than 512 x 512; the first IFD right
    after the header (or after GDAL's structural-metadata ghost area); IFDs in the order main
    image, then overviews from the largest; each overview's first tile stored before the
    previous level's (the smallest overview first, the main image last); tile data after the
    IFDs.
    """
    data = Path(path).read_bytes()
    try:
        ifds, header, _ = _ifds(data)
    except (ValueError, struct.error) as exc:
        return [f"cannot parse the TIFF structure: {exc}"]
    problems: list[str] = []
    if not ifds:
        return ["no image in the file"]
    first = ifds[0]["offset"]
    if first != header:
        ghost = data[header:header + len(_GHOST) + 6]
        size = int(ghost[len(_GHOST):]) if ghost.startswith(_GHOST) and \
            ghost[len(_GHOST):].isdigit() else None
        # GDAL's ghost area: "GDAL_STRUCTURAL_METADATA_SIZE=XXXXXX bytes\n" + XXXXXX bytes
        if size is None or first > header + len(_GHOST) + 13 + size + 8:
            problems.append(f"the main IFD is at byte {first}, not right after the header "
                            f"({header}) or GDAL's structural metadata")
    images = [d for d in ifds if not (d["tags"].get(254, (0,))[0] & 4)]  # masks excluded
    main, overviews = images[0], images[1:]
    width, height = main["tags"][256][0], main["tags"][257][0]
    for k, d in enumerate(images):
        if 322 not in d["tags"]:
            problems.append("the main image is not tiled" if k == 0 else
                            f"overview {k - 1} is not tiled")
    if (width > 512 or height > 512) and not overviews:
        problems.append(f"a {width} x {height} image without overviews")
    previous = None
    for k, d in enumerate(overviews):
        w = d["tags"][256][0]
        if previous is not None and w >= previous:
            problems.append(f"overview {k} is not smaller than overview {k - 1}")
        previous = w
    offsets = [d["offset"] for d in images]
    if offsets != sorted(offsets):
        problems.append("the IFDs are not in the order main image, then overviews")
    data_start = [d["tags"].get(324, d["tags"].get(273, (0,)))[0] for d in images]
    for k in range(1, len(images)):
        if data_start[k] and data_start[k - 1] and data_start[k] > data_start[k - 1]:
            what = "the main image" if k == 1 else f"overview {k - 2}"
            problems.append(f"the tiles of overview {k - 1} come after those of {what}")
    last_ifd = max(d["offset"] for d in ifds)
    if any(0 < s < last_ifd for s in data_start):
        problems.append("tile data before the last IFD (IFDs are not all at the start)")
    return problems


def keep_off_nodata(data: np.ndarray, valid: np.ndarray, nodata: float | None) -> np.ndarray:
    """``data`` ``(bands, rows, cols)`` with every ``valid`` ``(rows, cols)`` cell whose bands
    all equal ``nodata`` moved one step off it (``nodata - 1`` for integers, ``nodata + 1``
    when it is the type's minimum, as GDAL's warp kernel does; for floats, every band that GDAL
    reads as nodata (:func:`reads_as_nodata`) moves to the first float above nodata that GDAL
    reads as valid), in place.

    A computed value (balanced, blended) may land on the nodata value: a dark shadow of a
    uint8 ortho with nodata 0 balanced by a negative offset came out 0, written as no data (a
    hole in the mosaic). Only cells with every band at nodata are moved: GDAL's dataset mask
    (:func:`toolbox.io.raster.read_dataset_masked`) keeps a pixel with some bands at nodata,
    pure blue (0, 0, 255), valid, and such a pixel is copied as it is."""
    if nodata is None or math.isnan(nodata):
        return data
    dt = data.dtype
    if dt.kind in "iu":
        info = np.iinfo(dt)
        if not (float(nodata).is_integer() and info.min <= nodata <= info.max):
            return data
        step = int(nodata) - 1 if nodata > info.min else int(nodata) + 1
        hit = (data == dt.type(nodata)).all(axis=0) & valid
    else:  # GDAL reads a float within ~4 float ulps of nodata as no data too: step past them
        step = dt.type(nodata + abs(nodata) * 5 * float(np.finfo(np.float32).eps))
        while reads_as_nodata(step, nodata):  # (a few steps at most)
            step = np.nextafter(step, dt.type(np.inf))
        hit = reads_as_nodata(data, nodata).all(axis=0) & valid
    data[:, hit] = step
    return data


def reads_as_nodata(values: Any, nodata: float) -> Any:
    """Which float ``values`` GDAL's nodata mask reads as the (finite) ``nodata``: equal, or
    within ``FLT_EPSILON * |value + nodata| * 2`` (GDAL's ``ARE_REAL_EQUAL``, for Float32 and
    Float64 bands alike: -9998.999 is no data with nodata -9999)."""
    values = np.asarray(values)
    nd = values.dtype.type(nodata)
    tolerance = np.finfo(np.float32).eps * np.abs(values + nd) * 2
    return (values == nd) | (np.abs(values - nd) < tolerance)
