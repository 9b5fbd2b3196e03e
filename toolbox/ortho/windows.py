"""The coordinate map of a whole ortho, window by window (:class:`OrthoWindows`): DEM heights,
the camera's map, the visibility test and the report's counts of every output window."""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from toolbox.cameras import CameraModel, FrameCamera, GridProjector
from toolbox.ortho.codes import (  # duplicate-ok: the statistics codes, as kernels.py lists them
    BLOCK_EXACT,
    BLOCK_INTERPOLATED,
    BLOCK_PROJECTIVE,
    RELIEF_ROWS,
    STAT_COL_MAX,
    STAT_COL_MIN,
    STAT_MAX_RELIEF,
    STAT_MISSING,
    STAT_OUTSIDE_DEM,
    STAT_OUTSIDE_PHOTO,
    STAT_ROW_MAX,
    STAT_ROW_MIN,
)
from toolbox.ortho.dem import DemSampler, lattice_transform
from toolbox.ortho.metrics import TileStatistics, incidence_angle, relief_displacement
from toolbox.raster.maps import WindowResults, window_parts

if TYPE_CHECKING:
    from toolbox.ortho.sensor import CollinearityMap


class MapBufferPool:
    """Float32 buffers (2, n) for the maps of planned windows, kept between the orthophotos of
    one process (a block's photos, repeated runs): a new 1024 x 1024 pair costs about 1.3 ms
    of page faults on its first write (measured), twice a window's map kernel. At most
    ``keep`` buffers stay pooled, the latest given back (idle memory: 8 MB each for 1024 x
    1024 windows)."""

    def __init__(self, keep: int = 4):
        self.keep = keep
        self._free: list[np.ndarray] = []
        self._lock = threading.Lock()

    def take(self, size: int) -> np.ndarray:
        """A pooled buffer of at least ``size`` cells per map, else a new one."""
        with self._lock:
            for k, buffer in enumerate(self._free):
                if buffer.shape[1] >= size:
                    return self._free.pop(k)
        return np.empty((2, size), dtype="float32")

    def give(self, buffers: list[np.ndarray]) -> None:
        with self._lock:
            self._free = (self._free + buffers)[-self.keep:]


MAP_BUFFERS = MapBufferPool()


