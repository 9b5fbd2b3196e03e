"""Indirect warping: output tile -> source coordinates -> OpenCV resampling, and the warp mode
of the raster engine (:func:`warp_raster`, :func:`warp_to_geotiff`).

This is the resampling machinery of every output-to-source geometric correction (rectify,
ortho, true ortho, epipolar resampling): the caller gives a coordinate map
(:class:`~toolbox.raster.maps.CoordinateMap` and the capabilities it declares), and for each
tile :func:`warp_window`

1. gets the source window the tile needs: from the map's plan (a
   :class:`~toolbox.raster.maps.PlannedMap`), its exact bounds
   (:class:`~toolbox.raster.maps.BoundedMap`), its measured points
   (:class:`~toolbox.raster.maps.MeasuredMap`) or a scan of its coordinates,
2. reads only that window plus the interpolation margin (rasterio windowed read),
3. resamples with OpenCV (:mod:`toolbox.raster.resample`: ``cv2.remap``, or
   ``cv2.warpPerspective`` for a :class:`~toolbox.raster.maps.PerspectiveMap`), with an alpha
   band or nodata outside the source,

and the engine (:func:`toolbox.raster.engine.process_raster`) writes the tile with
:class:`toolbox.raster.writer.RasterWriter`, so memory is bounded by the tile size, whatever the
size of the photo or of the output. Pixel conventions: :mod:`toolbox.raster.maps`; output pixel
centres follow :mod:`toolbox.io.grid`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.counters import Counters
from toolbox.errors import ParameterError
from toolbox.io.grid import GridSpec
from toolbox.raster.datasets import ThreadDatasets
from toolbox.raster.engine import RasterInput, process_raster
from toolbox.raster.maps import (
    OUTSIDE,
    BoundedMap,
    CoordinateMap,
    MeasuredMap,
    PerspectiveMap,
    PlannedMap,
    ReportingMap,
    fill_outside_intervals,
    mask_from_intervals,
    plan_source,
    scan_bounds,
    window_parts,
)
from toolbox.raster.resample import (
    CV2_DTYPES,
    EXTRA_RESAMPLING,
    RESAMPLING_MARGIN,
    RESAMPLING_METHODS,
    deinterleave,
    inside_mask,
    interleave,
    pad_at_photo_edges,
    remap,
    warp_perspective,
)
from toolbox.raster.tile import Tile

DEFAULT_CHUNK = 2048  # output pixels per side of a processing window (a multiple of the block)
DEFAULT_MAX_SOURCE_PIXELS = 1 << 24  # larger source windows are split (16 Mpx per band)
DEFAULT_CACHE_MB = 256  # GDAL block cache while warping (bounded, unlike GDAL's 5 % of RAM)
ALPHA_MASK_DTYPES = ("uint8", "uint16")  # alpha bands GDAL reads as the mask (others: nodata)
WARP_MEMORY_MB = 32  # outputs up to this size are written from memory (RasterWriter memory_mb)


# -- streaming driver ----------------------------------------------------------------------------
@dataclass
class OutputLayout:
    """How source bands become output bands.

    data_bands : 1-based source band indexes resampled as data (every band except an alpha band)
    source_alpha : 1-based index of the source alpha band, or None
    source_masked : the source has nodata or an internal mask (sampled to find valid pixels)
    alpha : the output has an alpha band (last band)
    nodata : the output nodata value (None with an alpha band)
    dtype : numpy dtype name of the output
    """

    data_bands: list[int]
    source_alpha: int | None
    source_masked: bool
    alpha: bool
    nodata: float | None
    dtype: str

    @property
    def count(self) -> int:
        return len(self.data_bands) + (1 if self.alpha else 0)

    @property
    def fill(self) -> float:
        return 0 if self.nodata is None else self.nodata

    @property
    def alpha_max(self) -> float:
        dt = np.dtype(self.dtype)
        return float(np.iinfo(dt).max) if dt.kind in "iu" else 1.0


def photo_path(source: Any) -> str:
    """The path a warp reads the photo ``source`` (a path or RasterInfo) by: a paletted photo
    (one band with a colour table: its values are colour codes, which no resampling may
    interpolate) as its colours, RGB or RGBA when the table has transparency, as
    ``gdal_translate -expand rgb|rgba`` writes them (GDAL's ``vrt://`` expansion)."""
    from toolbox.raster.datasets import open_quietly
    from toolbox.raster.photo_grid import expanded_path

    path = str(getattr(source, "path", source))
    with open_quietly(path) as src:
        return expanded_path(src, path)


def open_photo(source: Any) -> tuple[str, Any]:
    """``(path, dataset)``: the photo ``source`` (a path or RasterInfo) open as a warp reads
    it, by :func:`photo_path`'s path (the caller closes it); one open of the file unless it is
    paletted (each open parses the file's header and georeferencing again: a warp opened its
    photo seven times); a photo with an EXIF orientation warned about
    (:func:`~toolbox.raster.photo_grid.warn_orientation_tag`)."""
    from toolbox.raster.photo_grid import open_expanded

    return open_expanded(getattr(source, "path", source), warn_orientation=True)


@contextmanager
def opened_photo(source: Any) -> Iterator[tuple[str, Any]]:
    """:func:`open_photo` as a context that closes the dataset."""
    path, src = open_photo(source)
    with src:
        yield path, src


def warp_layout(source: Any, outside: str = "alpha", nodata: float | None = None) -> OutputLayout:
    """:func:`output_layout` of a raster path (or RasterInfo), a paletted one expanded
    (:func:`photo_path`)."""
    with opened_photo(source) as (_, src):
        return output_layout(src, outside, nodata)


def output_layout(src: Any, outside: str = "alpha", nodata: float | None = None) -> OutputLayout:
    """Decide the output bands of a warp of the open rasterio dataset ``src``.

    ``outside = "alpha"`` adds an alpha band (0 outside the photo, the dtype's maximum inside);
    ``"nodata"`` fills outside pixels with ``nodata`` (default: the source nodata, else 0 for
    integers and NaN for floats). A source alpha band is resampled and always kept as alpha
    (``"nodata"`` is then refused: :class:`~toolbox.errors.ParameterError` on OUTSIDE).
    Only Byte and UInt16 rasters get an alpha band (GDAL reads no other alpha as a mask): the
    others mark the outside (and a source alpha's transparent cells) with nodata, by default the
    source's, else NaN for floats and the type's extreme for integers (:func:`_outside_value`).
    """
    from rasterio.enums import ColorInterp, MaskFlags

    if outside not in ("alpha", "nodata"):
        raise ValueError(f"outside must be 'alpha' or 'nodata', got {outside!r}")
    dtypes = set(src.dtypes)
    if len(dtypes) != 1:
        raise ValueError(f"bands of different data types ({', '.join(sorted(dtypes))})")
    dtype = src.dtypes[0]
    interp = list(src.colorinterp)
    alpha_bands = [k + 1 for k, ci in enumerate(interp) if ci == ColorInterp.alpha]
    source_alpha = alpha_bands[-1] if alpha_bands and src.count > 1 else None
    data_bands = [b for b in range(1, src.count + 1) if b != source_alpha]
    flags = src.mask_flag_enums[data_bands[0] - 1] if src.count else []
    source_masked = source_alpha is None and (
        src.nodata is not None or MaskFlags.per_dataset in flags)
    alpha_masks = np.dtype(dtype).name in ALPHA_MASK_DTYPES  # GDAL reads no other alpha as mask
    if not alpha_masks:
        if outside == "alpha" and nodata is None and src.nodata is None:
            nodata = _outside_value(np.dtype(dtype))
        outside = "nodata"
    if outside == "nodata" and source_alpha is not None and alpha_masks:
        # (the output keeps the photo's alpha: it would get an alpha band and a nodata value,
        # which the writer refuses, an internal error after the work)
        name = str(getattr(src, "name", ""))
        if name.startswith("vrt://") and name.endswith("?expand=rgba"):  # paletted: photo_path
            raise ParameterError("OUTSIDE", f"nodata does not apply to a paletted photo with "
                                 f"transparency (read as RGBA, its alpha kept as the output's):"
                                 f" use OUTSIDE=alpha, or warp its colours without the "
                                 f"transparency (gdal_translate -expand rgb "
                                 f"'{name[6:-12]}' photo_rgb.tif)")
        bands = " ".join(f"-b {b}" for b in data_bands)
        raise ParameterError("OUTSIDE", f"nodata does not apply to a photo with an alpha band "
                             f"(band {source_alpha}, kept as the output's alpha): use "
                             f"OUTSIDE=alpha, or warp its other bands "
                             f"(gdal_translate {bands} photo.tif bands.tif)")
    alpha = outside == "alpha" or (source_alpha is not None and alpha_masks)
    out_nodata = None
    if outside == "nodata":
        if nodata is not None:
            out_nodata = float(nodata)
        elif src.nodata is not None:
            out_nodata = float(src.nodata)
        else:
            out_nodata = float("nan") if np.dtype(dtype).kind == "f" else 0.0
        if np.dtype(dtype).kind in "iu" and not math.isnan(out_nodata):
            info = np.iinfo(np.dtype(dtype))
            if not (info.min <= out_nodata <= info.max and out_nodata == int(out_nodata)):
                raise ParameterError("NODATA", f"{out_nodata:g} does not fit the {dtype} data "
                                     f"type ({info.min}..{info.max})")
        elif np.dtype(dtype).kind in "iu":
            raise ParameterError("NODATA", f"NaN does not fit the integer data type {dtype}")
    return OutputLayout(data_bands, source_alpha, source_masked, alpha, out_nodata, dtype)


def _outside_value(dtype: np.dtype) -> float:
    """No-data value marking the outside of a warp of ``dtype`` without alpha: NaN for floats,
    the smallest value of a signed integer type, the largest of an unsigned one."""
    if dtype.kind == "f":
        return float("nan")
    info = np.iinfo(dtype)
    return float(info.min if dtype.kind == "i" else info.max)


def photometric_options(layout: OutputLayout) -> dict[str, str]:
    """GeoTIFF creation options declaring RGB photometry and the alpha band."""
    options: dict[str, str] = {}
    if len(layout.data_bands) == 3 and np.dtype(layout.dtype).kind in "iu":
        options["photometric"] = "RGB"
    if layout.alpha:
        options["alpha"] = "YES"
    return options


@dataclass
class WarpStatistics(Counters):
    """Counters of one warp run, summed over windows by :meth:`add`."""

    windows: int = 0  # output windows computed
    empty_windows: int = 0  # windows that see no source pixel
    split_windows: int = 0  # windows split because their source footprint was too large
    source_pixels_read: int = 0  # source pixels read over all windows
    output_pixels: int = 0  # output pixels written


def _split(window: Any) -> list[Any]:
    from rasterio.windows import Window

    col0, row0, width, height = window_parts(window)
    hw, hh = max(width // 2, 1), max(height // 2, 1)
    parts = []
    for r0, h in ((row0, hh), (row0 + hh, height - hh)):
        for c0, w in ((col0, hw), (col0 + hw, width - hw)):
            if w > 0 and h > 0:
                parts.append(Window(c0, r0, w, h))
    return parts


def warp_window(read: Callable[[list[int], Any], np.ndarray], source_size: tuple[int, int],
                coordinate_map: CoordinateMap, tile: Any, layout: OutputLayout,
                resampling: str = "bilinear",
                read_mask: Callable[[Any], np.ndarray] | None = None,
                max_source_pixels: int = DEFAULT_MAX_SOURCE_PIXELS,
                stats: WarpStatistics | None = None,
                fast: bool = True, aux: dict | None = None) -> Iterator[tuple[Any, np.ndarray]]:
    """Warp one output tile; yield ``(window, array (count, h, w))`` parts to write.

    ``tile`` is a :class:`toolbox.raster.tile.Tile` (or a bare Window: a tile without halo);
    ``aux`` the auxiliary arrays read onto it, handed to ``coordinate_map(tile, aux)``.

    ``read(bands, source_window)`` returns the source pixels (len(bands), h, w); ``read_mask``
    the source validity (h, w) uint8 0/255 (sources with nodata or an internal mask). Windows
    whose source window exceeds ``max_source_pixels`` are split in four, recursively. The
    map's declared capabilities (:mod:`toolbox.raster.maps`) choose the path: a
    :class:`~toolbox.raster.maps.PlannedMap` (the orthophoto's) decides the source window first
    and hands ready OpenCV maps; with ``fast`` a :class:`~toolbox.raster.maps.PerspectiveMap`
    (a homography) is evaluated by OpenCV's ``warpPerspective`` itself (same sampling as
    ``remap`` with the map's coordinates, without the coordinate arrays); otherwise the
    coordinates are computed (with their bounds, for a
    :class:`~toolbox.raster.maps.MeasuredMap`) and ``cv2.remap`` samples them. On the first two
    paths, for a source without alpha band or mask and 1, 3 or 4 output bands, the bands travel
    pixel-interleaved from the read to the writer (:func:`_warp_packed`), and cells outside
    the photo are filled by OpenCV's border value.
    """
    if not isinstance(tile, Tile):
        tile = Tile(0, tile, 0, None)
    aux = aux or {}
    window = tile.window
    stats = stats if stats is not None else WarpStatistics()
    width, height = source_size
    col0, row0, out_w, out_h = window_parts(window)
    plan = coordinate_map.plan(tile, aux) if isinstance(coordinate_map, PlannedMap) else None
    planned = plan is not None
    bounds = cols = rows = None
    exact_bounds = False
    if not planned:
        if isinstance(coordinate_map, BoundedMap):
            bounds = coordinate_map.source_bounds(window)
        if bounds is None:
            if isinstance(coordinate_map, MeasuredMap):
                cols, rows, bounds = coordinate_map.measured(tile, aux)
            else:
                cols, rows = coordinate_map(tile, aux)
        exact_bounds = bounds is not None
        if bounds is None:
            bounds = scan_bounds(cols, rows)
        plan = plan_source(bounds, width, height, resampling)
    out = np.empty((layout.count, out_h, out_w), dtype=layout.dtype)
    if plan is None or plan.window is None:  # (a planned map's EMPTY_PLAN)
        stats.empty_windows += 1
        out[:] = layout.fill
        if layout.alpha:
            out[-1] = 0
        yield window, out
        return
    src_win, pads = plan.window, plan.pads
    if src_win.width * src_win.height > max_source_pixels and (out_w > 1 or out_h > 1):
        stats.split_windows += 1
        for part in _split(window):
            sub = tile.sub_tile(part)
            r, c = int(part.row_off) - row0, int(part.col_off) - col0
            rows_, cols_ = sub.haloed_shape
            sub_aux = {k: v[..., r:r + rows_, c:c + cols_] for k, v in aux.items()}
            yield from warp_window(read, source_size, coordinate_map, sub, layout, resampling,
                                   read_mask, max_source_pixels, stats, fast, sub_aux)
        return
    stats.windows += 1
    stats.output_pixels += out_w * out_h
    stats.source_pixels_read += int(src_win.width * src_win.height)
    shift_c, shift_r = plan.shift_col, plan.shift_row
    all_inside = (exact_bounds and bounds[0] >= 0 and bounds[1] >= 0 and bounds[2] <= width
                  and bounds[3] <= height)
    perspective = cols is None and isinstance(coordinate_map, PerspectiveMap)
    use_fast = fast and not planned and perspective and resampling in RESAMPLING_METHODS
    intervals = None
    inside = None
    if use_fast:
        matrix = coordinate_map.perspective_matrix(window, shift_c, shift_r)
        if not all_inside:
            intervals = coordinate_map.inside_intervals(window, width, height)

        def sample(pixels: np.ndarray, method: str) -> np.ndarray:  # (border 0: see _warp_packed)
            return warp_perspective(pixels, matrix, (out_w, out_h), method)
    else:
        if planned:  # ready OpenCV maps, OUTSIDE where the centre is outside the photo
            map_x, map_y = coordinate_map.planned_maps(plan)
        elif perspective:
            map_x, map_y = coordinate_map(window, None, shift_c, shift_r)
        else:
            if cols is None:
                cols, rows = coordinate_map(tile, aux)
            map_x = (cols - np.float32(shift_c)).astype("float32", copy=False)
            map_y = (rows - np.float32(shift_r)).astype("float32", copy=False)

        def sample(pixels: np.ndarray, method: str) -> np.ndarray:  # (border 0: see _warp_packed)
            return remap(pixels, map_x, map_y, method)
    n_data = len(layout.data_bands)
    packed = (use_fast or planned) and layout.source_alpha is None \
        and not layout.source_masked and layout.count in (1, 3, 4) \
        and np.dtype(layout.dtype).name in CV2_DTYPES
    # (not 2 bands: OpenCV's 2-channel warpPerspective samples differently, up to 6 grey
    # levels from its 1-, 3- and 4-channel ones)
    if packed:
        packed_out = _warp_packed(read(layout.data_bands, src_win), pads, layout,
                                  lambda buf: sample(buf, resampling), intervals,
                                  map_x if planned else None)
        if _marks_nodata(layout):  # (an alpha output pays nothing)
            _keep_valid_off_nodata(packed_out, layout, True, intervals,
                                   map_x if planned else None)
        yield window, packed_out
        return
    if planned:
        inside = map_x != OUTSIDE
    elif not all_inside and not use_fast:
        inside = inside_mask(map_x, map_y, width, height, shift_c, shift_r)
    pixels = read(layout.data_bands, src_win)
    sampled = sample(pad_at_photo_edges(interleave(pixels), pads), resampling)
    deinterleave(sampled, out[:n_data])
    del sampled
    # validity from the source itself (alpha band, nodata or internal mask)
    alpha = None
    source_valid = None
    if layout.source_alpha is not None:
        source_alpha = read([layout.source_alpha], src_win)[0]
        alpha = sample(pad_at_photo_edges(source_alpha, pads), resampling)
        _weigh_by_alpha(out[:n_data], pixels, source_alpha, layout, pads, resampling, sample,
                        (lambda r, c: _perspective_points(matrix, r, c)) if use_fast else
                        (lambda r, c: (map_x[r, c], map_y[r, c])))
        if not layout.alpha:
            source_valid = alpha >= layout.alpha_max / 2
    elif layout.source_masked and read_mask is not None:
        touched = sample(pad_at_photo_edges(_invalid_weight(read_mask(src_win), resampling),
                                            pads), "nearest" if resampling == "nearest" else "bilinear")
        source_valid = touched == 0
    if source_valid is not None and intervals is not None:
        inside = mask_from_intervals(*intervals, out_w)
        intervals = None
    valid = inside if source_valid is None else (
        source_valid if inside is None else inside & source_valid)
    if layout.alpha:
        out[-1] = layout.alpha_max if alpha is None else alpha
    elif _marks_nodata(layout):
        _keep_valid_off_nodata(out[:n_data], layout, True if valid is None else valid,
                               intervals)
    if intervals is not None:  # homography fast path: fill row by row, no mask needed
        fill_outside_intervals(out[:n_data], *intervals, layout.fill)
        if layout.alpha:
            fill_outside_intervals(out[-1], *intervals, 0)
    elif valid is not None:
        invalid = ~valid
        for k in range(n_data):
            out[k][invalid] = layout.fill
        if layout.alpha:
            out[-1][invalid] = 0
    yield window, out


def _weigh_by_alpha(out: np.ndarray, pixels: np.ndarray, source_alpha: np.ndarray,
                    layout: OutputLayout, pads: tuple[int, int, int, int], resampling: str,
                    sample: Callable[[np.ndarray, str], np.ndarray],
                    points: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
                    ) -> None:
    """The colours ``out`` (data bands, h, w) of the cells whose kernel holds a (partly)
    transparent photo pixel, weighted by the pixels' alpha, in place: ``sum(w a c) / sum(w a)``
    (the colour of the opaque pixels around, as GDAL's warper weighs a source alpha), not
    ``sum(w c)``, which mixed in the colour kept under transparent pixels (often black: a
    dark fringe, 60 to 90 grey levels off next to a transparent area). ``pixels`` and
    ``source_alpha`` are the source window's bands and alpha; ``points(rows, cols)`` the
    OpenCV coordinates (in the padded window) of output cells. Cells whose kernel is opaque
    keep their value; the others (found by one sample of the transparent pixels grown by the
    kernel's reach) are sampled again, alone, from the part of the window around them. Byte
    and UInt16 photos (whose alpha band GDAL reads as a mask)."""
    import cv2

    amax = layout.alpha_max
    if resampling == "nearest" or layout.dtype not in ALPHA_MASK_DTYPES:
        return
    clear = (source_alpha < amax).view(np.uint8)
    if not cv2.countNonZero(clear):
        return
    radius = RESAMPLING_MARGIN[resampling] - 1
    if radius > 0:
        clear = cv2.dilate(clear, np.ones((2 * radius + 1, 2 * radius + 1), np.uint8))
    touched = sample(pad_at_photo_edges(clear * np.float32(1), pads), "bilinear") > 0
    rows, cols = np.nonzero(touched)
    if not rows.size:
        return
    xs, ys = (np.asarray(v, dtype=np.float64) for v in points(rows, cols))
    bands = interleave(pixels)
    padded = pad_at_photo_edges(bands, pads)
    weight = pad_at_photo_edges(source_alpha, pads)
    reach = RESAMPLING_MARGIN[resampling] + 1
    height, width = padded.shape[:2]
    x0 = int(max(math.floor(xs.min()) - reach, 0))
    y0 = int(max(math.floor(ys.min()) - reach, 0))
    x1 = int(min(math.ceil(xs.max()) + reach + 1, width))
    y1 = int(min(math.ceil(ys.max()) + reach + 1, height))
    if x1 <= x0 or y1 <= y0:
        return
    weight = weight[y0:y1, x0:x1].astype(np.float32) * np.float32(1.0 / amax)
    part = padded[y0:y1, x0:x1].astype(np.float32)
    part *= weight if part.ndim == 2 else weight[:, :, None]
    # the points as rows of a map (OpenCV takes maps under 32767 a side; np.resize fills the
    # last row by repeating them)
    n, side = len(xs), 4096
    shape = (-(-len(xs) // side), min(len(xs), side))
    map_x = np.resize((xs - x0).astype(np.float32), shape)
    map_y = np.resize((ys - y0).astype(np.float32), shape)
    total = remap(weight, map_x, map_y, resampling).ravel()[:n]
    colours = remap(part, map_x, map_y, resampling).reshape(shape[0] * shape[1], -1)[:n]
    # (a cubic or lanczos tap on a transparent pixel may be outweighed: alpha saturates at its
    # maximum, the weights' sum over the opaque taps is not 1)
    redo = (np.abs(total - 1) > 1e-4) & (total > 0)
    if not redo.any():
        return
    info = np.iinfo(np.dtype(layout.dtype))
    values = np.clip(np.rint(colours[redo] / total[redo, None]), info.min, info.max)
    out[:, rows[redo], cols[redo]] = values.T.astype(out.dtype)


def _perspective_points(matrix: np.ndarray, rows: np.ndarray,
                        cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV source coordinates of output cells (``rows``, ``cols`` of the window) by the
    ``cv2.warpPerspective`` matrix (output index -> source, ``WARP_INVERSE_MAP``)."""
    c, r = cols.astype(np.float64), rows.astype(np.float64)
    w = matrix[2, 0] * c + matrix[2, 1] * r + matrix[2, 2]
    return ((matrix[0, 0] * c + matrix[0, 1] * r + matrix[0, 2]) / w,
            (matrix[1, 0] * c + matrix[1, 1] * r + matrix[1, 2]) / w)


def _invalid_weight(mask: np.ndarray, resampling: str) -> np.ndarray:
    """The source validity ``mask`` (h, w) uint8 0/255 as float32 1 on the pixels a cell may
    not touch, 0 elsewhere: its bilinear (nearest) sample is 0 exactly where every pixel of
    ``resampling``'s kernel is valid.

    A cell's bilinear taps are pixels ``i, i + 1`` per axis; cubic's (and quadratic's) reach
    one pixel further each side, lanczos' three (:data:`RESAMPLING_MARGIN` - 1): the mask is
    eroded by that radius. The sample is float (bilinear weights are >= 0): any invalid tap
    with a weight makes it > 0, where a uint8 mask rounds weights under 2/1024 away. Tested
    with a uint8 bilinear sample of the mask alone (>= 255), a cubic or lanczos sample next
    to a nodata pixel took its value with the kernel's outer weights (a -9999 nodata put
    1196 on a photo of 30..250) and was kept valid, and a bilinear one up to 19. (OpenCV's
    erosion leaves the window's border alone: the window holds the kernel of every cell it
    serves.)"""
    import cv2

    radius = RESAMPLING_MARGIN[resampling] - 1
    if radius > 0:
        mask = cv2.erode(mask, np.ones((2 * radius + 1, 2 * radius + 1), np.uint8))
    return (mask == 0).astype(np.float32)


def _marks_nodata(layout: OutputLayout) -> bool:
    """The output marks no data with a number a resampled value can land on (not alpha, not
    NaN)."""
    return layout.nodata is not None and not math.isnan(layout.nodata)


def _keep_valid_off_nodata(data: np.ndarray, layout: OutputLayout, valid: np.ndarray | bool,
                           intervals=None, map_x: np.ndarray | None = None) -> None:
    """Move the valid cells of the warped ``data`` (data bands, h, w) that landed on the
    output nodata one step off it (:func:`toolbox.raster.writer.keep_off_nodata`), in place.

    Cubic and lanczos overshoot: a valid dark pixel next to a bright one interpolates below 0,
    which OpenCV saturates to 0 for uint8, the default nodata; a user's NODATA can equal an
    interpolated value, or a photo sample. Written as it is, the cell would be no data, a
    hole inside the footprint; GDAL's warp kernel moves such a value off the nodata too
    (``gdalwarp -dstnodata 0`` writes 1). ``valid``: the cells inside the photo (and valid
    in it), True for all; ``intervals``: the homography fast path's inside intervals per row,
    which further restrict it, as does a planned map's ``map_x`` (``OUTSIDE`` off the
    photo). The cells at nodata are found by one OpenCV pass over a pixel-interleaved result
    and the outside taken off by OpenCV or row slices: an output without such a cell pays
    about 1 ms per Mpx."""
    import cv2

    from toolbox.raster.writer import keep_off_nodata

    nodata = layout.nodata
    # (a float within a few ulps of nodata reads as nodata too: a superset, keep_off_nodata
    # decides)
    near = 8 * float(np.finfo(np.float32).eps) * abs(nodata) if data.dtype.kind == "f" else 0
    pixels = data.transpose(1, 2, 0)
    if pixels.flags.c_contiguous and data.shape[0] <= 4 and data.dtype.name in CV2_DTYPES:
        at = cv2.inRange(pixels, (nodata - near,) * data.shape[0],
                         (nodata + near,) * data.shape[0])  # 255: every band at nodata
    else:
        def at_nodata(band):
            return np.abs(band - nodata) <= near if near else band == nodata

        at = np.ascontiguousarray(at_nodata(data[0]))
        for band in data[1:]:
            at &= at_nodata(band)
        at = at.view(np.uint8)
    # not the cells outside (all at nodata: the fill)
    if map_x is not None:
        cv2.bitwise_and(at, cv2.compare(map_x, float(OUTSIDE), cv2.CMP_NE), dst=at)
    if intervals is not None:
        fill_outside_intervals(at, *intervals, 0)
    if valid is not True:
        at[~valid] = 0
    if not cv2.countNonZero(at):
        return
    rows, cols = np.nonzero(at)
    moved = keep_off_nodata(data[:, rows, cols][:, None], np.ones((1, rows.size), bool), nodata)
    data[:, rows, cols] = moved[:, 0]


def _warp_packed(data: np.ndarray, pads: tuple[int, int, int, int], layout: OutputLayout,
                 sample: Callable[[np.ndarray], np.ndarray], intervals,
                 planned_x: np.ndarray | None = None) -> np.ndarray:
    """The packed path of :func:`warp_window` for a source without alpha band or mask: the
    source bands ``data`` (bands, h, w) are merged pixel-interleaved into a buffer that has the
    edge pads of :func:`pad_at_photo_edges` (filled by replicating the edge rows and columns,
    without copying the window again) and, for an alpha output, an opaque alpha channel; one
    OpenCV call ``sample(buffer)`` resamples every band with the border value 0 (alpha stays
    opaque inside the photo, and is 0 outside it). Cells outside the photo get ``layout.fill``
    and alpha 0: from the border (fill 0, as with an alpha band) or row by row from
    ``intervals`` (a homography), or where a planned map's ``planned_x`` is
    :data:`~toolbox.raster.maps.OUTSIDE`.

    The border is never the fill itself: OpenCV starts a sample that has a kernel tap off the
    buffer from the border value (``border + sum(w * (pixel - border))``), and with cubic it
    decides that for groups of cells, not cell by cell: a NaN fill made NaN of cells whose
    whole kernel lies on the photo, several cells inside its edge (753 of 24580 cells of a
    float photo rectified with cubic). Returns a (count, h, w) view of the (h, w, count)
    result: GDAL writes pixel-interleaved GeoTIFFs from it without a layout conversion."""
    import cv2

    top, bottom, left, right = pads
    n, h, w = data.shape
    buf = np.empty((top + h + bottom, left + w + right, layout.count), dtype=data.dtype)
    inner = buf[top:top + h, left:left + w]
    planes = list(data)
    if layout.alpha:
        planes.append(np.full((h, w), layout.alpha_max, dtype=data.dtype))
    if len(planes) == 1:
        inner[:, :, 0] = planes[0]
    else:
        merged = cv2.merge(planes, inner)
        if not np.shares_memory(merged, buf):  # pragma: no cover - OpenCV made a new array
            inner[...] = merged
    if top:
        buf[:top, left:left + w] = inner[:1]
    if bottom:
        buf[top + h:, left:left + w] = inner[-1:]
    if left:
        buf[:, :left] = buf[:, left:left + 1]
    if right:
        buf[:, left + w:] = buf[:, left + w - 1:left + w]
    sampled = sample(buf if layout.count > 1 else buf[:, :, 0])
    if sampled.ndim == 2:
        sampled = sampled[:, :, None]
    out = sampled.transpose(2, 0, 1)
    if intervals is not None:
        fill_outside_intervals(out, *intervals, layout.fill)
    elif planned_x is not None and layout.fill != 0:  # (NaN too; an alpha output pays nothing)
        sampled[planned_x == OUTSIDE] = layout.fill
    return out


# -- warp mode: photo -> ground --------------------------------------------------------------------
@dataclass
class _WarpJob:
    path: Any
    datasets: ThreadDatasets
    source_size: tuple[int, int]
    coordinate_map: Any
    layout: Any
    resampling: str
    max_source_pixels: int
    fast: bool
    aux: dict = field(default_factory=dict)


def _warp_kernel(job: _WarpJob, tile: Tile, arrays: dict) -> tuple[np.ndarray, Any]:
    """Warp one tile: aux arrays -> coordinate map -> source window -> OpenCV resampling.
    Returns the tile and ``(WarpStatistics, the map's results of the tile or None)`` (a
    :class:`~toolbox.raster.maps.ReportingMap`'s, taken where the tile ran: on a Dask worker
    the map is a copy, its results travel back with the tile)."""
    src = job.datasets.get(job.path)
    stats = WarpStatistics()

    def read(bands, window):
        return src.read(bands, window=window)

    def read_mask(window):
        return src.dataset_mask(window=window)

    c0, r0 = int(tile.window.col_off), int(tile.window.row_off)
    parts = warp_window(read, job.source_size, job.coordinate_map, tile, job.layout,
                        job.resampling, read_mask, job.max_source_pixels, stats, job.fast,
                        aux=arrays)
    first = next(parts)
    if first[0] == tile.window:  # one part: the tile itself (no copy)
        out = first[1]
    else:
        out = np.empty((job.layout.count, *tile.shape), dtype=job.layout.dtype)
        for part, array in itertools.chain([first], parts):
            pc, pr = int(part.col_off) - c0, int(part.row_off) - r0
            out[:, pr:pr + int(part.height), pc:pc + int(part.width)] = array
    cmap = job.coordinate_map
    results = cmap.take_window_results(tile.window) if isinstance(cmap, ReportingMap) else None
    return out, (stats, results)


def warp_raster(source: Any, grid: GridSpec, coordinate_map: Any, writer_or_output: Any, *,
                layout: Any, resampling: str = "bilinear",
                aux: Mapping[str, RasterInput] | None = None, aux_halo: int = 0,
                tile_size: int = 2048, executor: Any = None, feedback: Any = None,
                max_source_pixels: int | None = None, fast: bool = True,
                start: float = 0.0, end: float = 100.0) -> Any:
    """Indirect warp of ``source`` (a photo) onto ``grid`` through ``coordinate_map``.

    Parameters
    ----------
    source : path or RasterInfo
        Any raster GDAL reads, any band count and data type (its georeferencing is ignored);
        a paletted one is read as its colours (:func:`photo_path`).
    coordinate_map : callable
        ``coordinate_map(tile, aux_arrays) -> (src_col, src_row)``: float32 (h, w) arrays over
        the tile without halo, source pixel convention (:mod:`toolbox.raster.maps`), NaN
        where there is no source point. ``aux_arrays`` holds the ``aux`` rasters read onto the
        tile (with ``aux_halo``). The capabilities it declares (:mod:`toolbox.raster.maps`:
        bounded, perspective, measured, planned) choose the path of :func:`warp_window`.
        It is pickled for a Dask worker (no lock or open file in its state); a
        :class:`~toolbox.raster.maps.ReportingMap` gets each tile's results back here.
    writer_or_output : RasterWriter or callable
        As in :func:`process_raster`; create the writer with ``layout`` (count, dtype, nodata,
        alpha: see :func:`toolbox.raster.warp.warp_layout`).
    layout : toolbox.raster.warp.OutputLayout
        Output bands, nodata/alpha outside the source.
    resampling : {"nearest", "bilinear", "cubic", "lanczos"}
    tile_size : int
        Output tile side (a multiple of the writer's 512 blocks).
    max_source_pixels : int, optional
        Largest source window read at once per band; bigger ones are split.

    Returns the summed :class:`~toolbox.raster.warp.WarpStatistics`.
    """
    methods = RESAMPLING_METHODS + EXTRA_RESAMPLING
    if resampling not in methods:
        raise ValueError(f"resampling must be one of {', '.join(methods)}, got {resampling!r}")
    with opened_photo(source) as (path, src):
        size = (src.width, src.height)
    return _warp_read_path(path, size, grid, coordinate_map, writer_or_output, layout=layout,
                           resampling=resampling, aux=aux, aux_halo=aux_halo,
                           tile_size=tile_size, executor=executor, feedback=feedback,
                           max_source_pixels=max_source_pixels, fast=fast, start=start, end=end)


def _warp_read_path(path: str, size: tuple[int, int], grid: GridSpec, coordinate_map: Any,
                    writer_or_output: Any, *, layout: Any, resampling: str,
                    aux: Mapping[str, RasterInput] | None, aux_halo: int, tile_size: int,
                    executor: Any, feedback: Any, max_source_pixels: int | None, fast: bool,
                    start: float, end: float, datasets: ThreadDatasets | None = None) -> Any:
    """:func:`warp_raster` of the photo read by ``path`` (:func:`photo_path`'s), of ``size``
    (width, height); ``datasets`` the threads' datasets of it (closed here)."""
    from functools import partial

    job = _WarpJob(path, datasets or ThreadDatasets(), size, coordinate_map, layout, resampling,
                   max_source_pixels or DEFAULT_MAX_SOURCE_PIXELS, fast)
    total = WarpStatistics()

    reporting = isinstance(coordinate_map, ReportingMap)

    def collect(tile, array, info):
        if info is not None:
            stats, results = info
            total.add(stats)
            if reporting:  # the tile's results, back in the caller's map (from a worker too)
                coordinate_map.merge_window_results(results)

    try:
        process_raster(grid, aux, partial(_warp_kernel, job), writer_or_output,
                       tile_size=tile_size, halo=aux_halo, executor=executor,
                       feedback=feedback, collect=collect, start=start, end=end)
    finally:
        job.datasets.close()
    return total


def warp_to_geotiff(source: Any, coordinate_map: Any, grid: Any, output: Any,
                    resampling: str = "bilinear", outside: str = "alpha",
                    nodata: float | None = None, chunk: int = DEFAULT_CHUNK,
                    max_source_pixels: int = DEFAULT_MAX_SOURCE_PIXELS, overviews: bool = True,
                    feedback: Any = None, cache_mb: int = DEFAULT_CACHE_MB,
                    tags: dict[str, str] | None = None,
                    creation_options: dict[str, Any] | None = None,
                    fast: bool = True, cog: bool = False, executor: Any = None,
                    aux: dict | None = None, memory_mb: float = WARP_MEMORY_MB) -> Any:
    """Warp a raster file onto ``grid`` through ``coordinate_map`` into a GeoTIFF: a
    :class:`~toolbox.raster.writer.RasterWriter` fed by
    :func:`warp_raster`.

    Parameters
    ----------
    source : path
        Any raster GDAL reads (GeoTIFF, JPEG, PNG...), 1 or more bands of one data type.
    coordinate_map : CoordinateMap
        Output tile -> source coordinates (e.g. :class:`~toolbox.raster.homography.HomographyMap`).
    grid : toolbox.io.grid.GridSpec
        Output grid (transform, width, height, crs; crs None for a local object system).
    output : path
        GeoTIFF to write (inside an algorithm: the staged path).
    resampling : {"nearest", "bilinear", "cubic", "lanczos", "quadratic"}
    outside : {"alpha", "nodata"}
        How pixels outside the photo are marked (see :func:`output_layout`).
    nodata : float, optional
        Output nodata with ``outside="nodata"``.
    chunk : int
        Output tile side in pixels (a multiple of the 512-pixel block keeps writes aligned).
    max_source_pixels : int
        Largest source window read at once (per band); bigger ones are split.
    overviews, cog : bool
        Internal overviews; a Cloud Optimized GeoTIFF.
    feedback : toolbox.feedback.Feedback, optional
        Progress (0-95 % for the tiles) and cancellation between tiles.
    cache_mb : int
        GDAL block cache size while warping, MB (bounds memory on huge sources).
    tags : dict, optional
        Metadata written to the output (e.g. the homography).
    creation_options : dict, optional
        More GeoTIFF creation options.
    fast : bool
        Let maps that offer it use ``cv2.warpPerspective`` (see :func:`warp_window`); False
        forces the generic coordinate-array + ``cv2.remap`` path.
    executor : toolbox.executor.Executor, optional
        Where tiles run (default: local threads); local threads also set GDAL's compression
        threads of an output gathered in memory (the writer's ``threads``: one when the tiles
        run on the caller's thread).
    aux : dict name -> RasterInput, optional
        Auxiliary rasters for the coordinate map.
    memory_mb : float
        An output up to this size (uncompressed) is gathered in memory, its overviews built
        there and copied once into the GeoTIFF (:class:`~toolbox.raster.writer.RasterWriter`'s
        ``memory_mb``); 0: streamed.
    """
    from toolbox.raster.writer import RasterWriter

    if resampling not in RESAMPLING_METHODS + EXTRA_RESAMPLING:
        raise ValueError(f"resampling must be one of "
                         f"{', '.join(RESAMPLING_METHODS + EXTRA_RESAMPLING)}, "
                         f"got {resampling!r}")
    from toolbox.raster.writer import copy_band_names

    threads = executor.workers if executor is not None and executor.kind == "local" else None
    path, src = open_photo(source)
    datasets = ThreadDatasets()  # the tiles' reads, on this thread by this very dataset
    datasets.adopt(path, src)
    try:
        layout = output_layout(src, outside, nodata)
        writer = RasterWriter(output, grid, layout.count, layout.dtype, layout.nodata,
                              alpha=layout.alpha, cog=cog, overviews=overviews, tags=tags,
                              creation_options=creation_options, cache_mb=cache_mb,
                              memory_mb=memory_mb, threads=threads)
        with writer:
            copy_band_names(src, writer.dataset, layout.data_bands)
            return _warp_read_path(path, (src.width, src.height), grid, coordinate_map, writer,
                                   layout=layout, resampling=resampling, aux=aux, aux_halo=0,
                                   tile_size=chunk, executor=executor, feedback=feedback,
                                   max_source_pixels=max_source_pixels, fast=fast, start=0.0,
                                   end=95 if overviews else 100, datasets=datasets)
    finally:
        datasets.close()
