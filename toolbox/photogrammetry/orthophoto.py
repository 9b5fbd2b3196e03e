"""Orthorectification driver: DEM heights per output window, the per-photo plan (footprint, GSD,
grid), the windowed warp of one photo with its statistics and auxiliary rasters, the per-photo
task of a block. The numeric kernels are in :mod:`toolbox.photogrammetry.ortho`.

Flow of one photo (``ortho:photo``; ``ortho:batch`` runs :func:`run_task` per photo)::

    plan = plan_photo(photo, dem, crs)                 # checks, footprint, mean height, GSD, grid
    report = orthorectify(photo, image, dem, plan.grid, output, OrthoOptions(...))

:func:`orthorectify` hands :class:`OrthoWindows` to :func:`toolbox.raster.engine.warp_to_geotiff`:
per output window it reads the DEM heights onto the window (:class:`DemSampler`, bilinear
between DEM cell centres, reprojected when the DEM's CRS differs), projects them
(:class:`~toolbox.photogrammetry.ortho.CollinearityMap`), blanks the cells hidden from the
camera (optional) and counts what the report needs.

Two paths compute a window's map. The film camera's is the compiled, planned one above. Every
other camera (the interior models of :mod:`toolbox.cameras`: pinhole, Brown, OpenCV, fisheye),
and the film camera when the ortho is in another CRS than its orientation, takes one explicit
path: the window's cells with their DEM heights go through the camera's ``project``
(:func:`project_cells`: one compiled pass for the interior models, the camera's vectorised
``project`` otherwise), and the warp remaps the photo there (``cv2.remap``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.cameras import CameraModel, GridProjector
from toolbox.errors import InputDataError
from toolbox.photogrammetry.ortho import (
    BLOCK_EXACT,
    BLOCK_INTERPOLATED,
    BLOCK_PROJECTIVE,
    DEFAULT_BLOCK,
    DEFAULT_TOLERANCE_PX,
    RELIEF_ROWS,
    STAT_COL_MAX,
    STAT_COL_MIN,
    STAT_MAX_RELIEF,
    STAT_MISSING,
    STAT_OUTSIDE_DEM,
    STAT_OUTSIDE_PHOTO,
    STAT_ROW_MAX,
    STAT_ROW_MIN,
    CollinearityMap,
    block_maxima,
    check_geometry,
    ground_sample_distance,
    heights_at_points,
    heights_on_grid,
    incidence_angle,
    nice_cell_size,
    relief_displacement,
    visibility_mask,
)


class DemSampler:
    """Heights of output cells from a DEM raster, one window per call.

    The DEM may be in another CRS than the output (``crs``): the cell centres are then
    transformed with pyproj (always_xy) and the heights taken bilinearly in the DEM's own grid.
    A DEM whose CRS differs only by a vertical part (a compound CRS such as UTM + EGM2008
    height) is read directly: its heights are taken as they are (:func:`same_horizontal_crs`).
    ``factor`` > 1 projects on a coarser DEM (the thesis' "fattore di ricampionamento"): the mean
    of ``factor`` x ``factor`` DEM cells, on a lattice fixed to the DEM's origin (no tile seams).
    """

    def __init__(self, info: Any, crs: Any = None, band: int = 1, factor: int = 1):
        self.path = info.path
        self.band = int(band)
        self.factor = max(1, int(factor))
        t = info.transform
        if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
            raise InputDataError(f"DEM {info} must be north-up (no rotation, rows going south)")
        self.transform = t
        self.shape = (info.height, info.width)
        self.nodata = info.nodata
        self.transformer = None
        if info.crs is not None and crs is not None and not same_horizontal_crs(info.crs, crs):
            from pyproj import Transformer

            self.transformer = Transformer.from_crs(crs, info.crs, always_xy=True)
        self._cache: tuple | None = None  # (i0, j0, array) of coarse cells held in memory

    def preload(self, bounds: tuple[float, float, float, float],
                max_cells: int = 1 << 24) -> bool:
        """Hold the DEM cells under ``bounds`` (output CRS) in memory when they are at most
        ``max_cells``, so that tiles slice them instead of reading the file; True if done."""
        if self.transformer is not None:
            xx, yy = np.meshgrid(np.linspace(bounds[0], bounds[2], 21),
                                 np.linspace(bounds[1], bounds[3], 21))
            dx, dy = self.transformer.transform(xx.ravel(), yy.ravel())
            pad = 2 * max(abs(self.transform.a), abs(self.transform.e)) * self.factor
            bounds = (min(dx) - pad, min(dy) - pad, max(dx) + pad, max(dy) + pad)
        span = self._span(bounds)
        if span is None:
            return False
        i0, i1, j0, j1 = span
        if (i1 - i0) * (j1 - j0) > max_cells:
            return False
        self._cache = (i0, j0, self._load(i0, i1, j0, j1))
        return True

    def _span(self, bounds):
        """Coarse-cell rows/columns (i0, i1, j0, j1) covering ``bounds`` (DEM CRS) plus one cell
        for the bilinear interpolation, clipped to the DEM; None outside it."""
        t, k = self.transform, self.factor
        rows, cols = self.shape
        c0 = (bounds[0] - t.c) / t.a
        c1 = (bounds[2] - t.c) / t.a
        r0 = (bounds[3] - t.f) / t.e
        r1 = (bounds[1] - t.f) / t.e
        if not all(math.isfinite(v) for v in (c0, c1, r0, r1)):
            return None
        j0 = max(int(math.floor(c0 / k)) - 1, 0)
        i0 = max(int(math.floor(r0 / k)) - 1, 0)
        j1 = min(int(math.ceil(c1 / k)) + 1, cols // k)
        i1 = min(int(math.ceil(r1 / k)) + 1, rows // k)
        if j1 - j0 < 2 or i1 - i0 < 2:
            return None
        return i0, i1, j0, j1

    def _load(self, i0: int, i1: int, j0: int, j1: int) -> np.ndarray:
        """Coarse cells [i0:i1, j0:j1] (means of k x k DEM cells), float64, NaN for nodata."""
        import rasterio
        from rasterio.windows import Window

        k = self.factor
        window = Window(j0 * k, i0 * k, (j1 - j0) * k, (i1 - i0) * k)
        with rasterio.open(self.path) as src:
            data = src.read(self.band, window=window, masked=True).astype("float64").filled(np.nan)
        if k > 1:
            data = data.reshape(i1 - i0, k, j1 - j0, k)
            with warnings.catch_warnings():  # all-nodata blocks give NaN, as they should
                warnings.simplefilter("ignore", RuntimeWarning)
                data = np.nanmean(data, axis=(1, 3))
        return np.ascontiguousarray(data)

    def _read(self, bounds: tuple[float, float, float, float]):
        """The (coarsened) DEM array covering ``bounds`` in DEM coordinates, NaN for nodata, and
        the centre of its cell [0, 0] and cell sizes; None when outside the DEM."""
        span = self._span(bounds)
        if span is None:
            return None
        i0, i1, j0, j1 = span
        cache = self._cache
        if cache is not None and cache[0] <= i0 and cache[1] <= j0 and \
                i1 <= cache[0] + cache[2].shape[0] and j1 <= cache[1] + cache[2].shape[1]:
            data = cache[2][i0 - cache[0]:i1 - cache[0], j0 - cache[1]:j1 - cache[1]]
        else:
            data = self._load(i0, i1, j0, j1)
        t, k = self.transform, self.factor
        gx0 = t.c + (j0 * k + 0.5 * k) * t.a
        gy0 = t.f + (i0 * k + 0.5 * k) * t.e
        return data, gx0, gy0, t.a * k, -t.e * k

    def _to_dem(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """DEM-CRS coordinates (flat) of the grid ``xs`` x ``ys`` (:func:`lattice_transform`,
        within 1/1000 of a DEM cell)."""
        return lattice_transform(self.transformer, xs, ys, 1e-3 * abs(self.transform.a))

    def part(self, xs: np.ndarray, ys: np.ndarray) -> tuple | None:
        """The DEM cells under the grid ``xs`` x ``ys`` (output CRS = the DEM's) as
        :func:`~toolbox.photogrammetry.ortho.heights_on_grid` takes them: (contiguous float64
        array, x and y of the centre of its cell [0, 0], cell width and height); None outside
        the DEM. ``xs`` and ``ys`` are monotonic (cell centres): their ends bound them."""
        x0, x1, y0, y1 = float(xs[0]), float(xs[-1]), float(ys[0]), float(ys[-1])
        part = self._read((min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)))
        if part is None:
            return None
        return (np.ascontiguousarray(part[0]), *part[1:])

    def heights(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Heights (h, w) float64 at the grid of cell centres ``xs`` (w,) x ``ys`` (h,) (output
        CRS), NaN where the DEM has none."""
        xs = np.ascontiguousarray(xs, dtype="float64")
        ys = np.ascontiguousarray(ys, dtype="float64")
        out = np.full((len(ys), len(xs)), np.nan)
        if self.transformer is None:
            part = self.part(xs, ys)
            if part is not None:
                heights_on_grid(*part, xs, ys, out)
            return out
        dx, dy = self._to_dem(xs, ys)
        finite = np.isfinite(dx) & np.isfinite(dy)
        if not finite.any():
            return out
        part = self._read((dx[finite].min(), dy[finite].min(), dx[finite].max(),
                           dy[finite].max()))
        if part is not None:
            flat = out.ravel()
            heights_at_points(np.ascontiguousarray(part[0]), *part[1:], dx, dy, flat)
            out = flat.reshape(out.shape)
        return out


def same_horizontal_crs(a: Any, b: Any) -> bool:
    """The same CRS, or the same horizontal CRS where one or both are compound (a vertical
    datum adds heights, it does not move the cells: no reprojection)."""
    from toolbox.io.crs import same_crs

    def horizontal(crs: Any) -> Any:
        return crs.sub_crs_list[0] if getattr(crs, "is_compound", False) else crs

    return same_crs(a, b) or same_crs(horizontal(a), horizontal(b))


LATTICE = 16  # cells between exactly transformed points when a grid goes to another CRS


def lattice_transform(transformer: Any, xs: np.ndarray, ys: np.ndarray, tolerance: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates (flat, contiguous float64) of the grid ``xs`` x ``ys`` in another CRS:
    exact with pyproj on a lattice of every :data:`LATTICE`-th cell (and the last), bilinear in
    between. The interpolation is checked at the centres of the lattice cells against pyproj;
    where it is off by more than ``tolerance`` (target CRS units) every point is transformed."""
    h, w = len(ys), len(xs)
    rows = np.unique(np.r_[np.arange(0, h, LATTICE), h - 1])
    cols = np.unique(np.r_[np.arange(0, w, LATTICE), w - 1])
    exact = len(rows) * len(cols) * 4 >= h * w or len(rows) < 2 or len(cols) < 2
    if not exact:
        lx, ly = np.meshgrid(xs[cols], ys[rows])
        tx, ty = transformer.transform(lx.ravel(), ly.ravel())
        dx = _interpolate_lattice(np.asarray(tx).reshape(lx.shape), rows, cols, h, w)
        dy = _interpolate_lattice(np.asarray(ty).reshape(lx.shape), rows, cols, h, w)
        mi = (rows[:-1] + rows[1:]) // 2
        mj = (cols[:-1] + cols[1:]) // 2
        cx, cy = np.meshgrid(xs[mj], ys[mi])
        ex, ey = transformer.transform(cx.ravel(), cy.ravel())
        error = np.hypot(np.asarray(ex) - dx[np.ix_(mi, mj)].ravel(),
                         np.asarray(ey) - dy[np.ix_(mi, mj)].ravel())
        exact = not (np.all(np.isfinite(error)) and error.max() <= tolerance)
    if exact:
        xx, yy = np.meshgrid(xs, ys)
        dx, dy = transformer.transform(xx.ravel(), yy.ravel())
    return (np.ascontiguousarray(np.ravel(dx), dtype="float64"),
            np.ascontiguousarray(np.ravel(dy), dtype="float64"))


def _interpolate_lattice(values: np.ndarray, rows: np.ndarray, cols: np.ndarray, h: int,
                         w: int) -> np.ndarray:
    """Bilinear interpolation of lattice values (at grid rows ``rows`` x columns ``cols``) onto
    every cell of an (h, w) grid."""
    i = np.arange(h)
    j = np.arange(w)
    bi = np.clip(np.searchsorted(rows, i, side="right") - 1, 0, len(rows) - 2)
    bj = np.clip(np.searchsorted(cols, j, side="right") - 1, 0, len(cols) - 2)
    ti = ((i - rows[bi]) / (rows[bi + 1] - rows[bi]))[:, None]
    tj = ((j - cols[bj]) / (cols[bj + 1] - cols[bj]))[None, :]
    v00 = values[bi][:, bj]
    v01 = values[bi][:, bj + 1]
    v10 = values[bi + 1][:, bj]
    v11 = values[bi + 1][:, bj + 1]
    return (v00 * (1 - tj) + v01 * tj) * (1 - ti) + (v10 * (1 - tj) + v11 * tj) * ti


@dataclass
class TileStatistics:
    """Counters of the cells of the ortho (see :meth:`as_dict`)."""

    cells: int = 0
    outside_dem: int = 0
    outside_photo: int = 0
    hidden: int = 0
    max_relief_m: float = 0.0
    blocks: dict[int, int] = field(default_factory=lambda: {0: 0, 1: 0, 2: 0})

    def add(self, other: TileStatistics) -> None:
        self.cells += other.cells
        self.outside_dem += other.outside_dem
        self.outside_photo += other.outside_photo
        self.hidden += other.hidden
        self.max_relief_m = max(self.max_relief_m, other.max_relief_m)
        for k, v in other.blocks.items():
            self.blocks[k] = self.blocks.get(k, 0) + v


# -- grids and surfaces ------------------------------------------------------------------------------
def lattice_grid(bounds: tuple[float, float, float, float], cell: float, crs: Any,
                 origin: tuple[float, float] = (0.0, 0.0), name: str = "CELL_SIZE") -> Any:
    """A north-up grid covering ``bounds`` whose edges lie on the lattice ``origin + k·cell``
    (default: multiples of the cell), so orthos of one block share one grid and mosaic
    without resampling."""
    from affine import Affine

    from toolbox.io.grid import GridSpec

    ox, oy = origin
    xmin = ox + math.floor((bounds[0] - ox) / cell + 1e-9) * cell
    ymin = oy + math.floor((bounds[1] - oy) / cell + 1e-9) * cell
    xmax = ox + math.ceil((bounds[2] - ox) / cell - 1e-9) * cell
    ymax = oy + math.ceil((bounds[3] - oy) / cell - 1e-9) * cell
    probe = GridSpec.from_bounds((xmin, ymin, xmax, ymax), cell, crs, snap=False, name=name)
    return GridSpec(Affine(cell, 0.0, xmin, 0.0, -cell, ymin + probe.height * cell),
                    probe.width, probe.height, crs)


def check_dem_crs(info: Any, name: str = "DEM") -> None:
    """Refuse a DEM without a CRS whose coordinates look like geographic degrees (heights
    cannot be placed on a projected ortho grid without knowing the datum)."""
    if info.crs is not None:
        return
    xmin, ymin, xmax, ymax = info.bounds
    if -180 <= xmin and xmax <= 360 and -90 <= ymin and ymax <= 90 and info.res[0] < 1.0:
        raise InputDataError(f"{name} {info} has no CRS and its coordinates ({xmin:.4f}.."
                             f"{xmax:.4f}, {ymin:.4f}..{ymax:.4f}) look like geographic degrees; "
                             "assign its CRS (e.g. gdal_edit.py -a_srs EPSG:4326) or reproject it")


def photo_surface(info: Any, photo: Any, crs: Any, band: int = 1) -> Any:
    """The DEM window every ray of the photo can meet, as a
    :class:`~toolbox.photogrammetry.surface.DemSurface` in ``crs`` (reprojected bilinearly at the
    DEM's resolution when the DEM is in another CRS)."""
    from toolbox.photogrammetry.surface import surface_for_photo

    if info.crs is None or crs is None or same_horizontal_crs(info.crs, crs):
        return surface_for_photo(info, photo, band)
    import rasterio
    from rasterio.enums import Resampling
    from rasterio.vrt import WarpedVRT

    from toolbox.io.raster import RasterInfo

    with rasterio.open(info.path) as src, WarpedVRT(src, crs=crs.to_wkt(),
                                                    resampling=Resampling.bilinear) as vrt:
        data = vrt.read(band, masked=True).astype("float64").filled(np.nan)
        view = RasterInfo(info.path, vrt.width, vrt.height, 1, ("float64",), crs, vrt.transform,
                          None, True)
    from toolbox.photogrammetry.surface import DemSurface, photo_ground_bounds

    whole = DemSurface.from_transform(data, view.transform, crs)
    low, high = whole.z_range
    pad = 0.1 * (high - low) + 1.0
    b = photo_ground_bounds(photo, low - pad, high + pad)
    t = view.transform
    c0 = max(int((b[0] - t.c) / t.a) - 2, 0)
    c1 = min(int((b[2] - t.c) / t.a) + 3, view.width)
    r0 = max(int((b[3] - t.f) / t.e) - 2, 0)
    r1 = min(int((b[1] - t.f) / t.e) + 3, view.height)
    if c1 - c0 < 2 or r1 - r0 < 2:
        raise InputDataError(f"DEM {info} does not cover the photo {photo.id!r}")
    from affine import Affine

    return DemSurface.from_transform(data[r0:r1, c0:c1], t @ Affine.translation(c0, r0), crs)


def mean_height_inside(surface: Any, polygon: Any) -> float:
    """Mean DEM height of the cell centres inside a footprint polygon (the photo's mean terrain
    height); the mean of the whole window when no centre falls inside."""
    import shapely

    rows, cols = surface.shape
    xx, yy = np.meshgrid(surface.x0 + np.arange(cols) * surface.cell_x,
                         surface.y0 - np.arange(rows) * surface.cell_y)
    inside = shapely.contains_xy(polygon, xx, yy) & np.isfinite(surface.z)
    return float(surface.z[inside].mean() if inside.any() else np.nanmean(surface.z))


# -- the driver ---------------------------------------------------------------------------------------
@dataclass
class OrthoOptions:
    """How :func:`orthorectify` works (see ``ortho:photo``'s help)."""

    resampling: str = "bilinear"
    outside: str = "alpha"
    nodata: float | None = None
    block: int = DEFAULT_BLOCK
    tolerance_px: float = DEFAULT_TOLERANCE_PX
    dem_factor: int = 1
    band: int = 1
    occlusion: bool = False
    chunk: int = 1024
    overviews: bool = True
    cog: bool = False


class MapBufferPool:
    """Float32 buffers (2, n) for the maps of planned windows, kept between the orthophotos of
    one process (a block's photos, repeated runs): a new 1024 x 1024 pair costs about 1.3 ms
    of page faults on its first write (measured), twice a window's map kernel. At most
    ``keep`` buffers stay pooled, the latest given back (idle memory: 8 MB each for 1024 x
    1024 windows)."""

    def __init__(self, keep: int = 4):
        import threading

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


class OrthoWindows:
    """The coordinate map of a whole ortho for :func:`toolbox.raster.engine.warp_to_geotiff`:
    per output window it reads the DEM heights onto the window (:class:`DemSampler`), projects
    them (:class:`CollinearityMap`), blanks the hidden cells (optional visibility test) and
    collects statistics; auxiliary rasters (occlusion mask, incidence angle) are written window
    by window.

    Given the warp's ``resampling`` (an OpenCV method), the windows of the common case (DEM
    and ortho in the orientation's CRS, no visibility test or incidence angles) are *planned*
    (:meth:`source_plan`): the source window comes first, from a bound of the window's image
    (:meth:`CollinearityMap.source_box` on the DEM heights' range), and the kernel writes the
    OpenCV maps relative to it, with the cells outside the photo blanked, in its one pass."""

    def __init__(self, photo: Any, grid: Any, sampler: DemSampler, cmap: CollinearityMap | None,
                 reference_height: float, surface: Any = None, mask_writer: Any = None,
                 incidence_writer: Any = None, to_orientation: Any = None,
                 resampling: str | None = None):
        from toolbox.raster.warp import RESAMPLING_METHODS

        self.photo, self.grid, self.sampler, self.cmap = photo, grid, sampler, cmap
        # cmap None: the camera's own project() maps every window (project_cells)
        self.camera: CameraModel = photo.sensor()
        self.image_size = (cmap.model.width, cmap.model.height) if cmap is not None else \
            tuple(photo.camera.image_size_px)
        self.resampling = resampling if resampling in RESAMPLING_METHODS else None
        self.to_orientation = to_orientation  # pyproj Transformer grid CRS -> orientation CRS
        self.reference_height = reference_height
        self.surface = surface
        self.mask_writer = mask_writer
        self.incidence_writer = incidence_writer
        self.centre = photo.require_exterior().centre
        self.per_window: dict[tuple[int, int, int, int], TileStatistics] = {}
        self._maxima: np.ndarray | None = None
        import threading

        self._write_lock = threading.Lock()  # aux writers, if a split window runs alongside
        self._local = threading.local()  # per thread: the window it works on (_kept_for)
        self._buffers: list[np.ndarray] = []  # the map buffers taken (_map_buffers)

    def release(self) -> None:
        """Give the map buffers back to :data:`MAP_BUFFERS` (when the ortho is written: no map
        of this job may be used afterwards); also on garbage collection."""
        with self._write_lock:
            buffers, self._buffers = self._buffers, []
        MAP_BUFFERS.give(buffers)

    def __del__(self) -> None:
        if getattr(self, "_buffers", None):
            self.release()

    def _key(self, window: Any) -> tuple[int, int, int, int]:
        return (int(window.col_off), int(window.row_off), int(window.width), int(window.height))

    def _kept_for(self, window: Any) -> dict:
        """What this thread keeps of the window it works on (the warp asks for the plan or the
        bounds, then the map, of one window; tiles run on threads)."""
        key = self._key(window)
        kept = getattr(self._local, "kept", None)
        if kept is None or kept["key"] != key:
            self._local.kept = kept = {"key": key}
        return kept

    def _prepared(self, window: Any) -> Any:
        """The planned window's inputs ``(transform, xs, ys, DEM part, plan)``, None when not
        planned."""
        kept = self._kept_for(window)
        if "prepared" not in kept:
            kept["prepared"] = self._prepare(window)
        return kept["prepared"]

    def _keep(self, window: Any):
        """The unplanned window's :meth:`_compute` result, kept for the calls that follow."""
        kept = self._kept_for(window)
        if "result" not in kept:
            kept["result"] = self._compute(window)
        return kept["result"]

    def source_plan(self, window: Any) -> Any:
        """The :class:`~toolbox.raster.warp.SourcePlan` of a planned window (see the class
        docstring), None when it is not planned. Cheap: no map is computed yet."""
        prepared = self._prepared(window)
        return None if prepared is None else prepared[4]

    def source_bounds(self, window: Any) -> tuple[float, float, float, float] | None:
        """The exact bounding box of the window's source coordinates when every cell has one
        (the warp then skips its own scan and, inside the photo, the inside test); None when
        some cells have none. The coordinates are kept for the call that follows."""
        return self._keep(window)[2]

    def __call__(self, tile: Any, aux: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """The source pixel coordinates of an output tile (the engine's ``coordinate_map(tile,
        aux)`` form; the DEM is sampled here, window by window): a planned window's OpenCV
        maps when :meth:`source_plan` gave one, valid until this thread's next window."""
        window = getattr(tile, "window", tile)
        prepared = self._prepared(window)
        if prepared is not None:
            return self._compute_planned(window, *prepared)
        result = self._keep(window)
        self._local.kept = None
        return result[0], result[1]

    def _prepare(self, window: Any) -> Any:
        """``(transform, xs, ys, DEM part, plan)`` of a window that can be planned
        (:meth:`_plan`), else None."""
        if (self.cmap is None or self.incidence_writer is not None
                or self.to_orientation is not None or self.sampler.transformer is not None):
            return None
        xs, ys = self.grid.cell_centers(window)
        part = self.sampler.part(xs, ys)
        if part is None:
            return None
        transform = self.grid.window_transform(window)
        plan = self._plan(window, transform, part)
        if plan is None:
            return None
        prepared = (transform, xs, ys, part, plan)
        if plan.window is None:  # no map is asked: count its cells here
            self._compute_planned(window, *prepared)
        return prepared

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
            with self._write_lock:
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
        self.per_window[self._key(window)] = stats

    def _compute(self, window: Any):
        xs, ys = self.grid.cell_centers(window)
        cell_x, cell_y = self.grid.cell_size
        if (self.cmap is not None and self.incidence_writer is None
                and self.to_orientation is None and self.sampler.transformer is None):
            part = self.sampler.part(xs, ys)
            if part is not None:
                return self._compute_fused(window, xs, ys, part)
        if self.incidence_writer is not None:
            xh = np.concatenate([[xs[0] - cell_x], xs, [xs[-1] + cell_x]])
            yh = np.concatenate([[ys[0] + cell_y], ys, [ys[-1] - cell_y]])
            z_halo = self.sampler.heights(xh, yh)
            z = np.ascontiguousarray(z_halo[1:-1, 1:-1])
            angles = incidence_angle(xs, ys, z_halo, self.centre)[None]
            with self._write_lock:
                self.incidence_writer.write(angles, window=window)
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
            cols, rows, box = project_cells(self.camera, gx, gy, z)
            modes = np.zeros((0, 0), dtype=np.int8)  # no blocks: every point exact
        return self._finish(window, xs, ys, gx, gy, z, cols, rows, modes, box)

    def _finish(self, window: Any, xs: np.ndarray, ys: np.ndarray, gx: np.ndarray,
                gy: np.ndarray, z: np.ndarray, cols: np.ndarray, rows: np.ndarray,
                modes: np.ndarray, box: np.ndarray):
        """Visibility test (optional) and statistics of a window's map; ``(cols, rows, box or
        None)`` as :meth:`source_bounds` needs them."""
        cmin, rmin, cmax, rmax, missing = box
        stats = TileStatistics(cells=z.size)
        nan_z = np.isnan(z)
        stats.outside_dem = int(np.count_nonzero(nan_z))
        if self.surface is not None:
            if self._maxima is None:
                self._maxima = block_maxima(self.surface.z)
            hidden = visibility_mask(xs, ys, z, self.centre, self.surface, self._maxima)
            if self.mask_writer is not None:
                with self._write_lock:
                    self.mask_writer.write(np.where(nan_z, 255, hidden).astype(np.uint8)[None],
                                           window=window)
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
        self.per_window[self._key(window)] = stats
        return cols, rows, box if every_cell else None

    def _plan(self, window: Any, transform: Any, part: tuple) -> Any:
        """The :class:`~toolbox.raster.warp.SourcePlan` of a window (EMPTY_PLAN when its image
        misses the photo), None when it cannot be planned (no resampling given, a visibility
        test, no DEM height under it, or the bound of :meth:`CollinearityMap.source_box` does
        not exist)."""
        from toolbox.raster.warp import EMPTY_PLAN, plan_source

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
        keys = list(self.per_window)

        def contains(a, b):
            return (a != b and a[0] <= b[0] and a[1] <= b[1] and b[0] + b[2] <= a[0] + a[2]
                    and b[1] + b[3] <= a[1] + a[3])

        total = TileStatistics()
        for k in keys:
            if not any(contains(k, other) for other in keys):
                total.add(self.per_window[k])
        return total


def project_cells(camera: CameraModel, gx: np.ndarray, gy: np.ndarray, z: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The coordinate map of a window through any camera: ground cells ``gx``, ``gy`` (h, w) at
    heights ``z`` (h, w; NaN: none) -> float32 photo pixels ``(cols, rows)`` (h, w; NaN where
    the cell has no height or no image) and ``box`` (col_min, row_min, col_max, row_max, NaN
    count) of the finite ones. A :class:`~toolbox.cameras.GridProjector` camera does it in
    one compiled pass."""
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


def orientation_transformer(photo: Any, crs: Any) -> Any:
    """pyproj Transformer from the ortho's CRS to the orientation's (always_xy), or None when
    they are the same (or either is unknown)."""
    from toolbox.io.crs import parse_crs, same_crs

    eo_crs = photo.require_exterior().crs
    if eo_crs is None or crs is None:
        return None
    eo_crs, crs = parse_crs(eo_crs), parse_crs(crs)
    if same_crs(eo_crs, crs):
        return None
    from pyproj import Transformer

    return Transformer.from_crs(crs, eo_crs, always_xy=True)


def expected_accuracy(map_scale: float | None) -> dict[str, float] | None:
    """The seeds' rule (S002 par. 2.6.6): RMS at most ±0.3 mm (small scales) to ±0.5 mm (large
    scales) at the map scale, in ground metres."""
    if map_scale is None:
        return None
    return {"map_scale": float(map_scale), "rms_small_scale_m": 0.3 * map_scale / 1000.0,
            "rms_large_scale_m": 0.5 * map_scale / 1000.0}


def orthorectify(photo: Any, image: Any, dem: Any, grid: Any, output: Any,
                 options: OrthoOptions | None = None, surface: Any = None,
                 reference_height: float | None = None, mask_output: Any = None,
                 incidence_output: Any = None, map_scale: float | None = None,
                 feedback: Any = None) -> dict[str, Any]:
    """Orthorectify one photo onto ``grid`` and write ``output`` (GeoTIFF, or COG).

    Parameters
    ----------
    photo : Photo
        Oriented, with a pixel transform; its image size must equal the raster's.
    image : RasterInfo
        The photo raster (any GDAL format, 1-4 bands, 8/16 bit).
    dem : RasterInfo
        Terrain (or surface) heights, any CRS.
    grid : GridSpec
        Output grid (the orientation's CRS, or another: see :class:`OrthoWindows`).
    surface : DemSurface, optional
        The DEM around the photo (needed for the visibility test; read when missing).
    reference_height : float, optional
        Plane of the relief-displacement figure (default: the DEM's mean under the grid).
    mask_output, incidence_output : path, optional
        Occlusion mask (uint8: 1 hidden, 0 seen, 255 no height) and incidence angle (float32,
        degrees) on the same grid.

    Returns
    -------
    dict : the per-photo report (JSON-ready).
    """
    from pathlib import Path

    import rasterio

    from toolbox.feedback import Feedback
    from toolbox.io.crs import crs_label
    from toolbox.io.raster import geotiff_profile
    from toolbox.raster.engine import warp_to_geotiff
    from toolbox.raster.warp import single_threaded_opencv

    options = options or OrthoOptions()
    feedback = feedback or Feedback()
    size = photo.camera.image_size_px
    if size is not None and tuple(size) != (image.width, image.height):
        raise InputDataError(f"photo {photo.id!r}: the raster {image} is {image.width} x "
                             f"{image.height} px but the camera {photo.camera.name!r} says "
                             f"{size[0]} x {size[1]}: wrong image or camera")
    sampler = DemSampler(dem, grid.crs, options.band, options.dem_factor)
    sampler.preload(grid.bounds)
    to_orientation = orientation_transformer(photo, grid.crs)
    if to_orientation is not None and (options.occlusion or incidence_output is not None):
        raise InputDataError("the visibility test and the incidence angles need the ortho in "
                             "the orientation's CRS")
    # the film camera's compiled, planned map; a camera model's own project() otherwise
    cmap = None if photo.is_model else CollinearityMap(photo, options.block,
                                                      options.tolerance_px, image.width,
                                                      image.height)
    if options.occlusion and surface is None:
        surface = photo_surface(dem, photo, grid.crs, options.band)
    if reference_height is None:
        step = max(1, int(math.ceil(max(grid.width, grid.height) / 256)))
        xs, ys = grid.cell_centers(None)
        with warnings.catch_warnings():  # no height at all is reported just below
            warnings.simplefilter("ignore", RuntimeWarning)
            reference_height = float(np.nanmean(sampler.heights(xs[::step], ys[::step])))
        if not math.isfinite(reference_height):
            raise InputDataError(f"DEM {dem} has no height under the output grid of photo "
                                 f"{photo.id!r}")
    aux = []
    profile_args = (grid.width, grid.height, 1)
    output = Path(output)
    target = output.with_name(f".{output.stem}.gtiff.tif") if options.cog else output
    try:
        mask_writer = incidence_writer = None
        if mask_output is not None:
            if not options.occlusion:
                raise InputDataError("an occlusion mask needs the visibility test (OCCLUSION)")
            mask_writer = rasterio.open(mask_output, "w", **geotiff_profile(
                *profile_args, "uint8", grid.crs, grid.transform, 255))
            aux.append(mask_writer)
        if incidence_output is not None:
            incidence_writer = rasterio.open(incidence_output, "w", **geotiff_profile(
                *profile_args, "float32", grid.crs, grid.transform, float("nan")))
            aux.append(incidence_writer)
        windows = OrthoWindows(photo, grid, sampler, cmap, reference_height,
                               surface if options.occlusion else None, mask_writer,
                               incidence_writer, to_orientation, options.resampling)
        eo = photo.require_exterior()
        tags = {"ORTHO_PHOTO": photo.id, "ORTHO_MAP_TOLERANCE_PX": str(options.tolerance_px),
                "ORTHO_RESAMPLING": options.resampling, "NADIR_X": repr(eo.x0),
                "NADIR_Y": repr(eo.y0), "PROJECTION_CENTRE_Z": repr(eo.z0)}
        # the engine runs the windows on one thread per core, each its map then its remap
        with feedback.timed("orthorectify"), single_threaded_opencv():
            warp = warp_to_geotiff(image.path, windows, grid, target, options.resampling,
                                   options.outside, options.nodata, chunk=options.chunk,
                                   overviews=options.overviews and not options.cog,
                                   feedback=feedback.step(0, 90 if options.cog else 100),
                                   tags=tags)
        if options.cog:
            from rasterio.shutil import copy as raster_copy

            with feedback.timed("cog"):
                raster_copy(target, output, driver="COG", COMPRESS="DEFLATE", BLOCKSIZE=512,
                            OVERVIEWS="AUTO", NUM_THREADS="ALL_CPUS")
    finally:
        for dst in aux:
            dst.close()
        if options.cog and target != output and target.exists():
            target.unlink()
    windows.release()
    totals = windows.totals()
    photo_gsd = ground_sample_distance(photo, reference_height)
    cells = max(totals.cells, 1)
    report = {
        "photo": photo.id, "image": str(image.path),
        "crs": crs_label(grid.crs), "cell_size": grid.cell_size[0],
        "photo_gsd_m": photo_gsd, "reference_height": reference_height,
        "width": grid.width, "height": grid.height, "bounds": list(grid.bounds),
        "cells": totals.cells,
        "outside_dem_fraction": totals.outside_dem / cells,
        "outside_photo_fraction": totals.outside_photo / cells,
        "hidden_fraction": totals.hidden / cells if options.occlusion else None,
        "max_relief_displacement_m": totals.max_relief_m,
        "max_relief_displacement_px": totals.max_relief_m / photo_gsd,
        "map_tolerance_px": options.tolerance_px,
        "map_blocks": {"projective_exact": totals.blocks.get(0, 0),
                       "distortion_interpolated": totals.blocks.get(1, 0),
                       "distortion_exact": totals.blocks.get(2, 0)},
        "resampling": options.resampling, "dem_factor": options.dem_factor,
        "expected_accuracy": expected_accuracy(map_scale),
        "warp": warp.as_dict(),
    }
    if totals.outside_dem:
        feedback.push_warning(f"photo {photo.id}: {totals.outside_dem} of {totals.cells} cells "
                              f"({100 * totals.outside_dem / cells:.1f} %) have no DEM height "
                              "and are left empty")
    return report


@dataclass
class OrthoPlan:
    """What an ortho of one photo needs before warping: the DEM window the photo sees, its
    footprint on the DEM (8 points a side: for reports), the mean terrain height, the photo's
    GSD there, the output grid and ``extent``, the bounds of the footprint traced densely
    (:func:`footprint_points_per_side`): what the default grid covers."""

    photo: Any
    surface: Any
    footprint: Any  # shapely Polygon
    mean_height: float
    gsd: float
    grid: Any
    extent: tuple[float, float, float, float] | None = None


FOOTPRINT_STEP_PX = 16  # photo pixels between the monoplotted points of the footprint's outline


def footprint_points_per_side(photo: Any) -> int:
    """Points per side of the footprint outline: one every :data:`FOOTPRINT_STEP_PX` pixels of
    the longer side (at least 8, at most 1024; 256 when the image size is unknown)."""
    size = photo.camera.image_size_px
    if size is None:
        return 256
    return int(min(1024, max(8, math.ceil(max(size) / FOOTPRINT_STEP_PX))))


def plan_photo(photo: Any, dem: Any, crs: Any, band: int = 1, cell: float | None = None,
               bounds: tuple[float, float, float, float] | None = None,
               origin: tuple[float, float] = (0.0, 0.0), output_crs: Any = None) -> OrthoPlan:
    """Check the geometry and choose the grid of one photo's ortho.

    ``crs`` is the orientation's; ``output_crs`` the ortho's (default the same; then the
    footprint is transformed, densified, to bound the grid). Defaults (as the thesis' software
    proposes, S002 par. 3.8): cell = the photo's ground sample distance at the mean terrain
    height of its footprint (2 significant digits); extent = the footprint on the DEM (the frame
    outline monoplotted on the DEM at every :data:`FOOTPRINT_STEP_PX` photo pixels of its
    sides, so that a valley or a lens' curve between two samples is not cut off: 8 points a
    side cut up to 87 m of real coverage); edges on the lattice ``origin + k·cell``.
    """
    from toolbox.io.crs import parse_crs
    from toolbox.photogrammetry.coverage import photo_footprint
    from toolbox.photogrammetry.surface import dem_height_range

    crs = None if crs is None else parse_crs(crs)
    output_crs = crs if output_crs is None else parse_crs(output_crs)
    check_dem_crs(dem)
    check_geometry(photo)
    low, _ = dem_height_range(dem, band)
    check_geometry(photo, low)
    surface = photo_surface(dem, photo, crs, band)
    eo = photo.require_exterior()
    under = float(surface.height(np.array([eo.x0]), np.array([eo.y0]))[0])
    check_geometry(photo, under if math.isfinite(under) else None)
    plane = float(np.nanmean(surface.z))
    polygon = photo_footprint(photo, surface, plane, 8).polygon  # mean height, reports
    outline = photo_footprint(photo, surface, plane, footprint_points_per_side(photo)).polygon
    mean_height = mean_height_inside(surface, polygon)
    gsd = ground_sample_distance(photo, mean_height)
    cell = nice_cell_size(gsd) if cell is None else float(cell)
    to_orientation = orientation_transformer(photo, output_crs)
    if to_orientation is not None:
        import shapely

        def to_output(xy: np.ndarray) -> np.ndarray:
            x, y = to_orientation.transform(xy[:, 0], xy[:, 1], direction="INVERSE")
            return np.column_stack([x, y])

        dense = shapely.segmentize(shapely.force_2d(polygon), max(polygon.length / 400.0, cell))
        polygon = shapely.transform(dense, to_output)
        outline = shapely.transform(shapely.segmentize(shapely.force_2d(outline), max(
            outline.length / 400.0, cell)), to_output)
    extent = tuple(float(v) for v in outline.union(polygon).bounds)
    grid = lattice_grid(extent if bounds is None else bounds, cell, output_crs, origin)
    return OrthoPlan(photo, surface, polygon, mean_height, gsd, grid, extent)


# -- whole blocks ---------------------------------------------------------------------------------------
@dataclass
class OrthoTask:
    """One photo of a block: everything :func:`run_task` needs (picklable, for Dask workers)."""

    photo: Any
    image: Any  # RasterInfo
    dem: Any  # RasterInfo
    grid: Any
    output: Any  # final path
    options: OrthoOptions
    reference_height: float
    map_scale: float | None = None


def run_task(task: OrthoTask) -> dict[str, Any]:
    """Orthorectify one photo of a block into a hidden file beside ``task.output``, renamed on
    success; a user error is returned as ``{"photo", "error"}`` (the block goes on)."""
    import os
    from pathlib import Path

    from toolbox.errors import ToolboxError
    from toolbox.feedback import CollectingFeedback

    final = Path(task.output)
    partial = final.with_name(f".{final.stem}.part{final.suffix}")
    feedback = CollectingFeedback()  # its caller reports the warnings, once
    try:
        report = orthorectify(task.photo, task.image, task.dem, task.grid, partial, task.options,
                              None, task.reference_height, map_scale=task.map_scale,
                              feedback=feedback)
        os.replace(partial, final)
    except ToolboxError as exc:
        return {"photo": task.photo.id, "error": str(exc)}
    finally:
        if partial.exists():
            partial.unlink()
    report["output"] = str(final)
    report["warnings"] = feedback.warnings
    return report
