"""Terrain surfaces for image -> ground: a DEM grid (bilinear between cell centres, the edge value
held across the outer half cell) read in a window.

A :class:`DemSurface` holds a north-up height grid as float64 with NaN for nodata, and the centre
of its first cell, so monoplotting and footprints never need the whole raster: only the window a
photo's rays can reach (:func:`read_dem_window`).
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.io.raster import read_filled


@dataclass(frozen=True, eq=False)
class DemSurface:
    """A north-up height grid.

    Attributes
    ----------
    z : (rows, cols) float64
        Heights, NaN for nodata; row 0 is the north edge.
    x0, y0 : float
        Ground coordinates of the centre of cell ``[0, 0]``.
    cell_x, cell_y : float
        Cell sizes (> 0); columns go east, rows go south.
    crs : pyproj.CRS or None
    """

    z: np.ndarray
    x0: float
    y0: float
    cell_x: float
    cell_y: float
    crs: Any = None

    def __post_init__(self) -> None:
        z = np.ascontiguousarray(self.z, dtype="float64")
        if z.ndim != 2 or min(z.shape) < 2:
            raise InputDataError(f"a DEM needs at least 2 x 2 cells, got shape {z.shape}")
        if not (self.cell_x > 0 and self.cell_y > 0):
            raise InputDataError(f"DEM cell sizes must be > 0, got {self.cell_x}, {self.cell_y}")
        if not np.isfinite(z).any():
            raise InputDataError("the DEM window holds no valid height (all nodata)")
        object.__setattr__(self, "z", z)

    @classmethod
    def from_transform(cls, z: np.ndarray, transform: Any, crs: Any = None,
                       nodata: float | None = None) -> DemSurface:
        """From an array and its affine transform (north-up, ``b = d = 0``); ``nodata`` -> NaN."""
        from toolbox.io.raster import without_negligible_rotation

        transform = without_negligible_rotation(transform, np.shape(z)[-1], np.shape(z)[-2])
        if transform.b != 0 or transform.d != 0 or transform.a <= 0 or transform.e >= 0:
            raise InputDataError("the DEM must be north-up (no rotation, rows going south)")
        z = np.asarray(z, dtype="float64")
        if nodata is not None and np.isfinite(nodata):
            z = np.where(z == nodata, np.nan, z)
        return cls(z, transform.c + 0.5 * transform.a, transform.f + 0.5 * transform.e,
                   transform.a, -transform.e, crs)

    @property
    def shape(self) -> tuple[int, int]:
        return self.z.shape

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """Extent of the cells (where heights are defined: bilinear between the centres, the
        edge value held across the outer half cell): xmin, ymin, xmax, ymax."""
        rows, cols = self.z.shape
        hx, hy = 0.5 * self.cell_x, 0.5 * self.cell_y
        return (self.x0 - hx, self.y0 - (rows - 0.5) * self.cell_y,
                self.x0 + (cols - 0.5) * self.cell_x, self.y0 + hy)

    @property
    def z_range(self) -> tuple[float, float]:
        return float(np.nanmin(self.z)), float(np.nanmax(self.z))

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear heights at ground points, the edge value held across the outer half cell
        (as the monoplot kernel's ``_dem_height``); NaN beyond the cells or on nodata."""
        from toolbox.raster.bilinear import bilinear

        x, y = np.broadcast_arrays(np.asarray(x, dtype="float64"), np.asarray(y, dtype="float64"))
        xy = np.column_stack([x.ravel(), y.ravel()])
        return bilinear(self.z, self.x0, self.y0, self.cell_x, -self.cell_y, xy,
                        half_cell=True).reshape(x.shape)

    def kernel_arguments(self) -> tuple:
        """``(z, x0, y0, cell_x, cell_y, zmin, zmax)`` as the monoplot kernel takes them."""
        zmin, zmax = self.z_range
        return (self.z, float(self.x0), float(self.y0), float(self.cell_x), float(self.cell_y),
                zmin, zmax)


