"""Indirect warping kernels: output tile -> source coordinates -> ``cv2.remap``.

This is the resampling machinery of every output-to-source geometric correction, run tile by
tile by :func:`toolbox.raster.engine.warp_raster`: the caller gives a **coordinate map**, a
callable ``map(tile, aux_arrays) -> (src_col, src_row)`` returning, for the cell centres of one
output tile, the source image coordinates to sample (``aux_arrays``: auxiliary rasters read onto
the tile, e.g. the DEM of an orthophoto). Rectification uses :class:`HomographyMap`. For each
tile :func:`warp_window`

1. asks the map for the source coordinates (vectorised, float32),
2. reads only the source window they cover plus the interpolation margin (rasterio windowed
   read),
3. resamples with OpenCV ``cv2.remap`` (nearest / bilinear / cubic / lanczos), with an alpha
   band or nodata outside the photo,

and the engine writes the tile with :class:`toolbox.raster.writer.RasterWriter`, so memory is
bounded by the tile size, whatever the size of the photo or of the output.

**Source pixel convention.** Source coordinates are continuous ``(col, row)``: the origin is the
top-left *corner* of the top-left pixel, columns grow right, rows grow *down*, pixel
``(row i, col j)`` covers ``[j, j+1) x [i, i+1)`` and its centre is ``(j + 0.5, i + 0.5)``
(GDAL's pixel/line convention). OpenCV samples pixel centres at integers, so the map given to
``cv2.remap`` is ``coordinate - 0.5 - window offset``. An output pixel is *inside* the photo when
its centre maps into ``[0, width] x [0, height]``.

Output pixel centres follow :mod:`toolbox.io.grid`: column ``j`` of a north-up grid has centre
``x = xmin + (j + 0.5)·cell``.
"""

from __future__ import annotations

import math
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from toolbox.errors import ParameterError

RESAMPLING_METHODS = ("nearest", "bilinear", "cubic", "lanczos")
# not OpenCV's: :mod:`toolbox.raster.quadratic` (the thesis' quadratic, for orthophotos)
EXTRA_RESAMPLING = ("quadratic",)
# source pixels needed beyond the bounding box of the sample points, per method (kernel radius)
RESAMPLING_MARGIN = {"nearest": 1, "bilinear": 1, "cubic": 2, "lanczos": 4, "quadratic": 2}
DEFAULT_CHUNK = 2048  # output pixels per side of a processing window (a multiple of the block)
DEFAULT_MAX_SOURCE_PIXELS = 1 << 24  # larger source windows are split (16 Mpx per band)
DEFAULT_CACHE_MB = 256  # GDAL block cache while warping (bounded, unlike GDAL's 5 % of RAM)
_CV2_DTYPES = ("uint8", "uint16", "int16", "float32", "float64")


_OPENCV_LOCK = threading.Lock()
_OPENCV_USERS = [0, 0]  # blocks inside single_threaded_opencv, OpenCV's setting before them


@contextmanager
def single_threaded_opencv() -> Iterator[None]:
    """Run OpenCV single-threaded inside the block: warps whose tiles already run on one
    thread per core (the raster engine's) would otherwise put OpenCV's own pool to work on top
    of them, more threads than cores. OpenCV's setting is process-wide: blocks may overlap
    (photos of a block on threads), and the setting before the first comes back after the
    last."""
    import cv2

    with _OPENCV_LOCK:
        if _OPENCV_USERS[0] == 0:
            _OPENCV_USERS[1] = cv2.getNumThreads()
            cv2.setNumThreads(1)
        _OPENCV_USERS[0] += 1
    try:
        yield
    finally:
        with _OPENCV_LOCK:
            _OPENCV_USERS[0] -= 1
            if _OPENCV_USERS[0] == 0:
                cv2.setNumThreads(_OPENCV_USERS[1])


