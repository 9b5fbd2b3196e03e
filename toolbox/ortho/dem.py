"""The DEM as a source of heights for output windows: :class:`DemSampler` (windowed reads,
coarsening, another CRS through a checked lattice transform)."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from toolbox.errors import ParameterError


class DemSampler:
    """Heights of output cells from a DEM raster, one window per call.

    The DEM may be in another CRS than the output (``crs``): the cell centres are then
    transformed with pyproj (always_xy) and the heights taken bilinearly in the DEM's own grid.
    A DEM whose CRS differs only by a vertical part (a compound CRS such as UTM + EGM2008
    height) is read directly: its heights are taken as they are
    (:func:`toolbox.io.crs.one_horizontal_crs`, which also takes two definitions of one CRS, an
    ESRI WKT and its EPSG code, as one on the DEM's extent).
    ``factor`` > 1 projects on a coarser DEM (the thesis' "fattore di ricampionamento"): the mean
    of ``factor`` x ``factor`` DEM cells, on a lattice fixed to the DEM's origin (no tile seams).
    Where ``factor`` does not divide the DEM's width (height), the last coarse column (row) is a
    partial block: the mean of the DEM cells it holds (nodata cells left out, as in every
    block), centred at the centre of those cells and ending at the DEM's edge, so that
    the coarse DEM covers the DEM's whole extent with the edge value held across its outer half
    block as everywhere else. Its centre is off the regular lattice, which the kernels take:
    the coordinates between the last full block's centre and the DEM's edge are mapped onto the
    regular lattice (:meth:`_lattice`: piecewise linear, exact at the nodes) before the
    kernels, and :meth:`part` leaves such windows to :meth:`heights`.
    """

    def __init__(self, info: Any, crs: Any = None, band: int = 1, factor: int = 1):
        self.path = info.path  # read on a Dask worker in the client's folder when not preloaded
        self.band = int(band)
        self.factor = max(1, int(factor))
        t = info.transform
        if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:
            from toolbox.io.raster import require_north_up

            require_north_up(t, "DEM", info.path)  # with the gdalwarp command
        self.transform = t
        self.shape = (info.height, info.width)
        k = self.factor
        self.coarse_shape = (-(-info.height // k), -(-info.width // k))  # with partial blocks
        if k > 1 and min(self.coarse_shape) < 2:  # bilinear heights need 2 x 2 coarse cells
            raise ParameterError("DEM_FACTOR", f"is {k}, which leaves the DEM {info} "
                                 f"({info.width} x {info.height} cells) less than 2 coarse "
                                 f"cells across; expected at most "
                                 f"{max(1, min(info.width, info.height) - 1)}")
        self.nodata = info.nodata
        self.transformer = None
        from toolbox.io.crs import one_horizontal_crs

        if info.crs is not None and crs is not None and \
                not one_horizontal_crs(info.crs, crs, info.bounds):
            from pyproj import Transformer

            self.transformer = Transformer.from_crs(crs, info.crs, always_xy=True)
        self._cache: tuple | None = None  # (i0, j0, array) of coarse cells held in memory
        self.compiled = True  # numba's kernels (toolbox.ortho.heights), else NumPy's (grid_numpy)

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
        j1 = min(int(math.ceil(c1 / k)) + 1, self.coarse_shape[1])
        i1 = min(int(math.ceil(r1 / k)) + 1, self.coarse_shape[0])
        if j1 - j0 < 2 or i1 - i0 < 2:
            return None
        return i0, i1, j0, j1

    def _load(self, i0: int, i1: int, j0: int, j1: int) -> np.ndarray:
        """Coarse cells [i0:i1, j0:j1] (means of the k x k DEM cells of a block, of those it
        holds for a partial last block), float64, NaN for nodata."""
        from rasterio.windows import Window

        from toolbox.photogrammetry.surface import read_dem_cells

        k = self.factor
        rows, cols = self.shape
        c1, r1 = min(j1 * k, cols), min(i1 * k, rows)
        window = Window(j0 * k, i0 * k, c1 - j0 * k, r1 - i0 * k)
        data = read_dem_cells(self.path, self.band, window, self.shape)
        if k > 1:
            if data.shape != ((i1 - i0) * k, (j1 - j0) * k):  # partial blocks: NaN-padded
                full = np.full(((i1 - i0) * k, (j1 - j0) * k), np.nan)
                full[:data.shape[0], :data.shape[1]] = data
                data = full
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

    def _lattice(self, values: np.ndarray, axis: int) -> np.ndarray:
        """Coordinates ``values`` (DEM CRS) along ``axis`` (0: y, 1: x) mapped onto the regular
        coarse lattice the kernels take: ``values`` itself (the same object) unless the axis
        ends in a partial block (:class:`DemSampler`). Then, in lattice units (node j at j),
        the points between the last full node ``n - 2`` and the partial block's true centre
        ``c`` are stretched linearly onto ``[n - 2, n - 1]``, those between ``c`` and the DEM's
        edge ``e`` go to node ``n - 1`` (the edge value held), those beyond ``e`` to ``n + 1``
        (outside every part: no height); the others are left as they are (bit for bit)."""
        k, cells = self.factor, self.shape[axis]
        if cells % k == 0:
            return values
        t = self.transform
        origin, step = (t.f, t.e * k) if axis == 0 else (t.c, t.a * k)
        n = self.coarse_shape[axis]
        f = (np.asarray(values, dtype="float64") - origin) / step - 0.5
        last = n - 2.0
        beyond = f > last
        if n < 2 or not beyond.any():
            return values
        edge = cells / k - 0.5
        centre = 0.5 * (last + cells / k)  # of the partial block's cells, (n - 1.5 + e) / 2
        g = np.minimum(last + (f - last) / (centre - last), n - 1.0)
        g = np.where(f > edge, n + 1.0, g)
        return np.where(beyond, origin + (g + 0.5) * step, values)

    def part(self, xs: np.ndarray, ys: np.ndarray) -> tuple | None:
        """The DEM cells under the grid ``xs`` x ``ys`` (output CRS = the DEM's) as
        :func:`~toolbox.ortho.heights.heights_on_grid` takes them: (contiguous float64
        array, x and y of the centre of its cell [0, 0], cell width and height); None outside
        the DEM, or where the grid reaches a partial last coarse block (off the regular
        lattice: :meth:`heights` maps those). ``xs`` and ``ys`` are monotonic (cell centres):
        their ends bound them."""
        if self.transformer is None and (self._lattice(xs, 1) is not xs
                                         or self._lattice(ys, 0) is not ys):
            return None
        x0, x1, y0, y1 = float(xs[0]), float(xs[-1]), float(ys[0]), float(ys[-1])
        part = self._read((min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)))
        if part is None:
            return None
        return (np.ascontiguousarray(part[0]), *part[1:])

    def heights(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Heights (h, w) float64 at the grid of cell centres ``xs`` (w,) x ``ys`` (h,) (output
        CRS), NaN where the DEM has none."""
        if self.compiled:
            from toolbox.ortho.heights import heights_at_points, heights_on_grid
        else:
            from toolbox.ortho.grid_numpy import heights_at_points, heights_on_grid
        xs = np.ascontiguousarray(xs, dtype="float64")
        ys = np.ascontiguousarray(ys, dtype="float64")
        out = np.full((len(ys), len(xs)), np.nan)
        if self.transformer is None:
            part = self._read((min(xs[0], xs[-1]), min(ys[0], ys[-1]), max(xs[0], xs[-1]),
                               max(ys[0], ys[-1])))
            if part is not None:
                heights_on_grid(np.ascontiguousarray(part[0]), *part[1:],
                                np.ascontiguousarray(self._lattice(xs, 1)),
                                np.ascontiguousarray(self._lattice(ys, 0)), out)
            return out
        dx, dy = self._to_dem(xs, ys)
        finite = np.isfinite(dx) & np.isfinite(dy)
        if not finite.any():
            return out
        part = self._read((dx[finite].min(), dy[finite].min(), dx[finite].max(),
                           dy[finite].max()))
        if part is not None:
            flat = out.ravel()
            dx = np.ascontiguousarray(self._lattice(dx, 1), dtype="float64")
            dy = np.ascontiguousarray(self._lattice(dy, 0), dtype="float64")
            heights_at_points(np.ascontiguousarray(part[0]), *part[1:], dx, dy, flat)
            out = flat.reshape(out.shape)
        return out


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
