"""Orthorectification kernels: the collinearity coordinate map of an output tile on a DEM, DEM
heights per tile, visibility (true ortho), incidence angle, relief displacement, GSD.

Method (indirect differential rectification; domain brief section 15, S002 par. 2.6.5 and 3.8):
for every output cell centre take Z from the DEM (bilinear between DEM cell centres), project
``(X, Y, Z)`` into the photo with the collinearity equations (brief section 4), add radial
distortion and the principal point, apply the fiducial -> pixel transform, and sample the photo
there (:mod:`toolbox.raster.warp`).

**Exact where it is cheap, interpolated where it is safe.** The collinearity equations without
distortion are a 3 x 4 projective matrix applied to ``(X, Y, Z, 1)``: the kernel evaluates them
exactly at every cell (a dozen multiply-adds and one division), so relief inside a tile costs no
accuracy. Only the radial distortion (a Newton solve per point) is done on a coarse grid: per
block of ``block`` x ``block`` cells its pixel correction (exact pixel minus distortion-free
pixel) is evaluated exactly at the block's corner cells and blended bilinearly inside, *only*
when the blend's error is provably below ``tolerance_px``. The bound is checked per block, not
sampled: with ``L`` the Lipschitz constant of the distortion field ``δ(p) = measured(p) - p``
(from the camera's table or polynomial), ``κ`` the condition number of the fiducial -> pixel
transform and ``D`` the diagonal of the block's distortion-free pixel box, the correction is
``κ·L``-Lipschitz in pixel space, so a blend of corner values (weights >= 0, sum 1) differs from
the exact correction by at most ``κ·L·D`` pixels. Blocks over the bound (very strong
distortion, cliffs that spread a block over many photo pixels) are computed exactly. Default
bound :data:`DEFAULT_TOLERANCE_PX` = 0.05 px.

Conventions as :mod:`toolbox.photogrammetry`: photo pixels ``(col, row)`` from the top-left corner,
centres at +0.5; output grids north-up, column ``j`` centre ``x = xmin + (j + 0.5)·cell``.
Kernels take arrays and numbers; :class:`DemSampler` is the only reader (one DEM window per
tile, handed to the kernels as an array). The per-tile kernels are single-threaded and release
the GIL (``nogil``): parallelism comes from running tiles or photos side by side; an OpenMP
region per tile costs more than it saves on a busy 2-core machine (measured: 3 ms single-threaded
against 22-31 ms with two spinning threads for one 1024 x 1024 tile).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit, prange

from toolbox.errors import InputDataError
from toolbox.photogrammetry.kernels import _dem_height, _distort, _project2d, _tuple9

DEFAULT_BLOCK = 64  # coarse-grid step of the distortion, cells: the thesis' 64, fastest measured
DEFAULT_TOLERANCE_PX = 0.05  # largest interpolation error accepted, photo pixels
#: block modes written by the kernel
BLOCK_PROJECTIVE, BLOCK_INTERPOLATED, BLOCK_EXACT = 0, 1, 2


# -- sensor model -----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SensorModel:
    """A photo's ground -> pixel model as plain arrays for the kernels.

    ``centre`` (3,), ``rot`` R(omega, phi, kappa) (3, 3), ``c`` mm, ``pp`` (2,) mm, the distortion
    arguments of :meth:`RadialDistortion.kernel_arguments`, ``f2p`` the fiducial -> pixel matrix,
    ``lipschitz`` the bound of ``|dδ/dp|`` of the distortion field, ``px_per_mm`` the largest
    scale of ``f2p`` (pixels per image mm) and ``f2p_condition`` its condition number.
    """

    centre: np.ndarray
    rot: np.ndarray
    c: float
    pp: np.ndarray
    distortion: tuple
    f2p: np.ndarray
    lipschitz: float
    px_per_mm: float
    f2p_condition: float
    width: int
    height: int

    @classmethod
    def from_photo(cls, photo: Any, width: int | None = None, height: int | None = None
                   ) -> SensorModel:
        eo = photo.require_exterior()
        cam = photo.camera
        f2p = np.ascontiguousarray(photo.require_pixel_transform().fiducial_to_pixel,
                                   dtype="float64")
        from toolbox.photogrammetry.collinearity import _distortion_args

        size = cam.image_size_px
        w, h = (width, height) if width is not None else (size or (None, None))
        if w is None:
            raise InputDataError(f"photo {photo.id!r}: the image size is unknown")
        return cls(eo.centre, np.ascontiguousarray(eo.rotation), float(cam.c),
                   np.asarray(cam.principal_point_mm, dtype="float64"),
                   _distortion_args(cam.distortion),
                   f2p, distortion_lipschitz(cam.distortion, _frame_radius(photo, w, h)),
                   *_pixel_scale(f2p, photo, w, h), int(w), int(h))


def _frame_radius(photo: Any, width: int, height: int) -> float:
    """Largest radius (mm) of the photo's corners from the principal point, times 1.5."""
    p2f = np.linalg.inv(photo.require_pixel_transform().fiducial_to_pixel)
    corners = np.array([[0, 0, 1], [width, 0, 1], [width, height, 1], [0, height, 1]], float)
    mm = corners @ p2f.T
    mm = mm[:, :2] / mm[:, 2:] - np.asarray(photo.camera.principal_point_mm)
    return 1.5 * float(np.hypot(mm[:, 0], mm[:, 1]).max())


