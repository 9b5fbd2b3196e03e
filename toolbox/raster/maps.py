"""Coordinate maps: what the warp asks of a map from output cells to source pixels, declared as
protocols, and the source window a map's points need.

**Source pixel convention.** Source coordinates are continuous ``(col, row)``: the origin is the
top-left *corner* of the top-left pixel, columns grow right, rows grow *down*, pixel
``(row i, col j)`` covers ``[j, j+1) x [i, i+1)`` and its centre is ``(j + 0.5, i + 0.5)``
(GDAL's pixel/line convention). OpenCV samples pixel centres at integers, so the map given to
``cv2.remap`` is ``coordinate - 0.5 - window offset``. An output pixel is *inside* the source
when its centre maps into ``[0, width] x [0, height]``.

A map is a :class:`CoordinateMap`; it may also be (checked with ``isinstance``, one capability
per protocol, no attribute probing):

- :class:`BoundedMap`: tells the exact bounding box of a window's points before computing them;
- :class:`PerspectiveMap`: a homography OpenCV evaluates itself (``cv2.warpPerspective``);
- :class:`MeasuredMap`: computes its points and their bounding box in one pass;
- :class:`PlannedMap`: decides the source window first (:class:`SourcePlan`, from a bound of
  the points) and then writes maps ready for OpenCV, :data:`OUTSIDE` on empty cells;
- :class:`ReportingMap`: keeps results per window (statistics, auxiliary rasters) that travel
  back with each tile's result to the caller's map (:class:`WindowResults` implements it), so
  a run on Dask worker processes reports what a local run does.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from toolbox.raster.resample import RESAMPLING_MARGIN

Bounds = tuple[float, float, float, float]  # (col_min, row_min, col_max, row_max), source pixels


@runtime_checkable
class CoordinateMap(Protocol):
    """Output tile -> source coordinates of its cell centres.

    ``map(tile, aux)`` returns ``(cols, rows)``: float32 arrays of the tile's shape without
    halo, in the source pixel convention, NaN where the output pixel has no source point.
    ``tile`` is a :class:`toolbox.raster.tile.Tile` (``tile.window`` on the output grid,
    ``tile.cell_centres()``); ``aux`` maps names to the auxiliary rasters read onto the tile
    with its halo, (bands, h + 2·halo, w + 2·halo).
    """

    def __call__(self, tile: Any, aux: dict) -> tuple[np.ndarray, np.ndarray]: ...


@runtime_checkable
class BoundedMap(CoordinateMap, Protocol):
    """A map that knows, cheaply and before computing them, the exact bounding box of a
    window's points (None when it cannot tell): the warp then skips its scan and, when the box
    lies inside the source, the inside test."""

    def source_bounds(self, window: Any) -> Bounds | None: ...


@runtime_checkable
class PerspectiveMap(BoundedMap, Protocol):
    """A homography: OpenCV's ``warpPerspective`` evaluates it without coordinate arrays.
    ``perspective_matrix(window, col_shift, row_shift)`` maps window pixel indexes to OpenCV
    source coordinates; ``inside_intervals(window, width, height)`` is the exact inside test
    as column intervals per row; the call takes the shift too."""

    def __call__(self, tile: Any, aux: dict | None = None, col_shift: float = 0.0,
                 row_shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]: ...

    def perspective_matrix(self, window: Any, col_shift: float = 0.0,
                           row_shift: float = 0.0) -> np.ndarray: ...

    def inside_intervals(self, window: Any, width: int,
                         height: int) -> tuple[np.ndarray, np.ndarray]: ...


@runtime_checkable
class MeasuredMap(CoordinateMap, Protocol):
    """A map that computes a window's points and their bounding box in one pass:
    ``measured(tile, aux) -> (cols, rows, bounds)``, ``bounds`` the exact box when every cell
    has a point, else None (the warp then scans)."""

    def measured(self, tile: Any, aux: dict) -> tuple[np.ndarray, np.ndarray, Bounds | None]: ...


@runtime_checkable
class PlannedMap(CoordinateMap, Protocol):
    """A map that decides a window's source window before computing its points:
    ``plan(tile, aux)`` gives the :class:`SourcePlan` (None: not plannable, the warp takes the
    map's other capabilities), ``planned_maps(plan)`` then the maps ready for OpenCV (relative
    to the plan's shift, :data:`OUTSIDE` on the cells outside the source or without a point),
    valid until the calling thread's next window."""

    def plan(self, tile: Any, aux: dict) -> SourcePlan | None: ...

    def planned_maps(self, plan: SourcePlan) -> tuple[np.ndarray, np.ndarray]: ...


@runtime_checkable
class ReportingMap(CoordinateMap, Protocol):
    """A map that keeps results per window for its caller. The warp takes a tile's results
    from the map where the tile ran, ``take_window_results(window)`` (a picklable value, or
    None; on a local thread or on a Dask worker, whose map is an unpickled copy), and hands
    them to the caller's map, ``merge_window_results(results)``, in the caller's process and
    in tile order."""

    def take_window_results(self, window: Any) -> Any: ...

    def merge_window_results(self, results: Any) -> None: ...


class WindowResults:
    """Per-window results of a coordinate map (a :class:`ReportingMap`): statistics
    (:meth:`record`; every window's: :meth:`window_results`) and arrays for the caller to
    write (:meth:`defer`; the caller's map writes them in :meth:`merge_window_results` with
    :meth:`write_deferred`). Pickled (for a Dask worker) without its lock and without any
    result: a worker's copy starts empty, its results come back with each tile's result."""

    #: attributes not pickled; :meth:`_fresh_state` recreates them on the worker
    _NOT_PICKLED: tuple[str, ...] = ("per_window", "_recorded", "_deferred", "_results_lock")

    def __init__(self) -> None:
        self._fresh_state()

    def _fresh_state(self) -> None:
        self.per_window: dict[tuple[int, int, int, int], Any] = {}  # merged from the tiles
        self._recorded: dict[tuple[int, int, int, int], Any] = {}  # here, not taken yet
        self._deferred: dict[tuple[int, int, int, int], list[tuple[str, np.ndarray]]] = {}
        self._results_lock = threading.Lock()

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k not in self._NOT_PICKLED}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._fresh_state()

    def record(self, window: Any, result: Any) -> None:
        """Keep ``result`` (e.g. the window's statistics) for ``window``."""
        key = window_parts(window)
        with self._results_lock:
            self._recorded[key] = result

    def window_results(self) -> dict[tuple[int, int, int, int], Any]:
        """Every window's result known here, ``(col, row, width, height) -> result``: the
        tiles' merged ones and those recorded here and not taken."""
        with self._results_lock:
            return {**self.per_window, **self._recorded}

    def defer(self, window: Any, name: str, array: np.ndarray) -> None:
        """An array for the caller's map to write on ``window`` (:meth:`write_deferred`)."""
        key = window_parts(window)
        with self._results_lock:
            self._deferred.setdefault(key, []).append((name, array))

    def take_window_results(self, window: Any) -> Any:
        """Remove and return the results of the windows inside ``window`` (a tile's, with
        the parts the warp split it into): ``(per_window, deferred)``, None when none."""
        c0, r0, w0, h0 = window_parts(window)

        def inside(key: tuple[int, int, int, int]) -> bool:
            c, r, w, h = key
            return c0 <= c and r0 <= r and c + w <= c0 + w0 and r + h <= r0 + h0

        with self._results_lock:
            results = {k: self._recorded.pop(k) for k in list(self._recorded) if inside(k)}
            deferred = {k: self._deferred.pop(k) for k in list(self._deferred) if inside(k)}
        return (results, deferred) if results or deferred else None

    def merge_window_results(self, results: Any) -> None:
        """Keep the results :meth:`take_window_results` took (here or on a worker) and write
        their deferred arrays."""
        if results is None:
            return
        per_window, deferred = results
        with self._results_lock:
            self.per_window.update(per_window)
        for key, arrays in deferred.items():
            for name, array in arrays:
                self.write_deferred(name, key, array)

    def write_deferred(self, name: str, window: tuple[int, int, int, int],
                       array: np.ndarray) -> None:
        """Write a deferred array (``window``: col, row, width, height), in the caller's
        process; the subclass that defers arrays says where."""
        raise NotImplementedError(f"{type(self).__name__} cannot write {name!r}")


def window_parts(window: Any) -> tuple[int, int, int, int]:
    """``(col_off, row_off, width, height)`` of a Tile or a Window."""
    window = getattr(window, "window", window)
    return int(window.col_off), int(window.row_off), int(window.width), int(window.height)


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
    inputs: Any = field(default=None, compare=False, repr=False)  # the planning map's own


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


def scan_bounds(cols: np.ndarray, rows: np.ndarray) -> tuple[float, float, float, float] | None:
    """Bounding box of the finite coordinates (None when there are none)."""
    finite = np.isfinite(cols) & np.isfinite(rows)
    if not finite.any():
        return None
    c, r = cols[finite], rows[finite]
    return float(c.min()), float(r.min()), float(c.max()), float(r.max())


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