def cv2_interpolation(resampling: str) -> int:
    """The OpenCV interpolation flag of a resampling name (see :data:`RESAMPLING_METHODS`)."""
    import cv2

    flags = {"nearest": cv2.INTER_NEAREST, "bilinear": cv2.INTER_LINEAR,
             "cubic": cv2.INTER_CUBIC, "lanczos": cv2.INTER_LANCZOS4}
    if resampling not in flags:
        raise ValueError(f"resampling must be one of {', '.join(RESAMPLING_METHODS)}, "
                         f"got {resampling!r}")
    return flags[resampling]


class CoordinateMap(Protocol):
    """Output tile -> source coordinates of its cell centres.

    ``__call__(tile, aux)`` returns ``(cols, rows)``: float32 arrays of the tile's shape without
    halo, ``tile.shape``, in the source pixel convention (module docstring), NaN where the
    output pixel has no source point. ``tile`` is a :class:`toolbox.raster.engine.Tile`
    (``tile.window`` on the output grid, ``tile.cell_centres()``); ``aux`` maps names to the
    auxiliary rasters read onto the tile with its halo, (bands, h + 2·halo, w + 2·halo).
    An implementation may also define
    ``source_bounds(window) -> (col_min, row_min, col_max, row_max) | None``: the exact bounding
    box of the finite coordinates (None when it cannot tell cheaply); the driver then skips
    scanning the arrays and, when the box lies inside the photo, the inside test. Two more
    optional methods give a fast path for maps OpenCV can evaluate itself:
    ``inside(window, width, height) -> bool (h, w)`` (the exact inside test without the
    coordinate arrays) and ``perspective_matrix(window, col_shift, row_shift) -> (3, 3)`` (the
    map as a homography for ``cv2.warpPerspective`` with ``WARP_INVERSE_MAP``).
    """

    def __call__(self, tile: Any, aux: dict) -> tuple[np.ndarray, np.ndarray]: ...


def _window_parts(window: Any) -> tuple[int, int, int, int]:
    window = getattr(window, "window", window)  # a Tile or a Window
    return int(window.col_off), int(window.row_off), int(window.width), int(window.height)