def _pixel_scale(f2p: np.ndarray, photo: Any, width: int, height: int) -> tuple[float, float]:
    """Largest singular value of the fiducial -> pixel Jacobian at the frame's corners and centre
    (pixels per mm) and its condition number (largest / smallest singular value), plus 2 %."""
    p2f = np.linalg.inv(f2p)
    largest, smallest = 0.0, np.inf
    for col, row in ((0, 0), (width, 0), (width, height), (0, height), (width / 2, height / 2)):
        q = p2f @ np.array([col, row, 1.0])
        x, y = q[0] / q[2], q[1] / q[2]
        w = f2p[2, 0] * x + f2p[2, 1] * y + f2p[2, 2]
        u = (f2p[0, 0] * x + f2p[0, 1] * y + f2p[0, 2]) / w
        v = (f2p[1, 0] * x + f2p[1, 1] * y + f2p[1, 2]) / w
        jac = (f2p[:2, :2] - np.outer([u, v], f2p[2, :2])) / w
        sv = np.linalg.svd(jac, compute_uv=False)
        largest, smallest = max(largest, float(sv[0])), min(smallest, float(sv[-1]))
    return 1.02 * largest, 1.02 * largest / smallest


def distortion_lipschitz(distortion: Any, radius_mm: float) -> float:
    """Bound of the Jacobian norm of ``δ(p) = distort(p) - p`` for ideal radii up to ``radius_mm``.

    The field is radial, so its Jacobian has the eigenvalues ``Δr'/(1 - Δr')`` (radial) and
    ``Δr(r)/r_ideal`` (tangential), with ``r - Δr(r) = r_ideal``. A table is piecewise linear:
    the first is largest on a segment, the second at a node or at r -> 0. A polynomial is
    sampled densely on [0, 1.05 radius]. The result is widened by 5 %.
    """
    if distortion is None:
        return 0.0
    from toolbox.photogrammetry.camera import DISTORTION_TABLE

    if distortion.mode == DISTORTION_TABLE:
        r, d = distortion.r_mm, distortion.dr_mm
        slopes = np.diff(d) / np.diff(r)
        radial = np.abs(slopes) / np.maximum(1.0 - np.abs(slopes), 1e-9)
        nodes = r > 0
        tangential = np.abs(d[nodes]) / np.maximum(r[nodes] - np.abs(d[nodes]), 1e-12)
        bound = max(float(radial.max()), float(tangential.max(initial=0.0)))
    else:
        rr = np.linspace(0.0, 1.05 * radius_mm, 4097)[1:]
        k1, k2 = distortion.k1, distortion.k2
        value = k1 * rr ** 3 + k2 * rr ** 5
        slope = 3 * k1 * rr ** 2 + 5 * k2 * rr ** 4
        radial = np.abs(slope) / np.maximum(1.0 - np.abs(slope), 1e-9)
        tangential = np.abs(value) / np.maximum(rr - np.abs(value), 1e-12)
        bound = max(float(radial.max()), float(tangential.max()))
    return 1.05 * bound