class OrthoWindows(WindowResults):
    """The coordinate map of a whole ortho for :func:`toolbox.raster.warp.warp_to_geotiff`:
    per output window it reads the DEM heights onto the window (:class:`DemSampler`), projects
    them (:class:`CollinearityMap`, or the camera's own ``project``), blanks the hidden cells
    (optional visibility test) and collects statistics (:meth:`statistics`, :meth:`totals`);
    auxiliary rasters (occlusion mask, incidence angle) are written window by window.

    A :class:`~toolbox.raster.maps.PlannedMap` and a :class:`~toolbox.raster.maps.MeasuredMap`.
    Given the warp's ``resampling`` (an OpenCV method), the windows of the common case (film
    camera, DEM and ortho in the orientation's CRS, no visibility test or incidence angles)
    are *planned* (:meth:`plan`): the source window comes first, from a bound of the window's
    image (:meth:`CollinearityMap.source_box` on the DEM heights' range), and the kernel writes
    the OpenCV maps relative to it, with the cells outside the photo blanked, in its one pass
    (:meth:`planned_maps`). Every other window is :meth:`measured`: its map and, when every
    cell has an image point, their exact bounds. Same maps either way (tested).

    A :class:`~toolbox.raster.maps.ReportingMap` (:class:`~toolbox.raster.maps.WindowResults`):
    the windows' statistics and auxiliary arrays (mask, angles) travel back with each tile's
    result to the caller's object, which writes the auxiliary rasters; pickled for a Dask
    worker without its writers, lock and thread-local buffers (made again there)."""

    _NOT_PICKLED = WindowResults._NOT_PICKLED + ("mask_writer", "incidence_writer", "_maxima",
                                                 "_buffers_lock", "_local", "_buffers")

    def __init__(self, photo: Any, grid: Any, sampler: DemSampler, cmap: CollinearityMap | None,
                 reference_height: float, surface: Any = None, mask_writer: Any = None,
                 incidence_writer: Any = None, to_orientation: Any = None,
                 resampling: str | None = None, compiled: bool = True):
        from toolbox.raster.resample import RESAMPLING_METHODS

        self.compiled = compiled  # a camera model's map by numba's kernel, else NumPy's

        self.photo, self.grid, self.sampler, self.cmap = photo, grid, sampler, cmap
        # cmap None: the camera's own project() maps every window (project_cells)
        self.camera: CameraModel = photo.sensor()
        self.image_size = (cmap.model.width, cmap.model.height) if cmap is not None else \
            tuple(photo.camera.image_size_px)
        self.resampling = resampling if resampling in RESAMPLING_METHODS else None
        self.to_orientation = to_orientation  # pyproj Transformer grid CRS -> orientation CRS
        # the one-pass kernel on the DEM's own cells (planned or measured): the film camera,
        # the DEM and the ortho in the orientation's CRS; else heights, then the camera's map
        self.one_pass = (cmap is not None and to_orientation is None
                         and sampler.transformer is None)
        self.reference_height = reference_height
        self.surface = surface
        self.mask_writer = mask_writer  # in the caller's process (write_deferred)
        self.incidence_writer = incidence_writer
        self.writes_mask = mask_writer is not None
        self.writes_incidence = incidence_writer is not None
        self.centre = photo.require_exterior().centre
        WindowResults.__init__(self)

    def _fresh_state(self) -> None:
        """No results, no map buffers (here, or on a worker: :meth:`__setstate__`)."""
        super()._fresh_state()
        self._maxima: np.ndarray | None = None
        self._buffers_lock = threading.Lock()
        self._local = threading.local()  # per thread: its map buffers (_map_buffers)
        self._buffers: list[np.ndarray] = []  # the map buffers taken (_map_buffers)

    def write_deferred(self, name: str, window: tuple[int, int, int, int],
                       array: np.ndarray) -> None:
        """Write a window's occlusion mask or incidence angles (in the caller's process)."""
        from rasterio.windows import Window

        writer = self.mask_writer if name == "mask" else self.incidence_writer
        writer.write(Window(*window), array)

    def release(self) -> None:
        """Give the map buffers back to :data:`MAP_BUFFERS` (when the ortho is written: no map
        of this job may be used afterwards); also on garbage collection."""
        with self._buffers_lock:
            buffers, self._buffers = self._buffers, []
        MAP_BUFFERS.give(buffers)

    def __del__(self) -> None:
        if getattr(self, "_buffers", None):
            self.release()

    def statistics(self, window: Any) -> TileStatistics:
        """The counts of a window the warp has mapped (planned or measured)."""
        return self.window_results()[window_parts(window)]

    def plan(self, tile: Any, aux: Any = None) -> Any:
        """The :class:`~toolbox.raster.maps.SourcePlan` of a planned window (see the class
        docstring; its ``inputs`` carry what :meth:`planned_maps` needs), None when it is not
        planned. Cheap: no map is computed yet (but for a window whose image misses the
        photo: its cells are counted here)."""
        return self._prepare(getattr(tile, "window", tile))

    def planned_maps(self, plan: Any) -> tuple[np.ndarray, np.ndarray]:
        """The OpenCV maps of a planned window (:meth:`plan`), in this thread's map buffers:
        valid until the thread's next window."""
        return self._compute_planned(*plan.inputs, plan)

    def measured(self, tile: Any, aux: Any = None
                 ) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float, float] | None]:
        """The source pixel coordinates of a window (NaN: no image point, or hidden) and their
        exact bounding box when every cell has one (else None)."""
        return self._compute(getattr(tile, "window", tile))

    def __call__(self, tile: Any, aux: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """The source pixel coordinates of an output tile (:meth:`measured` without bounds)."""
        cols, rows, _ = self.measured(tile, aux)
        return cols, rows

    def _prepare(self, window: Any) -> Any:
        """The plan of a window that can be planned (:meth:`_plan`), its ``inputs``
        ``(window, transform, xs, ys, DEM part)``; else None."""
        if not self.one_pass or self.writes_incidence:  # (angles: measured)
            return None
        xs, ys = self.grid.cell_centers(window)
        part = self.sampler.part(xs, ys)
        if part is None:
            return None
        transform = self.grid.window_transform(window)
        plan = self._plan(window, transform, part)
        if plan is None:
            return None
        plan = replace(plan, inputs=(window, transform, xs, ys, part))
        if plan.window is None:  # no map is asked: count its cells here
            self._compute_planned(*plan.inputs, plan)
        return plan

    def _compute_planned(self, window: Any, transform: Any, xs: np.ndarray, ys: np.ndarray,
                         part: tuple, plan: Any) -> tuple[np.ndarray, np.ndarray]:
        """The whole planned window's OpenCV maps (and its statistics), in this thread's map
        buffers (:meth:`_map_buffers`)."""
        cols, rows, modes, s, _ = self.cmap.project_on_dem(
            transform, xs, ys, part, self.centre, self.reference_height,
            shift=(plan.shift_col, plan.shift_row), out=self._map_buffers(len(ys), len(xs)))
        self._record(window, cols.size, s, modes)
        return cols, rows

    def _map_buffers(self, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
        """This thread's two float32 (h, w) arrays for a planned window's maps, reused window
        after window: they hold until the thread's next window (the warp resamples a window
        before it asks for the next) or :meth:`release`. From :data:`MAP_BUFFERS`: new
        arrays cost their page faults on first write."""
        flat = getattr(self._local, "maps", None)
        if flat is None or flat.shape[1] < h * w:
            self._local.maps = flat = MAP_BUFFERS.take(h * w)
            with self._buffers_lock:
                self._buffers.append(flat)
        return flat[0, :h * w].reshape(h, w), flat[1, :h * w].reshape(h, w)

    def _record(self, window: Any, cells: int, s: np.ndarray, modes: np.ndarray) -> None:
        """The window's statistics from a kernel's ``stats`` array and block modes."""
        stats = TileStatistics(cells=cells, outside_dem=int(s[STAT_OUTSIDE_DEM]),
                               outside_photo=int(s[STAT_OUTSIDE_PHOTO]),
                               max_relief_m=float(s[STAT_MAX_RELIEF]))
        if self.cmap.model.distortion[0] == 0:  # every block projective
            stats.blocks = {BLOCK_PROJECTIVE: modes.size, BLOCK_INTERPOLATED: 0, BLOCK_EXACT: 0}
        else:
            counts = np.bincount(modes.ravel(), minlength=3)
            stats.blocks = {k: int(counts[k]) for k in range(3)}
        self.record(window, stats)

    def _compute(self, window: Any):
        """The map of an unplanned window with its statistics: the one-pass kernel where it
        applies (:meth:`_compute_fused`), else the heights then the camera's map."""
        xs, ys = self.grid.cell_centers(window)
        cell_x = self.grid.cell_size[0]
        if self.one_pass:
            part = self.sampler.part(xs, ys)
            if part is not None:
                if self.writes_incidence:
                    self._write_incidence(window, xs, ys)
                return self._compute_fused(window, xs, ys, part)
        if self.writes_incidence:
            z = self._write_incidence(window, xs, ys)
        else:
            z = self.sampler.heights(xs, ys)
        if self.to_orientation is None and self.cmap is not None:
            cols, rows, modes, box = self.cmap.project(self.grid.window_transform(window), z)
            gx, gy = xs[None, :], ys[:, None]
        else:  # the camera's project(), point by point (the ortho in another CRS: the cell
            # centres go to the orientation's CRS first)
            if self.to_orientation is None:
                gx, gy = np.broadcast_to(xs[None, :], z.shape), np.broadcast_to(ys[:, None],
                                                                                z.shape)
            else:
                gx, gy = lattice_transform(self.to_orientation, xs, ys, 1e-3 * cell_x)
                gx, gy = gx.reshape(z.shape), gy.reshape(z.shape)
            cols, rows, box = project_cells(self.camera, gx, gy, z, self.compiled)
            modes = np.zeros((0, 0), dtype=np.int8)  # no blocks: every point exact
        return self._finish(window, xs, ys, gx, gy, z, cols, rows, modes, box)

    def _write_incidence(self, window: Any, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Write the window's incidence angles (normals from the heights of the window and
        one cell around it); returns the window's heights."""
        cell_x, cell_y = self.grid.cell_size
        xh = np.concatenate([[xs[0] - cell_x], xs, [xs[-1] + cell_x]])
        yh = np.concatenate([[ys[0] + cell_y], ys, [ys[-1] - cell_y]])
        z_halo = self.sampler.heights(xh, yh)
        angles = incidence_angle(xs, ys, z_halo, self.centre)[None]
        self.defer(window, "incidence", angles)
        return np.ascontiguousarray(z_halo[1:-1, 1:-1])

    def _finish(self, window: Any, xs: np.ndarray, ys: np.ndarray, gx: np.ndarray,
                gy: np.ndarray, z: np.ndarray, cols: np.ndarray, rows: np.ndarray,
                modes: np.ndarray, box: np.ndarray):
        """Visibility test (optional) and statistics of a window's map; ``(cols, rows, box or
        None)`` as :meth:`measured` returns them."""
        cmin, rmin, cmax, rmax, missing = box
        stats = TileStatistics(cells=z.size)
        nan_z = np.isnan(z)
        stats.outside_dem = int(np.count_nonzero(nan_z))
        if self.surface is not None:
            from toolbox.ortho.visibility import block_maxima, visibility_mask

            if self._maxima is None:
                self._maxima = block_maxima(self.surface.z)
            hidden = visibility_mask(xs, ys, z, self.centre, self.surface, self._maxima)
            if self.writes_mask:
                self.defer(window, "mask", np.where(nan_z, 255, hidden).astype(np.uint8))
            mask = hidden.astype(bool)
            stats.hidden = int(np.count_nonzero(mask))
            if stats.hidden:
                cols[mask] = np.nan
                rows[mask] = np.nan
                missing += stats.hidden
        w, h = self.image_size
        every_cell = missing == 0
        box = (float(cmin), float(rmin), float(cmax), float(rmax)) if missing < z.size else None
        if every_cell and box[0] >= 0 and box[1] >= 0 and box[2] <= w and box[3] <= h:
            inside = None  # the whole window is in the photo
            stats.outside_photo = 0
        else:
            inside = (cols >= 0) & (cols <= w) & (rows >= 0) & (rows <= h)
            stats.outside_photo = int(z.size - missing - np.count_nonzero(inside))
        sub = (slice(None, None, RELIEF_ROWS), slice(None))  # as the kernels sample it
        gx, gy = np.broadcast_to(gx, z.shape), np.broadcast_to(gy, z.shape)
        disp = relief_displacement(gx[sub], gy[sub], z[sub], self.centre, self.reference_height)
        disp = disp[inside[sub]] if inside is not None else disp.ravel()
        disp = disp[np.isfinite(disp)]
        stats.max_relief_m = float(disp.max()) if disp.size else 0.0
        counts = np.bincount(modes.ravel(), minlength=3)
        stats.blocks = {k: int(counts[k]) for k in range(3)}
        self.record(window, stats)
        return cols, rows, box if every_cell else None

    def _plan(self, window: Any, transform: Any, part: tuple) -> Any:
        """The :class:`~toolbox.raster.maps.SourcePlan` of a window (EMPTY_PLAN when its image
        misses the photo), None when it cannot be planned (no resampling given, a visibility
        test, no DEM height under it, or the bound of :meth:`CollinearityMap.source_box` does
        not exist)."""
        from toolbox.raster.maps import EMPTY_PLAN, plan_source

        if self.resampling is None or self.surface is not None:
            return None
        low, high = np.fmin.reduce(part[0], axis=None), np.fmax.reduce(part[0], axis=None)
        if not (math.isfinite(low) and math.isfinite(high)):  # NaN: no height at all
            return None
        box = self.cmap.source_box(transform, int(window.height), int(window.width),
                                   float(low), float(high))
        if box is None:
            return None
        model = self.cmap.model
        return plan_source(box, model.width, model.height, self.resampling) or EMPTY_PLAN

    def _compute_fused(self, window: Any, xs: np.ndarray, ys: np.ndarray, part: tuple):
        """:meth:`_compute` with the heights, the map and the statistics in one kernel pass
        (:meth:`CollinearityMap.project_on_dem`); the visibility test, when asked, follows on
        the kept heights."""
        hidden_test = self.surface is not None
        cols, rows, modes, s, z = self.cmap.project_on_dem(
            self.grid.window_transform(window), xs, ys, part, self.centre,
            self.reference_height, keep_heights=hidden_test)
        if hidden_test:  # the counts after the visibility test (it blanks cells)
            return self._finish(window, xs, ys, xs[None, :], ys[:, None], z, cols, rows,
                                modes, s[:5])
        self._record(window, cols.size, s, modes)
        missing = int(s[STAT_MISSING])
        if missing == cols.size:
            return cols, rows, None
        box = (float(s[STAT_COL_MIN]), float(s[STAT_ROW_MIN]), float(s[STAT_COL_MAX]),
               float(s[STAT_ROW_MAX]))
        return cols, rows, box if missing == 0 else None

    def totals(self) -> TileStatistics:
        """Sums over the windows, without the parents of windows the warp split in four."""
        return leaf_window_totals(self.window_results())


def project_cells(camera: CameraModel, gx: np.ndarray, gy: np.ndarray, z: np.ndarray,
                  compiled: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The coordinate map of a window through any camera: ground cells ``gx``, ``gy`` (h, w) at
    heights ``z`` (h, w; NaN: none) -> float32 photo pixels ``(cols, rows)`` (h, w; NaN where
    the cell has no height or no image) and ``box`` (col_min, row_min, col_max, row_max, NaN
    count) of the finite ones. A :class:`~toolbox.cameras.GridProjector` camera does it in
    one compiled pass; without ``compiled`` a :class:`~toolbox.cameras.FrameCamera` does it in
    NumPy (:func:`~toolbox.ortho.grid_numpy.frame_grid_to_pixels`, the same arithmetic)."""
    if not compiled and isinstance(camera, FrameCamera):
        from toolbox.ortho.grid_numpy import frame_grid_to_pixels

        return frame_grid_to_pixels(camera, gx, gy, z)
    if isinstance(camera, GridProjector):
        return camera.project_grid(gx, gy, z)
    image = camera.project(np.column_stack([gx.ravel(), gy.ravel(), z.ravel()]))
    cols = image[:, 0].astype("float32").reshape(z.shape)
    rows = image[:, 1].astype("float32").reshape(z.shape)
    finite = np.isfinite(cols) & np.isfinite(rows)
    cols[~finite] = np.nan
    rows[~finite] = np.nan
    box = np.array([cols[finite].min(), rows[finite].min(), cols[finite].max(),
                    rows[finite].max(), z.size - finite.sum()]) if finite.any() else \
        np.array([np.inf, np.inf, -np.inf, -np.inf, z.size])
    return cols, rows, box


def leaf_window_totals(per_window: dict) -> TileStatistics:
    """Sum of the statistics of the windows ``(col, row, width, height) -> stats`` that hold no
    other window (the warp splits a window in four when its source is too large: the parent's
    statistics would count its cells twice)."""
    keys = list(per_window)

    def contains(a, b):
        return (a != b and a[0] <= b[0] and a[1] <= b[1] and b[0] + b[2] <= a[0] + a[2]
                and b[1] + b[3] <= a[1] + a[3])

    total = TileStatistics()
    for k in keys:
        if not any(contains(k, other) for other in keys):
            total.add(per_window[k])
    return total