def read_dem_window(info: Any, bounds: tuple[float, float, float, float] | None = None,
                    band: int = 1, margin_cells: int = 2) -> DemSurface:
    """Read the part of a DEM raster (a :class:`~toolbox.io.raster.RasterInfo`) covering
    ``bounds`` (xmin, ymin, xmax, ymax, ground units) plus ``margin_cells``; all of it if None.

    Raises :class:`InputDataError` when the bounds miss the raster or the window is all nodata.
    """
    from affine import Affine
    from rasterio.windows import Window

    from toolbox.io.raster import require_north_up

    require_north_up(info.transform, "DEM", info.path)  # with the gdalwarp command
    if bounds is None:
        window = Window(0, 0, info.width, info.height)
    else:
        inverse = ~info.transform
        corners = [inverse @ (x, y) for x in bounds[0::2] for y in bounds[1::2]]
        cols, rows = zip(*corners, strict=True)
        col0 = max(int(np.floor(min(cols))) - margin_cells, 0)
        row0 = max(int(np.floor(min(rows))) - margin_cells, 0)
        col1 = min(int(np.ceil(max(cols))) + margin_cells, info.width)
        row1 = min(int(np.ceil(max(rows))) + margin_cells, info.height)
        if col1 - col0 < 2 or row1 - row0 < 2:
            raise InputDataError(f"DEM {info} does not cover the area needed "
                                 f"({', '.join(f'{v:.1f}' for v in bounds)})")
        window = Window(col0, row0, col1 - col0, row1 - row0)
    data = read_dem_cells(info.path, band, window, (info.height, info.width))
    transform = info.transform @ Affine.translation(window.col_off, window.row_off)
    return DemSurface.from_transform(data, transform, info.crs)


#: a DEM band of at most this many cells (8 MB as float64) is read whole once per process and
#: its windows sliced from memory (:func:`read_dem_cells`): an ortho run read the same small
#: DEM 2-3 times a photo, each open of a GeoTIFF with a compound CRS 5-8 ms CPU (GDAL builds
#: the CRS from PROJ's database at every open)
SMALL_DEM_CELLS = 1 << 20
_WHOLE_DEM: dict[tuple, np.ndarray] = {}  # the last small DEM band read, by (path, mtime, size)
_WHOLE_DEM_LOCK = threading.Lock()


def read_dem_cells(path: Any, band: int, window: Any, shape: tuple[int, int]) -> np.ndarray:
    """Cells ``window`` (a rasterio Window inside the raster) of band ``band`` of the DEM at
    ``path`` (``shape`` its rows and columns), float64, NaN where the DEM's mask says no data:
    a new array. A DEM of at most :data:`SMALL_DEM_CELLS` cells is read whole once (the last
    one kept, while its file is unchanged) and the windows sliced from it: the same values as
    GDAL's windowed reads."""
    import rasterio

    rows, cols = shape
    r0, c0 = int(window.row_off), int(window.col_off)
    r1, c1 = r0 + int(window.height), c0 + int(window.width)
    inside = 0 <= r0 < r1 <= rows and 0 <= c0 < c1 <= cols
    if inside and rows * cols <= SMALL_DEM_CELLS:
        try:
            st = os.stat(path)
        except OSError:
            st = None
        if st is not None:
            key = (str(path), st.st_mtime_ns, st.st_size, int(band), rows, cols)
            with _WHOLE_DEM_LOCK:
                whole = _WHOLE_DEM.get(key)
                if whole is None:
                    with rasterio.open(path) as src:
                        whole = read_filled(src, band)
                    if whole.shape == (rows, cols):
                        _WHOLE_DEM.clear()
                        _WHOLE_DEM[key] = whole
            if whole.shape == (rows, cols):
                return whole[r0:r1, c0:c1].copy()
    with rasterio.open(path) as src:
        return read_filled(src, band, window)


def dem_height_range(info: Any, band: int = 1) -> tuple[float, float]:
    """Approximate (overview-based) min and max height of a DEM raster, as GDAL computes them.

    GDAL's PAM is off meanwhile, so no ``.aux.xml`` is written beside the input.
    """
    import rasterio

    with rasterio.Env(GDAL_PAM_ENABLED="NO"), rasterio.open(info.path) as src:
        stats = src.stats(indexes=[band], approx=True)[0]
    if not (np.isfinite(stats.min) and np.isfinite(stats.max)):
        raise InputDataError(f"DEM {info} holds no valid height")
    return float(stats.min), float(stats.max)