# -- the coordinate map kernel ----------------------------------------------------------------------
def tile_matrices(model: SensorModel, gx0: float, gy0: float, cx: float, cy: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The collinearity equations of a tile as 3 x 4 matrices on ``(j, i, Z, 1)`` (cell column,
    cell row, height): ``A`` gives ``(n1, n2, den)`` with ideal image mm ``ξ = -c·n1/den``,
    ``η = -c·n2/den`` (brief section 4; ``den < 0`` in front of the camera) and ``M`` the
    homogeneous photo pixel ``(col·w, row·w, w)`` without distortion (principal point and
    fiducial -> pixel included). Cell ``[i, j]`` has its centre at ``(gx0 + j·cx, gy0 - i·cy)``;
    the constant column is computed relative to the projection centre (no large numbers)."""
    rt = model.rot.T
    shift = np.array([[cx, 0.0, 0.0, gx0 - model.centre[0]],
                      [0.0, -cy, 0.0, gy0 - model.centre[1]],
                      [0.0, 0.0, 1.0, -model.centre[2]]])
    a = rt @ shift
    k = np.array([[-model.c, 0.0, model.pp[0]], [0.0, -model.c, model.pp[1]], [0.0, 0.0, 1.0]])
    m = model.f2p @ k @ a
    return np.ascontiguousarray(a), np.ascontiguousarray(m)


@njit(cache=True, nogil=True)
def project_tile_projective(z, a, m, cols, rows, box):
    """Source pixels of a tile without distortion: exactly ``M·(j, i, Z, 1)`` per cell (see
    :func:`tile_matrices`), NaN where Z is NaN or the point is not in front of the camera.
    ``box`` (5,) gets the bounding box of the finite coordinates (col_min, row_min, col_max,
    row_max) and the number of NaN cells."""
    h, w = z.shape
    cmin = rmin = 1e300
    cmax = rmax = -1e300
    missing = 0
    for i in range(h):
        ud = m[0, 1] * i + m[0, 3]
        vd = m[1, 1] * i + m[1, 3]
        wd = m[2, 1] * i + m[2, 3]
        dd = a[2, 1] * i + a[2, 3]
        for j in range(w):
            zc = z[i, j]
            den = dd + a[2, 0] * j + a[2, 2] * zc
            if den < 0.0:
                q = 1.0 / (wd + m[2, 0] * j + m[2, 2] * zc)
                u = (ud + m[0, 0] * j + m[0, 2] * zc) * q
                v = (vd + m[1, 0] * j + m[1, 2] * zc) * q
                cols[i, j] = u
                rows[i, j] = v
                cmin = min(cmin, u)
                cmax = max(cmax, u)
                rmin = min(rmin, v)
                rmax = max(rmax, v)
            else:  # behind the camera, or NaN height
                cols[i, j] = np.nan
                rows[i, j] = np.nan
                missing += 1
    box[0], box[1], box[2], box[3], box[4] = cmin, rmin, cmax, rmax, missing


@njit(cache=True, inline="always")
def _ideal(a, j, i, zc, c):
    """Ideal image mm (relative to the principal point) of cell (j, i) at height zc; ok flag."""
    den = a[2, 0] * j + a[2, 1] * i + a[2, 2] * zc + a[2, 3]
    if not den < 0.0:
        return 0.0, 0.0, False
    q = -c / den
    return ((a[0, 0] * j + a[0, 1] * i + a[0, 2] * zc + a[0, 3]) * q,
            (a[1, 0] * j + a[1, 1] * i + a[1, 2] * zc + a[1, 3]) * q, True)


@njit(cache=True, nogil=True)
def project_tile_distorted(z, a, m, c, pp, dmode, dr, dd, dk, di, f2p, lipschitz_px, block,
                           tolerance_px, cols, rows, modes, box):
    """Source pixels of a tile with radial distortion (see the module docstring).

    Per block of ``block`` x ``block`` cells: the distortion-free pixels exactly at every cell
    (``M`` of :func:`tile_matrices`); the distortion's pixel correction exactly at the block's
    four corner cells (ideal point -> distortion -> principal point -> fiducial -> pixel, minus
    the distortion-free pixel) and blended bilinearly inside when ``lipschitz_px·D <=
    tolerance_px``, D the diagonal of the block's distortion-free pixel box; otherwise every cell
    exactly. ``modes`` (blocks_y, blocks_x) gets BLOCK_INTERPOLATED or BLOCK_EXACT; ``box`` as
    in :func:`project_tile_projective`.
    """
    h, w = z.shape
    nby = (h + block - 1) // block
    nbx = (w + block - 1) // block
    mt = _tuple9(f2p)
    px, py = pp[0], pp[1]
    cmin = rmin = 1e300
    cmax = rmax = -1e300
    missing = 0
    for b in range(nby * nbx):
        bi = b // nbx
        bj = b - bi * nbx
        i0 = bi * block
        j0 = bj * block
        i1 = min(i0 + block, h) - 1
        j1 = min(j0 + block, w) - 1
        umin = vmin = 1e300
        umax = vmax = -1e300
        complete = True
        for i in range(i0, i1 + 1):
            ud = m[0, 1] * i + m[0, 3]
            vd = m[1, 1] * i + m[1, 3]
            wd = m[2, 1] * i + m[2, 3]
            dd0 = a[2, 1] * i + a[2, 3]
            for j in range(j0, j1 + 1):
                zc = z[i, j]
                if not dd0 + a[2, 0] * j + a[2, 2] * zc < 0.0:
                    complete = False
                    cols[i, j] = np.nan
                    rows[i, j] = np.nan
                    continue
                q = 1.0 / (wd + m[2, 0] * j + m[2, 2] * zc)
                u = (ud + m[0, 0] * j + m[0, 2] * zc) * q
                v = (vd + m[1, 0] * j + m[1, 2] * zc) * q
                cols[i, j] = u
                rows[i, j] = v
                umin = min(umin, u)
                umax = max(umax, u)
                vmin = min(vmin, v)
                vmax = max(vmax, v)
        diagonal = math.sqrt((umax - umin) ** 2 + (vmax - vmin) ** 2) if umax >= umin else 0.0
        interpolate = complete and lipschitz_px * diagonal <= tolerance_px
        modes[bi, bj] = BLOCK_INTERPOLATED if interpolate else BLOCK_EXACT
        if interpolate:  # exact pixel correction at the four corner cells, blended inside
            d0u = d0v = d1u = d1v = d2u = d2v = d3u = d3v = 0.0
            for k in range(4):
                ci = i0 if k < 2 else i1
                cj = j0 if k % 2 == 0 else j1
                xi, eta, ok = _ideal(a, cj, ci, z[ci, cj], c)
                xd, yd = _distort(xi, eta, dmode, dr, dd, dk, di)
                u, v = _project2d(mt, xd + px, yd + py)
                du = u - cols[ci, cj]
                dv = v - rows[ci, cj]
                if k == 0:
                    d0u, d0v = du, dv
                elif k == 1:
                    d1u, d1v = du, dv
                elif k == 2:
                    d2u, d2v = du, dv
                else:
                    d3u, d3v = du, dv
            ri = 1.0 / (i1 - i0) if i1 > i0 else 0.0
            rj = 1.0 / (j1 - j0) if j1 > j0 else 0.0
            for i in range(i0, i1 + 1):
                ti = (i - i0) * ri
                # corrections along the block's top and bottom rows, blended down the rows
                lu = d0u + ti * (d2u - d0u)
                lv = d0v + ti * (d2v - d0v)
                su = (d1u + ti * (d3u - d1u)) - lu
                sv = (d1v + ti * (d3v - d1v)) - lv
                for j in range(j0, j1 + 1):
                    tj = (j - j0) * rj
                    u = cols[i, j] + (lu + tj * su)
                    v = rows[i, j] + (lv + tj * sv)
                    cols[i, j] = u
                    rows[i, j] = v
                    cmin = min(cmin, u)
                    cmax = max(cmax, u)
                    rmin = min(rmin, v)
                    rmax = max(rmax, v)
            continue
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                xi, eta, ok = _ideal(a, j, i, z[i, j], c)
                if not ok:
                    missing += 1
                    continue
                xd, yd = _distort(xi, eta, dmode, dr, dd, dk, di)
                u, v = _project2d(mt, xd + px, yd + py)
                cols[i, j] = u
                rows[i, j] = v
                cmin = min(cmin, u)
                cmax = max(cmax, u)
                rmin = min(rmin, v)
                rmax = max(rmax, v)
    box[0], box[1], box[2], box[3], box[4] = cmin, rmin, cmax, rmax, missing


class CollinearityMap:
    """Ground tile + its heights -> photo pixel coordinates (a plain callable).

    ``cmap(transform, z)``: ``transform`` the tile's affine (north-up, pixel corner -> ground),
    ``z`` (h, w) heights of its cell centres (NaN: none). Returns float32 ``(cols, rows)`` in the
    photo's pixel convention (NaN: no image point). ``last_modes`` keeps the block modes of the
    last call (see :func:`project_tile_distorted`), ``last_box`` the bounding box of its finite
    coordinates and its number of NaN cells (see :func:`project_tile_projective`).
    """

    def __init__(self, photo: Any, block: int = DEFAULT_BLOCK,
                 tolerance_px: float = DEFAULT_TOLERANCE_PX, width: int | None = None,
                 height: int | None = None):
        self.model = SensorModel.from_photo(photo, width, height)
        self.block = int(block)
        self.tolerance_px = float(tolerance_px)
        self.last_modes = np.zeros((0, 0), dtype=np.int8)
        self.last_box = np.zeros(5)

    def __call__(self, transform: Any, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cols, rows, self.last_modes, self.last_box = self.project(transform, z)
        return cols, rows

    def project(self, transform: Any, z: np.ndarray):
        """``(cols, rows, block modes, box)`` of a tile (thread-safe: no state kept)."""
        if transform.b != 0 or transform.d != 0:
            raise InputDataError("the output grid must be north-up")
        z = np.ascontiguousarray(z, dtype="float64")
        h, w = z.shape
        cols = np.empty((h, w), dtype="float32")
        rows = np.empty((h, w), dtype="float32")
        b = self.block
        modes = np.empty(((h + b - 1) // b, (w + b - 1) // b), dtype=np.int8)
        s = self.model
        a, m = tile_matrices(s, transform.c + 0.5 * transform.a, transform.f + 0.5 * transform.e,
                             transform.a, -transform.e)
        box = np.empty(5)
        if s.distortion[0] == 0:
            project_tile_projective(z, a, m, cols, rows, box)
            modes[:] = BLOCK_PROJECTIVE
        else:
            project_tile_distorted(z, a, m, s.c, s.pp, *s.distortion, s.f2p,
                                   s.lipschitz * s.f2p_condition, b, self.tolerance_px, cols,
                                   rows, modes, box)
        return cols, rows, modes, box


class EngineMap:
    """A :class:`CollinearityMap` in the form the raster engine's ``warp_raster`` takes
    (``coordinate_map(tile, aux_arrays) -> (src_col, src_row)``): the heights are the auxiliary
    raster ``aux`` read onto the tile (its halo, if any, is cropped). Picklable for Dask."""

    def __init__(self, cmap: CollinearityMap, aux: str = "dem"):
        self.cmap, self.aux = cmap, aux

    def __call__(self, tile: Any, arrays: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        z = np.asarray(arrays[self.aux], dtype="float64")
        z = z[0] if z.ndim == 3 else z
        halo = int(getattr(tile, "halo", 0))
        if halo:
            z = z[halo:-halo, halo:-halo]
        return self.cmap(tile.core_transform, np.ascontiguousarray(z))


# -- DEM heights per tile ----------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def heights_on_grid(dem, gx0, gy0, cx, cy, xs, ys, out):
    """Bilinear heights (between DEM cell centres, NaN outside or on nodata) at the grid points
    ``(xs[j], ys[i])``; ``dem`` cell [0, 0] centred at ``(gx0, gy0)``, cells ``cx`` x ``cy``.
    Separable: the column and row of every point are found once per column and once per row
    (the same arithmetic as the per-point ``_dem_height`` of the monoplot kernel)."""
    rows, cols = dem.shape
    w = xs.shape[0]
    jj = np.empty(w, dtype=np.int64)
    tx = np.empty(w)
    for j in range(w):
        fx = (xs[j] - gx0) / cx
        if fx >= 0.0 and fx <= cols - 1:
            jj[j] = min(int(fx), cols - 2)
            tx[j] = fx - jj[j]
        else:
            jj[j] = -1
            tx[j] = 0.0
    for i in range(ys.shape[0]):
        fy = (gy0 - ys[i]) / cy
        if not (fy >= 0.0 and fy <= rows - 1):
            out[i, :] = np.nan
            continue
        r = min(int(fy), rows - 2)
        ty = fy - r
        for j in range(w):
            c = jj[j]
            if c < 0:
                out[i, j] = np.nan
                continue
            t = tx[j]
            out[i, j] = (dem[r, c] * (1.0 - t) + dem[r, c + 1] * t) * (1.0 - ty) + \
                (dem[r + 1, c] * (1.0 - t) + dem[r + 1, c + 1] * t) * ty


@njit(cache=True, nogil=True)
def heights_at_points(dem, gx0, gy0, cx, cy, x, y, out):
    """As :func:`heights_on_grid` at scattered points ``(x[k], y[k])`` (1-D arrays)."""
    for k in range(x.shape[0]):
        out[k] = _dem_height(x[k], y[k], dem, gx0, gy0, cx, cy)[0]


class DemSampler:
    """Heights of output cells from a DEM raster, one window per call.

    The DEM may be in another CRS than the output (``crs``): the cell centres are then
    transformed with pyproj (always_xy) and the heights taken bilinearly in the DEM's own grid.
    ``factor`` > 1 projects on a coarser DEM (the thesis' "fattore di ricampionamento"): the mean
    of ``factor`` x ``factor`` DEM cells, on a lattice fixed to the DEM's origin (no tile seams).
    """

    def __init__(self, info: Any, crs: Any = None, band: int = 1, factor: int = 1):
        from toolbox.io.crs import same_crs

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
        if info.crs is not None and crs is not None and not same_crs(info.crs, crs):
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
        """DEM-CRS coordinates (flat, contiguous) of the grid ``xs`` x ``ys``: exact with pyproj
        on a lattice of every :data:`LATTICE`-th cell (and the last), bilinear in between. The
        interpolation is checked at the centres of the lattice cells against pyproj; where it
        differs by more than 1/1000 of a DEM cell every point is transformed."""
        h, w = len(ys), len(xs)
        rows = np.unique(np.r_[np.arange(0, h, LATTICE), h - 1])
        cols = np.unique(np.r_[np.arange(0, w, LATTICE), w - 1])
        exact = len(rows) * len(cols) * 4 >= h * w or len(rows) < 2 or len(cols) < 2
        if not exact:
            lx, ly = np.meshgrid(xs[cols], ys[rows])
            tx, ty = self.transformer.transform(lx.ravel(), ly.ravel())
            tx = np.asarray(tx).reshape(lx.shape)
            ty = np.asarray(ty).reshape(lx.shape)
            dx = _interpolate_lattice(tx, rows, cols, h, w)
            dy = _interpolate_lattice(ty, rows, cols, h, w)
            mi = (rows[:-1] + rows[1:]) // 2
            mj = (cols[:-1] + cols[1:]) // 2
            cx, cy = np.meshgrid(xs[mj], ys[mi])
            ex, ey = self.transformer.transform(cx.ravel(), cy.ravel())
            error = np.hypot(np.asarray(ex) - dx[np.ix_(mi, mj)].ravel(),
                             np.asarray(ey) - dy[np.ix_(mi, mj)].ravel())
            exact = not (np.all(np.isfinite(error)) and
                         error.max() <= 1e-3 * abs(self.transform.a))
        if exact:
            xx, yy = np.meshgrid(xs, ys)
            dx, dy = self.transformer.transform(xx.ravel(), yy.ravel())
        return (np.ascontiguousarray(np.ravel(dx), dtype="float64"),
                np.ascontiguousarray(np.ravel(dy), dtype="float64"))

    def heights(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Heights (h, w) float64 at the grid of cell centres ``xs`` (w,) x ``ys`` (h,) (output
        CRS), NaN where the DEM has none."""
        xs = np.ascontiguousarray(xs, dtype="float64")
        ys = np.ascontiguousarray(ys, dtype="float64")
        out = np.full((len(ys), len(xs)), np.nan)
        if self.transformer is None:
            part = self._read((xs.min(), ys.min(), xs.max(), ys.max()))
            if part is not None:
                heights_on_grid(np.ascontiguousarray(part[0]), *part[1:], xs, ys, out)
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


LATTICE = 16  # cells between exactly transformed points when the DEM is in another CRS


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


# -- visibility (true ortho) -------------------------------------------------------------------------
SKY_BLOCK = 8  # DSM cells per side of the blocks whose maxima let rays skip free ground


def block_maxima(dsm: np.ndarray, block: int = SKY_BLOCK) -> np.ndarray:
    """Highest DSM value of every ``block`` x ``block`` group of cells, widened by one cell on
    every side (the bilinear surface inside a block uses its neighbours), NaN ignored
    (-inf where a block has no value)."""
    rows, cols = dsm.shape
    nb_r, nb_c = -(-rows // block), -(-cols // block)
    padded = np.full((nb_r * block + 2, nb_c * block + 2), -np.inf)
    padded[1:rows + 1, 1:cols + 1] = np.where(np.isfinite(dsm), dsm, -np.inf)
    from scipy.ndimage import maximum_filter

    grown = maximum_filter(padded, size=3, mode="nearest")[1:-1, 1:-1]
    return np.ascontiguousarray(grown.reshape(nb_r, block, nb_c, block).max(axis=(1, 3)))


@njit(parallel=True, cache=True)
def hidden_cells(xs, ys, z, centre, dsm, gx0, gy0, cx, cy, zmax, tolerance, bmax, block, out):
    """Occlusion test of ground cells ``(xs[j], ys[i], z[i, j])`` against a DSM.

    The ray from each cell towards the projection centre is walked over the DSM (bilinear
    between cell centres) in half-cell steps until it rises above the DSM's highest point
    ``zmax``; the cell is hidden (``out = 1``) where the surface stands more than ``tolerance``
    above the ray, i.e. the camera sees something else along that line of sight (the object-space
    form of a Z-buffer: no depth tolerance between image and ground samples, no holes). Where
    the ray enters a block of ``block`` x ``block`` DSM cells above that block's highest value
    (``bmax``, :func:`block_maxima`) it jumps to the block's exit: the ray only rises, so nothing
    in that block can hide the cell. Cells without height get 0; beyond the DSM the ray is free.
    """
    x0, y0, z0 = centre[0], centre[1], centre[2]
    step = 0.5 * min(cx, cy)
    rows, cols = dsm.shape
    for i in prange(ys.shape[0]):
        for j in range(xs.shape[0]):
            out[i, j] = 0
            zc = z[i, j]
            if not math.isfinite(zc):
                continue
            dxh = x0 - xs[j]
            dyh = y0 - ys[i]
            rho = math.sqrt(dxh * dxh + dyh * dyh)
            rise = z0 - zc
            if rho < 1e-9 or rise <= 0.0:
                continue
            ux = dxh / rho
            uy = dyh / rho
            slope = rise / rho
            s_max = min(rho, (zmax - zc) / slope)
            dfx = ux / cx  # DSM column index per metre along the ray
            dfy = -uy / cy  # DSM row index per metre
            s = step
            while s < s_max:
                px = xs[j] + s * ux
                py = ys[i] + s * uy
                fx = (px - gx0) / cx
                fy = (gy0 - py) / cy
                ray = zc + s * slope
                if fx >= 0.0 and fy >= 0.0 and fx <= cols - 1 and fy <= rows - 1:
                    bi = int(fy) // block
                    bj = int(fx) // block
                    if ray > bmax[bi, bj] + tolerance:  # free above this block: to its exit
                        tx = 1e300
                        ty = 1e300
                        if dfx > 0.0:
                            tx = ((bj + 1) * block - fx) / dfx
                        elif dfx < 0.0:
                            tx = (bj * block - fx) / dfx
                        if dfy > 0.0:
                            ty = ((bi + 1) * block - fy) / dfy
                        elif dfy < 0.0:
                            ty = (bi * block - fy) / dfy
                        s += max(min(tx, ty), 0.0) + 1e-6 * step
                        continue
                hgt, code = _dem_height(px, py, dsm, gx0, gy0, cx, cy)
                if code == 0 and hgt > ray + tolerance:
                    out[i, j] = 1
                    break
                s += step


def visibility_mask(xs: np.ndarray, ys: np.ndarray, z: np.ndarray, centre: np.ndarray,
                    surface: Any, maxima: np.ndarray | None = None) -> np.ndarray:
    """Hidden cells (uint8 1) of the grid ``xs`` x ``ys`` with heights ``z`` seen from
    ``centre`` over the DSM ``surface`` (:class:`~toolbox.photogrammetry.surface.DemSurface`);
    ``maxima`` from :func:`block_maxima` (computed when missing)."""
    maxima = block_maxima(surface.z) if maxima is None else maxima
    out = np.zeros(z.shape, dtype=np.uint8)
    hidden_cells(np.ascontiguousarray(xs, dtype="float64"),
                 np.ascontiguousarray(ys, dtype="float64"), np.ascontiguousarray(z),
                 np.asarray(centre, dtype="float64"), surface.z, surface.x0, surface.y0,
                 surface.cell_x, surface.cell_y, surface.z_range[1],
                 0.01 * min(surface.cell_x, surface.cell_y), maxima, SKY_BLOCK, out)
    return out


# -- incidence angle, relief displacement, GSD --------------------------------------------------------
def incidence_angle(xs: np.ndarray, ys: np.ndarray, z_halo: np.ndarray, centre: np.ndarray
                    ) -> np.ndarray:
    """Angle (degrees, float32) between the ray cell -> projection centre and the surface normal,
    as GRASS i.ortho.rectify writes it: 0 = seen head-on, 90 = grazing, > 90 = back-facing.

    ``z_halo`` holds the heights of the cells and one cell around them ((h + 2, w + 2)), so the
    normals come from central differences everywhere (no seams between tiles).
    """
    cx = float(xs[1] - xs[0]) if len(xs) > 1 else 1.0
    cy = float(ys[0] - ys[1]) if len(ys) > 1 else 1.0
    dzdx = (z_halo[1:-1, 2:] - z_halo[1:-1, :-2]) / (2 * cx)
    dzdy = (z_halo[:-2, 1:-1] - z_halo[2:, 1:-1]) / (2 * cy)
    z = z_halo[1:-1, 1:-1]
    vx = centre[0] - xs[None, :]
    vy = centre[1] - ys[:, None]
    vz = centre[2] - z
    dot = -dzdx * vx - dzdy * vy + vz
    norm = np.sqrt(dzdx ** 2 + dzdy ** 2 + 1.0) * np.sqrt(vx ** 2 + vy ** 2 + vz ** 2)
    with np.errstate(invalid="ignore"):
        return np.degrees(np.arccos(np.clip(dot / norm, -1.0, 1.0))).astype("float32")


def relief_displacement(xs: np.ndarray, ys: np.ndarray, z: np.ndarray, centre: np.ndarray,
                        reference_height: float) -> np.ndarray:
    """Ground displacement (m) a rectification on the plane ``Z = reference_height`` would leave
    at each cell: ``ρ·|Z - Zref| / (Z0 - Z)`` with ρ the horizontal distance from the nadir
    point (brief section 15, eq. [49] in ground units)."""
    rho = np.hypot(xs[None, :] - centre[0], ys[:, None] - centre[1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return rho * np.abs(z - reference_height) / (centre[2] - z)


def ground_sample_distance(photo: Any, height: float) -> float:
    """Ground size (m) of one photo pixel at the image centre on the plane ``Z = height``: the
    mean of the ground steps of one pixel along the columns and along the rows."""
    w, h = photo.camera.image_size_px
    pts = np.array([[w / 2 - 0.5, h / 2], [w / 2 + 0.5, h / 2], [w / 2, h / 2 - 0.5],
                    [w / 2, h / 2 + 0.5]])
    ground = photo.pixel_to_ground(pts, height)
    return 0.5 * float(np.hypot(*(ground[1, :2] - ground[0, :2])) +
                       np.hypot(*(ground[3, :2] - ground[2, :2])))


def nice_cell_size(value: float) -> float:
    """``value`` rounded to 2 significant digits (a GSD proposal such as 0.053 m or 1.2 m)."""
    if not value > 0:
        raise InputDataError(f"cell size must be > 0, got {value}")
    digits = 1 - int(math.floor(math.log10(value)))
    return round(value, digits)


def check_geometry(photo: Any, terrain_height: float | None = None) -> None:
    """Refuse a camera that cannot see the terrain: an optical axis that does not descend, or
    (given ``terrain_height``) a projection centre at or below the terrain."""
    eo = photo.require_exterior()
    axis = eo.rotation @ np.array([0.0, 0.0, -1.0])
    if not axis[2] < 0:
        raise InputDataError(f"photo {photo.id!r}: the camera looks away from the ground (its "
                             f"optical axis points {'up' if axis[2] > 0 else 'horizontally'}; "
                             f"omega = {math.degrees(eo.omega):.1f}, phi = "
                             f"{math.degrees(eo.phi):.1f} degrees): check the angles and their "
                             "unit")
    if terrain_height is not None and not eo.z0 > terrain_height:
        raise InputDataError(f"photo {photo.id!r}: the projection centre (Z0 = {eo.z0:.2f}) is "
                             f"not above the terrain ({terrain_height:.2f}); check Z0 and the "
                             "DEM's height datum")


def tilt_warning(photo: Any, limit_deg: float = 10.0) -> str | None:
    """A warning when omega or phi exceed ``limit_deg`` (a vertical photo has a few degrees at
    most: tens of degrees usually mean angles read in the wrong unit)."""
    eo = photo.require_exterior()
    o, p = (math.degrees(a) for a in (eo.omega, eo.phi))
    if max(abs(o), abs(p)) > limit_deg:
        return (f"photo {photo.id!r}: omega = {o:.1f} deg, phi = {p:.1f} deg: a vertical aerial "
                f"photo is tilted by a few degrees at most; if the angles were read in the wrong "
                f"unit (they were taken as {eo.source_unit}), fix the unit")
    return None


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
    from toolbox.io.crs import same_crs
    from toolbox.photogrammetry.surface import surface_for_photo

    if info.crs is None or crs is None or same_crs(info.crs, crs):
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


PREFETCH = 2  # windows whose maps are computed ahead, on as many threads


class OrthoWindows:
    """The coordinate map of a whole ortho for :func:`toolbox.raster.warp.warp_to_geotiff`:
    per output window it reads the DEM heights onto the window (:class:`DemSampler`), projects
    them (:class:`CollinearityMap`), blanks the hidden cells (optional visibility test) and
    collects statistics; auxiliary rasters (occlusion mask, incidence angle) are written window
    by window."""

    def __init__(self, photo: Any, grid: Any, sampler: DemSampler, cmap: CollinearityMap,
                 reference_height: float, surface: Any = None, mask_writer: Any = None,
                 incidence_writer: Any = None):
        self.photo, self.grid, self.sampler, self.cmap = photo, grid, sampler, cmap
        self.reference_height = reference_height
        self.surface = surface
        self.mask_writer = mask_writer
        self.incidence_writer = incidence_writer
        self.centre = photo.require_exterior().centre
        self.per_window: dict[tuple[int, int, int, int], TileStatistics] = {}
        self._maxima: np.ndarray | None = None
        import threading

        self._write_lock = threading.Lock()  # aux writers, if a split window runs alongside

    def _key(self, window: Any) -> tuple[int, int, int, int]:
        return (int(window.col_off), int(window.row_off), int(window.width), int(window.height))

    def prefetch(self, windows: list[Any]) -> None:
        """Compute the windows' coordinates :data:`PREFETCH` ahead on background threads, in
        this order (the warp's), so that the maps of the next windows overlap each other and the
        resampling and compression of the current one (the kernels release the GIL). Call
        :meth:`close` at the end."""
        from concurrent.futures import ThreadPoolExecutor

        self._order = {self._key(w): k for k, w in enumerate(windows)}
        self._windows = list(windows)
        self._pool = ThreadPoolExecutor(PREFETCH, thread_name_prefix="ortho-map")
        self._futures: dict = {}
        for k in range(PREFETCH):
            self._submit(k)

    def _submit(self, index: int) -> None:
        if index < len(self._windows):
            window = self._windows[index]
            self._futures[self._key(window)] = self._pool.submit(self._compute, window)

    def _result(self, window: Any):
        key = self._key(window)
        future = getattr(self, "_futures", {}).pop(key, None)
        if future is None:
            return self._compute(window)
        self._submit(self._order[key] + PREFETCH)
        return future.result()

    def close(self) -> None:
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            self._futures = {}

    def source_bounds(self, window: Any) -> tuple[float, float, float, float] | None:
        """The exact bounding box of the window's source coordinates when every cell has one
        (the warp then skips its own scan and, inside the photo, the inside test); None when
        some cells have none. The coordinates are kept for the call that follows."""
        self._last = (self._key(window), self._result(window))
        return self._last[1][2]

    def __call__(self, window: Any) -> tuple[np.ndarray, np.ndarray]:
        last = getattr(self, "_last", None)
        if last is not None and last[0] == self._key(window):
            self._last = None
            return last[1][0], last[1][1]
        cols, rows, _ = self._result(window)
        return cols, rows

    def _compute(self, window: Any):
        xs, ys = self.grid.cell_centers(window)
        cell_x, cell_y = self.grid.cell_size
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
        cols, rows, modes, box = self.cmap.project(self.grid.window_transform(window), z)
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
        w, h = self.cmap.model.width, self.cmap.model.height
        every_cell = missing == 0
        box = (float(cmin), float(rmin), float(cmax), float(rmax)) if missing < z.size else None
        if every_cell and box[0] >= 0 and box[1] >= 0 and box[2] <= w and box[3] <= h:
            inside = None  # the whole window is in the photo
            stats.outside_photo = 0
        else:
            inside = (cols >= 0) & (cols <= w) & (rows >= 0) & (rows <= h)
            stats.outside_photo = int(z.size - missing - np.count_nonzero(inside))
        sub = (slice(None, None, 4), slice(None, None, 4))
        disp = relief_displacement(xs[sub[1]], ys[sub[0]], z[sub], self.centre,
                                   self.reference_height)
        disp = disp[inside[sub]] if inside is not None else disp.ravel()
        disp = disp[np.isfinite(disp)]
        stats.max_relief_m = float(disp.max()) if disp.size else 0.0
        counts = np.bincount(modes.ravel(), minlength=3)
        stats.blocks = {k: int(counts[k]) for k in range(3)}
        self.per_window[self._key(window)] = stats
        return cols, rows, box if every_cell else None

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
        Output grid in the orientation's CRS.
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
    from toolbox.raster.warp import warp_to_geotiff

    options = options or OrthoOptions()
    feedback = feedback or Feedback()
    size = photo.camera.image_size_px
    if size is not None and tuple(size) != (image.width, image.height):
        raise InputDataError(f"photo {photo.id!r}: the raster {image} is {image.width} x "
                             f"{image.height} px but the camera {photo.camera.name!r} says "
                             f"{size[0]} x {size[1]}: wrong image or camera")
    sampler = DemSampler(dem, grid.crs, options.band, options.dem_factor)
    sampler.preload(grid.bounds)
    cmap = CollinearityMap(photo, options.block, options.tolerance_px, image.width, image.height)
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
    windows = None
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
                               incidence_writer)
        from toolbox.io.raster import iter_windows

        windows.prefetch([t.core for t in iter_windows(grid.width, grid.height, options.chunk)])
        eo = photo.require_exterior()
        tags = {"ORTHO_PHOTO": photo.id, "ORTHO_MAP_TOLERANCE_PX": str(options.tolerance_px),
                "ORTHO_RESAMPLING": options.resampling, "NADIR_X": repr(eo.x0),
                "NADIR_Y": repr(eo.y0), "PROJECTION_CENTRE_Z": repr(eo.z0)}
        with feedback.timed("orthorectify"):
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
        if windows is not None:
            windows.close()
        for dst in aux:
            dst.close()
        if options.cog and target != output and target.exists():
            target.unlink()
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
    footprint on the DEM, the mean terrain height, the photo's GSD there and the output grid."""

    photo: Any
    surface: Any
    footprint: Any  # shapely Polygon
    mean_height: float
    gsd: float
    grid: Any


def plan_photo(photo: Any, dem: Any, crs: Any, band: int = 1, cell: float | None = None,
               bounds: tuple[float, float, float, float] | None = None,
               origin: tuple[float, float] = (0.0, 0.0)) -> OrthoPlan:
    """Check the geometry and choose the grid of one photo's ortho.

    Defaults (as the thesis' software proposes, S002 par. 3.8): cell = the photo's ground
    sample distance at the mean terrain height of its footprint (2 significant digits); extent
    = the footprint on the DEM (the frame outline monoplotted, 8 points per side); edges on the
    lattice ``origin + k·cell``.
    """
    from toolbox.photogrammetry.coverage import photo_footprint
    from toolbox.photogrammetry.surface import dem_height_range

    check_dem_crs(dem)
    check_geometry(photo)
    low, _ = dem_height_range(dem, band)
    check_geometry(photo, low)
    surface = photo_surface(dem, photo, crs, band)
    eo = photo.require_exterior()
    under = float(surface.height(np.array([eo.x0]), np.array([eo.y0]))[0])
    check_geometry(photo, under if math.isfinite(under) else None)
    fp = photo_footprint(photo, surface, float(np.nanmean(surface.z)), 8)
    polygon = fp.polygon
    mean_height = mean_height_inside(surface, polygon)
    gsd = ground_sample_distance(photo, mean_height)
    cell = nice_cell_size(gsd) if cell is None else float(cell)
    grid = lattice_grid(polygon.bounds if bounds is None else bounds, cell, crs, origin)
    return OrthoPlan(photo, surface, polygon, mean_height, gsd, grid)


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
    from toolbox.feedback import Feedback

    final = Path(task.output)
    partial = final.with_name(f".{final.stem}.part{final.suffix}")
    feedback = Feedback()
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