class HomographyMap:
    """Coordinate map of a plane-to-plane homography onto a north-up output grid.

    Parameters
    ----------
    ground_to_pixel : (3, 3) array
        Homography from output map coordinates (X, Y) to source pixel coordinates (col, row,
        source pixel convention): ``[col·w, row·w, w]^T = H @ [X, Y, 1]^T``.
    output_transform : affine.Affine
        The output grid's transform (pixel corner -> map), as in :class:`toolbox.io.grid.GridSpec`.
    front : (X, Y), optional
        A ground point known to be seen by the photo (e.g. the image centre's ground point).
        Output points on the other side of the plane's vanishing line (``w`` of the opposite
        sign: behind the camera) get NaN. Default: no such test.

    Notes
    -----
    The matrix is composed with the output grid once (output pixel index -> source pixel), so
    each window costs three broadcast additions and two divisions in float32; coordinates stay
    small (pixels), so float32 keeps them to about 1e-3 pixel.
    """

    def __init__(self, ground_to_pixel: np.ndarray, output_transform: Any,
                 front: tuple[float, float] | None = None):
        t = output_transform
        grid = np.array([[t.a, t.b, t.c + 0.5 * (t.a + t.b)],
                         [t.d, t.e, t.f + 0.5 * (t.d + t.e)], [0.0, 0.0, 1.0]])
        matrix = np.asarray(ground_to_pixel, dtype="float64") @ grid
        if front is not None:
            wf = ground_to_pixel[2, 0] * front[0] + ground_to_pixel[2, 1] * front[1] \
                + ground_to_pixel[2, 2]
            if wf < 0:
                matrix = -matrix
        self.check_sign = front is not None
        self.matrix = matrix / np.abs(matrix).max()

    def _terms(self, window: Any):
        col0, row0, width, height = _window_parts(window)
        j = np.arange(col0, col0 + width, dtype="float64")
        i = np.arange(row0, row0 + height, dtype="float64")
        m = self.matrix
        return [((m[k, 0] * j).astype("float32")[None, :],
                 (m[k, 1] * i + m[k, 2]).astype("float32")[:, None]) for k in range(3)]

    def corner_coordinates(self, window: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Source (cols, rows) and ``w`` of the window's four corner pixel centres (float64)."""
        col0, row0, width, height = _window_parts(window)
        j = np.array([col0, col0 + width - 1, col0 + width - 1, col0], dtype="float64")
        i = np.array([row0, row0, row0 + height - 1, row0 + height - 1], dtype="float64")
        p = self.matrix @ np.vstack([j, i, np.ones(4)])
        with np.errstate(divide="ignore", invalid="ignore"):
            return p[0] / p[2], p[1] / p[2], p[2]

    def source_bounds(self, window: Any) -> tuple[float, float, float, float] | None:
        """Exact bounding box of the window's sample points when ``w > 0`` over the whole window
        (a homography then maps the window's convex hull onto the convex hull of the corners'
        images); None when ``w`` changes sign or sign checks are off."""
        cols, rows, w = self.corner_coordinates(window)
        if np.all(w > 0) or (not self.check_sign and np.all(w < 0)):
            return float(cols.min()), float(rows.min()), float(cols.max()), float(rows.max())
        return None

    def perspective_matrix(self, window: Any, col_shift: float = 0.0,
                           row_shift: float = 0.0) -> np.ndarray:
        """The map of ``window`` for ``cv2.warpPerspective(..., WARP_INVERSE_MAP)``: window pixel
        index (x, y) -> OpenCV source coordinates ``(col - col_shift, row - row_shift)``."""
        col0, row0, _, _ = _window_parts(window)
        shift = np.array([[1.0, 0.0, -col_shift], [0.0, 1.0, -row_shift], [0.0, 0.0, 1.0]])
        offset = np.array([[1.0, 0.0, col0], [0.0, 1.0, row0], [0.0, 0.0, 1.0]])
        return shift @ self.matrix @ offset

    def inside_intervals(self, window: Any, width: int,
                         height: int) -> tuple[np.ndarray, np.ndarray]:
        """Exact inside test of the window's pixel centres as column intervals per row.

        Returns ``(start, stop)`` int arrays (one per window row, window-local columns,
        half-open ``[start, stop)``; ``start >= stop`` for an empty row). Inside means
        ``0 <= col <= width`` and ``0 <= row <= height`` (and in front of the camera when
        ``front`` was given). ``u = col·w``, ``v = row·w`` and ``w`` are affine in the output
        column, so along a row each condition (``u >= 0``, ``width·w - u >= 0``, ...) holds on an
        interval of columns; no coordinate array is needed.
        """
        col0, row0, out_w, out_h = _window_parts(window)
        i = np.arange(row0, row0 + out_h, dtype="float64")
        m = self.matrix
        u0, v0, w0 = (m[k, 1] * i + m[k, 2] for k in range(3))
        du, dv, dw = m[0, 0], m[1, 0], m[2, 0]
        if not self.check_sign:  # no front: the sign of w at the window centre is "in front"
            centre = m[2, 0] * (col0 + out_w / 2) + m[2, 1] * (row0 + out_h / 2) + m[2, 2]
            if centre < 0:
                u0, v0, w0, du, dv, dw = -u0, -v0, -w0, -du, -dv, -dw
        lo = np.full(out_h, float(col0))
        hi = np.full(out_h, float(col0 + out_w - 1))
        conditions = ((w0, dw), (u0, du), (width * w0 - u0, width * dw - du), (v0, dv),
                      (height * w0 - v0, height * dw - dv))
        with np.errstate(divide="ignore", invalid="ignore"):
            for alpha, beta in conditions:  # alpha + beta·j >= 0
                if beta > 0:
                    lo = np.maximum(lo, np.ceil(-alpha / beta))
                elif beta < 0:
                    hi = np.minimum(hi, np.floor(-alpha / beta))
                else:
                    hi = np.where(alpha >= 0, hi, -np.inf)
        start = np.clip(lo - col0, 0, out_w).astype(np.int64)
        stop = np.clip(hi - col0 + 1, 0, out_w).astype(np.int64)
        return start, np.maximum(stop, start)

    def inside(self, window: Any, width: int, height: int) -> np.ndarray:
        """The :meth:`inside_intervals` test as a bool (h, w) mask."""
        return mask_from_intervals(*self.inside_intervals(window, width, height),
                                   int(window.width))

    def __call__(self, window: Any, aux: dict | None = None, col_shift: float = 0.0,
                 row_shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Source (cols - col_shift, rows - row_shift), float32 (h, w); NaN behind the camera.
        ``window`` is a Tile or a Window; ``aux`` is not used (a plane needs no DEM)."""
        (ua, ub), (va, vb), (wa, wb) = self._terms(window)
        w = wa + wb
        u = ua + ub
        v = va + vb
        if col_shift:
            u -= np.float32(col_shift) * w
        if row_shift:
            v -= np.float32(row_shift) * w
        np.divide(u, w, out=u)
        np.divide(v, w, out=v)
        if self.check_sign:
            _, _, wc = self.corner_coordinates(window)
            if not np.all(wc > 0):
                behind = w <= 0
                u[behind] = np.nan
                v[behind] = np.nan
        return u, v


#: map value of the cells a planned map leaves empty (see :class:`SourcePlan`): far outside any
#: source window, so that ``cv2.remap`` gives its border value there (NaN does not: OpenCV 5's
#: bilinear path samples pixel 0 for a NaN coordinate)
OUTSIDE = np.float32(-1e5)


@dataclass(frozen=True)
class SourcePlan:
    """The source window of an output window decided *before* its coordinates are computed,
    from a conservative bound of them (a coordinate map offering ``source_plan(window)``, e.g.
    the orthophoto's). Its maps then come ready for OpenCV: relative to the padded source
    buffer (``coordinate - shift``) and :data:`OUTSIDE` on every cell whose centre is outside
    the photo or has no source point, so the warp needs no pass of its own over them."""

    window: Any  # rasterio Window of the source pixels to read
    pads: tuple[int, int, int, int]  # edge replication (top, bottom, left, right), pixels
    shift_col: float  # source column of OpenCV map column 0 (window offset - pad + 0.5)
    shift_row: float


#: the plan of a window whose image misses the source: every cell gets the fill
EMPTY_PLAN = SourcePlan(None, (0, 0, 0, 0), 0.0, 0.0)


def plan_source(bounds: tuple[float, float, float, float] | None, width: int, height: int,
                resampling: str) -> SourcePlan | None:
    """The :class:`SourcePlan` of sample points inside ``bounds`` (source pixel convention) in a
    ``width`` x ``height`` source: :func:`source_window` with the method's margin, padded by
    replicating the photo's edge where the window touches it (the kernel of a sample just
    inside the photo needs pixels beyond it); None when it does not overlap the source."""
    window = source_window(bounds, width, height, RESAMPLING_MARGIN[resampling])
    if window is None:
        return None
    pad = RESAMPLING_MARGIN[resampling] + 1
    pads = (pad if window.row_off == 0 else 0,
            pad if window.row_off + window.height == height else 0,
            pad if window.col_off == 0 else 0,
            pad if window.col_off + window.width == width else 0)
    return SourcePlan(window, pads, window.col_off - pads[2] + 0.5,
                      window.row_off - pads[0] + 0.5)


def source_window(bounds: tuple[float, float, float, float] | None, width: int, height: int,
                  margin: int) -> Any:
    """The source window covering ``bounds`` (col_min, row_min, col_max, row_max, source pixel
    convention) plus ``margin`` pixels, clipped to the ``width`` x ``height`` source; None when
    it does not overlap the source.

    A sample at coordinate ``c`` uses the pixels around ``c - 0.5``; ``margin`` pixels on each
    side cover the interpolation kernel.
    """
    from rasterio.windows import Window

    if bounds is None:
        return None
    cmin, rmin, cmax, rmax = bounds
    if not all(math.isfinite(v) for v in bounds):
        return None
    c0 = max(int(math.floor(cmin - 0.5)) - margin, 0)
    r0 = max(int(math.floor(rmin - 0.5)) - margin, 0)
    c1 = min(int(math.ceil(cmax - 0.5)) + margin + 1, width)
    r1 = min(int(math.ceil(rmax - 0.5)) + margin + 1, height)
    if c1 <= c0 or r1 <= r0:
        return None
    return Window(c0, r0, c1 - c0, r1 - r0)


def mask_from_intervals(start: np.ndarray, stop: np.ndarray, width: int) -> np.ndarray:
    """Bool (len(start), width) mask true on ``[start[r], stop[r])`` of each row ``r``."""
    mask = np.zeros((len(start), width), dtype=bool)
    for r, (a, b) in enumerate(zip(start.tolist(), stop.tolist(), strict=True)):
        if b > a:
            mask[r, a:b] = True
    return mask


def fill_outside_intervals(out: np.ndarray, start: np.ndarray, stop: np.ndarray,
                           value: float) -> None:
    """Set ``out[..., r, c]`` to ``value`` outside ``[start[r], stop[r])`` (in place)."""
    width = out.shape[-1]
    for r, (a, b) in enumerate(zip(start.tolist(), stop.tolist(), strict=True)):
        if a > 0:
            out[..., r, :a] = value
        if b < width:
            out[..., r, max(b, a):] = value


def scan_bounds(cols: np.ndarray, rows: np.ndarray) -> tuple[float, float, float, float] | None:
    """Bounding box of the finite coordinates (None when there are none)."""
    finite = np.isfinite(cols) & np.isfinite(rows)
    if not finite.any():
        return None
    c, r = cols[finite], rows[finite]
    return float(c.min()), float(r.min()), float(c.max()), float(r.max())


def inside_mask(cols: np.ndarray, rows: np.ndarray, width: int, height: int,
                col_shift: float = 0.0, row_shift: float = 0.0) -> np.ndarray:
    """Output pixels whose centre maps into the photo ``[0, width] x [0, height]`` (NaN: no).

    ``cols``/``rows`` may be given shifted (``cols - col_shift``...), as the cv2 maps are.
    """
    inside = cols >= np.float32(-col_shift)
    inside &= cols <= np.float32(width - col_shift)
    inside &= rows >= np.float32(-row_shift)
    inside &= rows <= np.float32(height - row_shift)
    return inside


def remap(source: np.ndarray, map_x: np.ndarray, map_y: np.ndarray,
          resampling: str = "bilinear", border: float = 0) -> np.ndarray:
    """Sample ``source`` at OpenCV map coordinates (pixel centres at integers).

    ``source`` is (rows, cols) or (rows, cols, bands) of any numeric dtype (OpenCV handles
    uint8, uint16, int16, float32 and float64 directly; other types go through float64 and are
    rounded back). Any number of bands (OpenCV takes at most 4 at a time). Outside the source
    the value is ``border`` (``cv2.BORDER_CONSTANT``, which OpenCV skips quickly); callers that
    need the photo's edge pixels extended pad the source first (see
    :func:`pad_at_photo_edges`).
    """
    import cv2

    if resampling == "quadratic":
        from toolbox.raster.quadratic import remap_quadratic

        return remap_quadratic(source, map_x, map_y)
    flag = cv2_interpolation(resampling)
    value = (float(border),) * 4
    return _by_four_bands(source, lambda part: cv2.remap(part, map_x, map_y, flag,
                                                         borderMode=cv2.BORDER_CONSTANT,
                                                         borderValue=value))


def _by_four_bands(source: np.ndarray, warp_one) -> np.ndarray:
    """``warp_one`` (an OpenCV warp of a (rows, cols[, <= 4 bands]) array) applied to
    ``source`` of any dtype and band count: types OpenCV lacks go through float64 and are rounded
    back, bands go 4 at a time, and the trailing band axis OpenCV drops is restored."""
    dtype = source.dtype
    work = source if dtype.name in _CV2_DTYPES else source.astype("float64")

    def one(part: np.ndarray) -> np.ndarray:
        res = warp_one(part)
        return res[:, :, None] if part.ndim == 3 and res.ndim == 2 else res

    if work.ndim == 2 or work.shape[2] <= 4:
        out = one(work)
    else:
        out = np.concatenate([one(np.ascontiguousarray(work[:, :, k:k + 4]))
                              for k in range(0, work.shape[2], 4)], axis=2)
    if out.dtype != dtype:
        if dtype.kind in "iu":
            info = np.iinfo(dtype)
            out = np.clip(np.rint(out), info.min, info.max)
        out = out.astype(dtype)
    return out


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


def warp_layout(source: Any, outside: str = "alpha", nodata: float | None = None) -> OutputLayout:
    """:func:`output_layout` of a raster path (or RasterInfo)."""
    import rasterio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(getattr(source, "path", source)) as src:
            return output_layout(src, outside, nodata)


def output_layout(src: Any, outside: str = "alpha", nodata: float | None = None) -> OutputLayout:
    """Decide the output bands of a warp of the open rasterio dataset ``src``.

    ``outside = "alpha"`` adds an alpha band (0 outside the photo, the dtype's maximum inside);
    ``"nodata"`` fills outside pixels with ``nodata`` (default: the source nodata, else 0 for
    integers and NaN for floats). A source alpha band is resampled and always kept as alpha.
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
    alpha = outside == "alpha" or source_alpha is not None
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


def photometric_options(layout: OutputLayout) -> dict[str, str]:
    """GeoTIFF creation options declaring RGB photometry and the alpha band."""
    options: dict[str, str] = {}
    if len(layout.data_bands) == 3 and np.dtype(layout.dtype).kind in "iu":
        options["photometric"] = "RGB"
    if layout.alpha:
        options["alpha"] = "YES"
    return options


@dataclass
class WarpStatistics:
    """Counters of one warp run."""

    windows: int = 0
    empty_windows: int = 0
    split_windows: int = 0
    source_pixels_read: int = 0
    output_pixels: int = 0
    timings: dict[str, float] = field(default_factory=dict)

    def add(self, other: WarpStatistics) -> None:
        for name in ("windows", "empty_windows", "split_windows", "source_pixels_read",
                     "output_pixels"):
            setattr(self, name, getattr(self, name) + getattr(other, name))

    def as_dict(self) -> dict:
        return {"windows": self.windows, "empty_windows": self.empty_windows,
                "split_windows": self.split_windows,
                "source_pixels_read": self.source_pixels_read,
                "output_pixels": self.output_pixels}


def _split(window: Any) -> list[Any]:
    from rasterio.windows import Window

    col0, row0, width, height = _window_parts(window)
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

    ``tile`` is a :class:`toolbox.raster.engine.Tile` (or a bare Window: a tile without halo);
    ``aux`` the auxiliary arrays read onto it, handed to ``coordinate_map(tile, aux)``.

    ``read(bands, source_window)`` returns the source pixels (len(bands), h, w); ``read_mask``
    the source validity (h, w) uint8 0/255 (sources with nodata or an internal mask). Windows
    whose source window exceeds ``max_source_pixels`` are split in four, recursively. With
    ``fast`` and a map offering ``perspective_matrix`` and ``inside`` (a homography), OpenCV's
    ``warpPerspective`` evaluates the map itself (same sampling as ``remap`` with the map's
    coordinates, without the coordinate arrays); a map offering ``source_plan(window)`` (the
    orthophoto's) decides the source window first and hands ready OpenCV maps (see
    :class:`SourcePlan`); otherwise the coordinates are computed and ``cv2.remap`` samples
    them. On the first two paths, for a source without alpha band or mask and 1, 3 or 4 output
    bands, the bands travel pixel-interleaved from the read to the writer
    (:func:`_warp_packed`), and cells outside the photo are filled by OpenCV's border value.
    """
    from toolbox.raster.tile import Tile

    if not isinstance(tile, Tile):
        tile = Tile(0, tile, 0, None)
    aux = aux or {}
    window = tile.window
    stats = stats if stats is not None else WarpStatistics()
    width, height = source_size
    col0, row0, out_w, out_h = _window_parts(window)
    planner = getattr(coordinate_map, "source_plan", None)
    plan = planner(window) if planner is not None else None
    planned = plan is not None
    bounds = cols = rows = None
    exact_bounds = False
    if not planned:
        bounds_method = getattr(coordinate_map, "source_bounds", None)
        bounds = bounds_method(window) if bounds_method is not None else None
        exact_bounds = bounds is not None
        if bounds is None:
            cols, rows = coordinate_map(tile, aux)
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
    use_fast = (fast and not planned and cols is None and resampling in RESAMPLING_METHODS
                and hasattr(coordinate_map, "perspective_matrix")
                and hasattr(coordinate_map, "inside_intervals"))
    intervals = None
    inside = None
    if use_fast:
        matrix = coordinate_map.perspective_matrix(window, shift_c, shift_r)
        if not all_inside:
            intervals = coordinate_map.inside_intervals(window, width, height)

        def sample(pixels: np.ndarray, method: str, border: float = 0) -> np.ndarray:
            return warp_perspective(pixels, matrix, (out_w, out_h), method, border)
    else:
        if planned:  # ready OpenCV maps, OUTSIDE where the centre is outside the photo
            map_x, map_y = coordinate_map(tile, aux)
        elif cols is None and isinstance(coordinate_map, HomographyMap):
            map_x, map_y = coordinate_map(window, None, shift_c, shift_r)
        else:
            if cols is None:
                cols, rows = coordinate_map(tile, aux)
            map_x = (cols - np.float32(shift_c)).astype("float32", copy=False)
            map_y = (rows - np.float32(shift_r)).astype("float32", copy=False)

        def sample(pixels: np.ndarray, method: str, border: float = 0) -> np.ndarray:
            return remap(pixels, map_x, map_y, method, border)
    n_data = len(layout.data_bands)
    packed = (use_fast or planned) and layout.source_alpha is None \
        and not layout.source_masked and layout.count in (1, 3, 4) \
        and np.dtype(layout.dtype).name in _CV2_DTYPES
    # (not 2 bands: OpenCV's 2-channel warpPerspective samples differently, up to 6 grey
    # levels from its 1-, 3- and 4-channel ones)
    if packed:
        yield window, _warp_packed(read(layout.data_bands, src_win), pads, layout,
                                   lambda buf: sample(buf, resampling, layout.fill), intervals)
        return
    if planned:
        inside = map_x != OUTSIDE
    elif not all_inside and not use_fast:
        inside = inside_mask(map_x, map_y, width, height, shift_c, shift_r)
    sampled = sample(pad_at_photo_edges(_interleave(read(layout.data_bands, src_win)), pads),
                     resampling)
    _deinterleave(sampled, out[:n_data])
    del sampled
    # validity from the source itself (alpha band, nodata or internal mask)
    alpha = None
    source_valid = None
    if layout.source_alpha is not None:
        alpha = sample(pad_at_photo_edges(read([layout.source_alpha], src_win)[0], pads),
                       resampling)
        if not layout.alpha:
            source_valid = alpha >= layout.alpha_max / 2
    elif layout.source_masked and read_mask is not None:
        mask = sample(pad_at_photo_edges(read_mask(src_win), pads),
                      "nearest" if resampling == "nearest" else "bilinear")
        source_valid = mask >= 255
    if source_valid is not None and intervals is not None:
        inside = mask_from_intervals(*intervals, out_w)
        intervals = None
    valid = inside if source_valid is None else (
        source_valid if inside is None else inside & source_valid)
    if layout.alpha:
        out[-1] = layout.alpha_max if alpha is None else alpha
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


def _warp_packed(data: np.ndarray, pads: tuple[int, int, int, int], layout: OutputLayout,
                 sample: Callable[[np.ndarray], np.ndarray], intervals) -> np.ndarray:
    """The packed path of :func:`warp_window` for a source without alpha band or mask: the
    source bands ``data`` (bands, h, w) are merged pixel-interleaved into a buffer that has the
    edge pads of :func:`pad_at_photo_edges` (filled by replicating the edge rows and columns,
    without copying the window again) and, for an alpha output, an opaque alpha channel; one
    OpenCV call ``sample(buffer)`` resamples every band (alpha stays opaque inside the photo,
    and is the border value 0 outside it). Cells outside the photo get ``layout.fill`` and
    alpha 0: from OpenCV's border (a planned map) or row by row from ``intervals`` (a
    homography). With an alpha band ``fill`` is 0. Returns a (count, h, w) view of the (h, w,
    count) result: GDAL writes pixel-interleaved GeoTIFFs from it without a layout conversion."""
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
    return out


def pad_at_photo_edges(pixels: np.ndarray, pads: tuple[int, int, int, int]) -> np.ndarray:
    """Replicate the edge pixels of ``pixels`` ((h, w) or (h, w, bands)) outwards by ``pads`` =
    (top, bottom, left, right) pixels; unchanged when every pad is 0."""
    import cv2

    if not any(pads):
        return pixels
    top, bottom, left, right = pads
    if pixels.dtype.name in _CV2_DTYPES + ("int8", "int32"):
        return cv2.copyMakeBorder(pixels, top, bottom, left, right, cv2.BORDER_REPLICATE)
    widths = ((top, bottom), (left, right)) + (((0, 0),) if pixels.ndim == 3 else ())
    return np.pad(pixels, widths, mode="edge")


def _interleave(data: np.ndarray) -> np.ndarray:
    """(bands, h, w) -> (h, w) or pixel-interleaved (h, w, bands) for OpenCV."""
    import cv2

    if data.shape[0] == 1:
        return data[0]
    if data.shape[0] <= 4 and data.dtype.name in _CV2_DTYPES:
        return cv2.merge(list(data))
    return np.ascontiguousarray(np.moveaxis(data, 0, -1))


def _deinterleave(sampled: np.ndarray, out: np.ndarray) -> None:
    """Copy (h, w) or (h, w, bands) ``sampled`` into band-sequential ``out`` (bands, h, w)."""
    import cv2

    if sampled.ndim == 2:
        out[0] = sampled
    elif sampled.shape[2] <= 4 and sampled.dtype.name in _CV2_DTYPES and out.flags.c_contiguous:
        cv2.split(sampled, list(out))
    else:
        for k in range(sampled.shape[2]):
            out[k] = sampled[:, :, k]


def warp_perspective(source: np.ndarray, matrix: np.ndarray, size: tuple[int, int],
                     resampling: str = "bilinear", border: float = 0) -> np.ndarray:
    """``cv2.warpPerspective`` with ``WARP_INVERSE_MAP`` (``matrix``: output pixel index ->
    OpenCV source coordinates), ``border`` outside the source, any dtype and band count (as
    :func:`remap`). ``size`` is (width, height) of the output."""
    import cv2

    flag = cv2_interpolation(resampling) | cv2.WARP_INVERSE_MAP
    value = (float(border),) * 4
    return _by_four_bands(source, lambda part: cv2.warpPerspective(
        part, matrix, size, flags=flag, borderMode=cv2.BORDER_CONSTANT, borderValue=value))