def photo_ground_bounds(photo: Any, z_low: float, z_high: float,
                        within: tuple[float, float, float, float] | None = None
                        ) -> tuple[float, float, float, float]:
    """Bounding box (xmin, ymin, xmax, ymax) of the ground a photo's frame can see between the
    heights ``z_low`` and ``z_high``, cut to ``within`` (the DEM's extent) when given.

    When every corner ray descends, the region is the convex frustum slice between ``z_low``
    and ``min(z_high, Z0)`` (the projection centre itself when it flies below ``z_high``: a
    drone in a valley), bounded by its corners. When the frame holds the horizon (corner rays
    level or rising) the region is unbounded: the wedge the rays' horizontal directions span,
    cut to ``within``. :class:`InputDataError` when the rays never reach those heights, or the
    region is unbounded and ``within`` is not given.
    """
    eo = photo.require_exterior()
    x0, y0, z0 = eo.x0, eo.y0, eo.z0
    corners = photo.frame_outline_mm(1)
    down = photo.image_to_ground(corners, z0 - 1.0, invalid="nan")
    descending = np.isfinite(down[:, 0])
    if descending.all():
        heights = [z for z in (z_low, min(z_high, z0)) if z < z0]
        if not heights:
            raise InputDataError(f"photo {photo.id!r}: its rays all descend from Z0 = {z0:.2f} "
                                 f"and never reach the terrain's heights ({z_low:.2f} to "
                                 f"{z_high:.2f}); check Z0 and the DEM's height datum")
        pts = np.vstack([photo.image_to_ground(corners, z) for z in heights] +
                        ([np.array([[x0, y0, z0]])] if z_high >= z0 else []))
        box = (float(pts[:, 0].min()), float(pts[:, 1].min()), float(pts[:, 0].max()),
               float(pts[:, 1].max()))
        if within is None:
            return box
        return (max(box[0], within[0]), max(box[1], within[1]), min(box[2], within[2]),
                min(box[3], within[3]))
    what = f"photo {photo.id!r}: its frame holds the horizon (rays level or rising)"
    if within is None:
        raise InputDataError(f"{what}: the ground it sees is unbounded")
    up = photo.image_to_ground(corners, z0 + 1.0, invalid="nan")
    ends = np.where(descending[:, None], down, up)[:, :2] - (x0, y0)
    if not np.isfinite(ends).all() or z0 > z_high and not descending.any():
        return within  # a corner ray exactly level, or every ray above the terrain's heights
    import shapely

    # the wedge of horizontal directions, cut at a distance beyond every corner of `within`
    angles = np.arctan2(ends[:, 1], ends[:, 0])
    order = np.argsort(angles)
    gaps = np.diff(np.concatenate([angles[order], angles[order][:1] + 2 * np.pi]))
    if gaps.max() <= np.pi:  # the directions surround the nadir: every direction
        return within
    start = (int(np.argmax(gaps)) + 1) % len(order)
    spread = 2 * np.pi - gaps.max()
    reach = np.hypot(np.array(within[0::2]) - x0, np.array(within[1::2])[:, None] - y0).max()
    turns = np.linspace(0.0, spread, max(3, int(np.ceil(spread / 0.2)) + 1))
    far = reach / np.cos(0.5 * (turns[1] - turns[0])) + 1.0
    arc = angles[order][start] + turns
    wedge = shapely.Polygon([(x0, y0)] + list(zip(x0 + far * np.cos(arc), y0 + far * np.sin(arc),
                                                  strict=True)))
    cut = wedge.intersection(shapely.box(*within))
    if cut.is_empty:
        raise InputDataError(f"{what} and looks away from the DEM")
    return tuple(float(v) for v in cut.bounds)


def surface_for_photo(info: Any, photo: Any, band: int = 1,
                      z_range: tuple[float, float] | None = None) -> DemSurface:
    """The DEM window that every ray of ``photo``'s frame can meet (approximate height range
    widened by 10% and 1 m)."""
    z_low, z_high = dem_height_range(info, band) if z_range is None else z_range
    pad = 0.1 * (z_high - z_low) + 1.0
    return read_dem_window(info, photo_ground_bounds(photo, z_low - pad, z_high + pad,
                                                     info.bounds), band)
