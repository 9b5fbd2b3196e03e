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
bound :data:`DEFAULT_TOLERANCE_PX` = 0.05 px. On a DEM window (the orthophoto's one-pass
path) D is taken from a box known to hold the block's pixels before they are computed: the
image of the block's cells x the heights of the DEM nodes around them
(:func:`block_modes_on_dem`).

Conventions as :mod:`toolbox.photogrammetry`: photo pixels ``(col, row)`` from the top-left corner,
centres at +0.5; output grids north-up, column ``j`` centre ``x = xmin + (j + 0.5)·cell``.
Kernels take arrays and numbers; the DEM is read per tile by
:class:`toolbox.photogrammetry.orthophoto.DemSampler` (the driver) and handed to them as an
array. The per-tile kernels are single-threaded and release the GIL (``nogil``): parallelism
comes from running tiles or photos side by side; an OpenMP region per tile costs more than it
saves on a busy 2-core machine (measured: 3 ms single-threaded against 22-31 ms with two
spinning threads for one 1024 x 1024 tile).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit, prange

from toolbox.errors import InputDataError
from toolbox.photogrammetry.kernels import _dem_height, _distort, _project2d, _tuple9
from toolbox.raster.warp import OUTSIDE

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
    scale of ``f2p`` (pixels per image mm), ``f2p_condition`` its condition number and
    ``max_distortion_px`` a bound of the distortion's shift of a point of the photo, pixels.
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
    max_distortion_px: float = 0.0

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
        radius = _frame_radius(photo, w, h)
        px_per_mm, condition = _pixel_scale(f2p, photo, w, h)
        return cls(eo.centre, np.ascontiguousarray(eo.rotation), float(cam.c),
                   np.asarray(cam.principal_point_mm, dtype="float64"),
                   _distortion_args(cam.distortion),
                   f2p, distortion_lipschitz(cam.distortion, radius), px_per_mm, condition,
                   int(w), int(h), px_per_mm * distortion_magnitude(cam.distortion, radius))


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


def distortion_magnitude(distortion: Any, radius_mm: float) -> float:
    """Bound of ``|Δr|`` (mm), the distortion's shift of a point, for measured radii up to
    ``radius_mm``: a table is piecewise linear with its last value held, so its largest node
    value; a polynomial is sampled densely on [0, 1.05 radius] and widened by 5 %."""
    if distortion is None:
        return 0.0
    from toolbox.photogrammetry.camera import DISTORTION_TABLE

    if distortion.mode == DISTORTION_TABLE:
        return float(np.abs(distortion.dr_mm).max())
    rr = np.linspace(0.0, 1.05 * radius_mm, 4097)
    return 1.05 * float(np.abs(distortion.k1 * rr ** 3 + distortion.k2 * rr ** 5).max())


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


# Every kernel below compiles with ``error_model="numpy"`` (a division by zero gives inf/NaN, no
# exception check): without the check LLVM vectorises the per-cell loops, 8x faster measured.
# Their divisions are guarded or cannot meet zero; results are the same IEEE operations.
FAST = {"cache": True, "nogil": True, "error_model": "numpy"}


@njit(**FAST)
def project_tile_projective(z, a, m, cols, rows):
    """Source pixels of a tile without distortion: exactly ``M·(j, i, Z, 1)`` per cell (see
    :func:`tile_matrices`), NaN where Z is NaN or the point is not in front of the camera;
    returns the number of NaN cells (the box: :func:`window_box`)."""
    h, w = z.shape
    a20, a22 = a[2, 0], a[2, 2]
    m00, m02, m10, m12, m20, m22 = m[0, 0], m[0, 2], m[1, 0], m[1, 2], m[2, 0], m[2, 2]
    missing = 0
    for i in range(h):
        zr, cr, rr = z[i], cols[i], rows[i]
        ud = m[0, 1] * i + m[0, 3]
        vd = m[1, 1] * i + m[1, 3]
        wd = m[2, 1] * i + m[2, 3]
        dd = a[2, 1] * i + a[2, 3]
        for j in range(w):  # branch-free, so that it vectorises
            zc = zr[j]
            ahead = dd + a20 * j + a22 * zc < 0.0  # in front of the camera (False for NaN)
            q = 1.0 / (wd + m20 * j + m22 * zc)
            cr[j] = (ud + m00 * j + m02 * zc) * q if ahead else np.nan
            rr[j] = (vd + m10 * j + m12 * zc) * q if ahead else np.nan
            missing += 0 if ahead else 1
    return missing


def window_box(cols: np.ndarray, rows: np.ndarray, box: np.ndarray) -> None:
    """The bounding box of the finite ``cols``, ``rows`` into ``box[:4]`` (col_min, row_min,
    col_max, row_max; 1e300 / -1e300 when there is none; ``box[4]`` must hold the number of NaN
    cells). NumPy's fmin/fmax reductions are vectorised and skip NaN: 0.2 ms per Mpx."""
    if box[4] < cols.size:
        box[:4] = (np.fmin.reduce(cols, axis=None), np.fmin.reduce(rows, axis=None),
                   np.fmax.reduce(cols, axis=None), np.fmax.reduce(rows, axis=None))
    else:
        box[:4] = (1e300, 1e300, -1e300, -1e300)


def block_modes(cols: np.ndarray, rows: np.ndarray, block: int, lipschitz_px: float,
                tolerance_px: float) -> np.ndarray:
    """Per block of ``block`` x ``block`` cells of a distortion-free map: BLOCK_INTERPOLATED
    where every cell has an image point and ``lipschitz_px·D <= tolerance_px``, D the diagonal
    of the block's pixel box (widened by 1e-3 px for the float32 rounding), else BLOCK_EXACT."""
    h, w = cols.shape
    nby, nbx = -(-h // block), -(-w // block)

    def per_block(ufunc, values, fill):
        """``ufunc`` reduced over every block (padded with ``fill``): down the block's rows
        first (whole rows at a time, vectorised), then along the short result."""
        if (nby * block, nbx * block) != (h, w):
            values = np.pad(values, ((0, nby * block - h), (0, nbx * block - w)),
                            constant_values=fill)
        down = ufunc.reduce(values.reshape(nby, block, nbx * block), axis=1)
        return ufunc.reduce(down.reshape(nby, nbx, block), axis=2)

    gap = per_block(np.logical_or, np.isnan(cols), False)
    size = np.hypot(per_block(np.fmax, cols, np.nan) - per_block(np.fmin, cols, np.nan),
                    per_block(np.fmax, rows, np.nan) - per_block(np.fmin, rows, np.nan)) + 1e-3
    with np.errstate(invalid="ignore"):
        interpolate = ~gap & (lipschitz_px * size <= tolerance_px)
    return np.where(interpolate, BLOCK_INTERPOLATED, BLOCK_EXACT).astype(np.int8)


@njit(**FAST)
def block_modes_on_dem(dem, dgx0, dgy0, dcx, dcy, xs, ys, a, m, block, lipschitz_px,
                       tolerance_px, modes):
    """:func:`block_modes` of a window's map from its DEM part (as
    :func:`ortho_window_projective` takes it) instead of its cells: per block a box that holds
    every cell's distortion-free pixel, the image of the block's cells x the heights of the
    DEM nodes around them (a bilinear height lies in their range; ``den`` is affine, so the 8
    corners in front of the camera mean the whole box, and a central projection keeps
    convexity there: the corners' pixels bound it). BLOCK_INTERPOLATED when
    ``lipschitz_px·D <= tolerance_px`` with D the box's diagonal (+ 1e-3 px), else
    BLOCK_EXACT, also where a node is NaN, the block leaves the DEM or a corner is not in
    front. A box at least the cells' own, so the bound holds; no pass over the map (0.05
    against 0.7 ms per 1024 x 1024 window, measured)."""
    nrow, ncol = dem.shape
    h, w = ys.shape[0], xs.shape[0]
    for bi in range(modes.shape[0]):
        i0 = bi * block
        i1 = min(i0 + block, h) - 1
        fy0, fy1 = (dgy0 - ys[i0]) / dcy, (dgy0 - ys[i1]) / dcy
        for bj in range(modes.shape[1]):
            j0 = bj * block
            j1 = min(j0 + block, w) - 1
            modes[bi, bj] = BLOCK_EXACT
            fx0, fx1 = (xs[j0] - dgx0) / dcx, (xs[j1] - dgx0) / dcx
            if not (min(fx0, fx1) >= 0.0 and max(fx0, fx1) <= ncol - 1
                    and min(fy0, fy1) >= 0.0 and max(fy0, fy1) <= nrow - 1):
                continue  # leaves the DEM: no height somewhere
            r_lo, r_hi = int(min(fy0, fy1)), min(int(max(fy0, fy1)) + 1, nrow - 1)
            c_lo, c_hi = int(min(fx0, fx1)), min(int(max(fx0, fx1)) + 1, ncol - 1)
            z_lo, z_hi, nan_node = np.inf, -np.inf, False
            for r in range(r_lo, r_hi + 1):
                for c in range(c_lo, c_hi + 1):
                    z_lo = min(z_lo, dem[r, c])
                    z_hi = max(z_hi, dem[r, c])
                    nan_node = nan_node or math.isnan(dem[r, c])
            if nan_node:  # a cell without height somewhere
                continue
            u_lo = v_lo = np.inf
            u_hi = v_hi = -np.inf
            ahead = True
            for k in range(8):
                j = j0 if k % 2 == 0 else j1
                i = i0 if (k // 2) % 2 == 0 else i1
                zc = z_lo if k < 4 else z_hi
                ahead = ahead and a[2, 0] * j + a[2, 1] * i + a[2, 2] * zc + a[2, 3] < 0.0
                q = 1.0 / (m[2, 0] * j + m[2, 1] * i + m[2, 2] * zc + m[2, 3])
                u = (m[0, 0] * j + m[0, 1] * i + m[0, 2] * zc + m[0, 3]) * q
                v = (m[1, 0] * j + m[1, 1] * i + m[1, 2] * zc + m[1, 3]) * q
                u_lo, u_hi = min(u_lo, u), max(u_hi, u)
                v_lo, v_hi = min(v_lo, v), max(v_hi, v)
            size = math.sqrt((u_hi - u_lo) ** 2 + (v_hi - v_lo) ** 2) + 1e-3
            if ahead and lipschitz_px * size <= tolerance_px:
                modes[bi, bj] = BLOCK_INTERPOLATED


@njit(cache=True, error_model="numpy")
def _exact_pixel(a, j, i, zc, c, px, py, mt, dmode, dr, dd, dk, di):
    """Photo pixel of cell (j, i) at height zc with the distortion (ideal point -> distortion
    -> principal point -> fiducial -> pixel); ok flag. One function with the ideal point (a
    function more is a compilation more)."""
    den = a[2, 0] * j + a[2, 1] * i + a[2, 2] * zc + a[2, 3]
    if not den < 0.0:  # behind the camera, or NaN height
        return np.nan, np.nan, False
    q = -c / den
    xi = (a[0, 0] * j + a[0, 1] * i + a[0, 2] * zc + a[0, 3]) * q
    eta = (a[1, 0] * j + a[1, 1] * i + a[1, 2] * zc + a[1, 3]) * q
    xd, yd = _distort(xi, eta, dmode, dr, dd, dk, di)
    u, v = _project2d(mt, xd + px, yd + py)
    return u, v, True


@njit(**FAST)
def distort_blocks(z, a, c, pp, dmode, dr, dd, dk, di, f2p, block, modes, shift, cols, rows):
    """Add the radial distortion to a distortion-free map (:func:`project_tile_projective`),
    block by block as ``modes`` (:func:`block_modes`) says (see the module docstring); the map
    is in pixels minus ``shift`` (2,) (zeros, or the OpenCV shift of a planned map).

    BLOCK_INTERPOLATED: the distortion's pixel correction exactly at the block's four corner
    cells (ideal point -> distortion -> principal point -> fiducial -> pixel, minus the
    distortion-free pixel), blended bilinearly inside; BLOCK_EXACT: every cell exactly."""
    h, w = cols.shape
    mt = _tuple9(f2p)
    px, py = pp[0], pp[1]
    sc, sr = shift[0], shift[1]
    for bi in range(modes.shape[0]):
        i0 = bi * block
        i1 = min(i0 + block, h) - 1
        for bj in range(modes.shape[1]):
            j0 = bj * block
            j1 = min(j0 + block, w) - 1
            if modes[bi, bj] != BLOCK_INTERPOLATED:
                for i in range(i0, i1 + 1):
                    for j in range(j0, j1 + 1):
                        u, v, _ = _exact_pixel(a, j, i, z[i, j], c, px, py, mt, dmode, dr, dd,
                                               dk, di)
                        cols[i, j], rows[i, j] = u - sc, v - sr
                continue
            d0u = d0v = d1u = d1v = d2u = d2v = d3u = d3v = 0.0
            for k in range(4):
                corner_i = i0 if k < 2 else i1
                corner_j = j0 if k % 2 == 0 else j1
                u, v, _ = _exact_pixel(a, corner_j, corner_i, z[corner_i, corner_j], c, px, py,
                                       mt, dmode, dr, dd, dk, di)
                du = u - sc - cols[corner_i, corner_j]
                dv = v - sr - rows[corner_i, corner_j]
                if k == 0:
                    d0u, d0v = du, dv
                elif k == 1:
                    d1u, d1v = du, dv
                elif k == 2:
                    d2u, d2v = du, dv
                else:
                    d3u, d3v = du, dv
            step_i = 1.0 / (i1 - i0) if i1 > i0 else 0.0
            step_j = 1.0 / (j1 - j0) if j1 > j0 else 0.0
            for i in range(i0, i1 + 1):
                ti = (i - i0) * step_i
                # corrections along the block's top and bottom rows, blended down the rows
                lu = d0u + ti * (d2u - d0u)
                lv = d0v + ti * (d2v - d0v)
                su = (d1u + ti * (d3u - d1u)) - lu
                sv = (d1v + ti * (d3v - d1v)) - lv
                cr, rr = cols[i, j0:j1 + 1], rows[i, j0:j1 + 1]  # slices: it vectorises
                for j in range(cr.shape[0]):
                    tj = j * step_j
                    cr[j] = cr[j] + (lu + tj * su)
                    rr[j] = rr[j] + (lv + tj * sv)


#: fields of the ``stats`` array of :func:`ortho_window_projective`
(STAT_COL_MIN, STAT_ROW_MIN, STAT_COL_MAX, STAT_ROW_MAX, STAT_MISSING, STAT_OUTSIDE_DEM,
 STAT_OUTSIDE_PHOTO, STAT_MAX_RELIEF) = range(8)
RELIEF_ROWS = 8  # every 8th row (all its columns) enters the largest relief displacement


@njit(**FAST)
def _relief_row_bits(cr, rr, zr, dx2, dy2, photo, reference_height, z0, line):
    """The largest squared relief displacement (m², :func:`relief_displacement`) of one row's
    cells inside ``photo`` (4,), as the bits of its float64 (0: none): branch-free into
    ``line``, then an integer maximum (non-negative doubles order as their int64 patterns,
    and an integer maximum vectorises where a float one does not without fastmath; the
    caller takes the square root once). ``dx2`` the squared x offsets of the columns from the
    projection centre, ``dy2`` the row's."""
    c_lo, c_hi, r_lo, r_hi = photo[0], photo[1], photo[2], photo[3]
    for j in range(zr.shape[0]):
        u, v, zc = cr[j], rr[j], zr[j]
        inside = (u >= c_lo) & (u <= c_hi) & (v >= r_lo) & (v <= r_hi)
        ratio = (zc - reference_height) / (z0 - zc)
        value = (dx2[j] + dy2) * ratio * ratio
        line[j] = value if inside & (value < np.inf) else 0.0  # (and not NaN)
    return line.view(np.int64).max()


@njit(**FAST)
def ortho_window_projective(dem, dgx0, dgy0, dcx, dcy, xs, ys, a, m, centre, reference_height,
                            photo, blank, slack, z, cols, rows, stats):
    """Heights, coordinate map and statistics of one output window in one pass, row by row,
    without distortion.

    The DEM part ``dem`` and the cell centres ``xs``, ``ys`` as :func:`heights_on_grid`; ``a``,
    ``m`` of :func:`tile_matrices`; ``z`` (h, w) gets the heights, or is (0, 0) when they are
    not wanted. ``photo`` (4,) is the photo ``[col0, col1] x [row0, row1]`` in the map's
    coordinates (``[0, width] x [0, height]``, or shifted with ``m``: see
    :meth:`CollinearityMap.project_on_dem`); with ``blank`` every cell outside it (or without
    image point) gets :data:`~toolbox.raster.warp.OUTSIDE` instead of its coordinates (else NaN
    where there is no image point). ``stats`` (8,) gets (after the box, left to
    :func:`window_box`) the number of cells without image point, the cells without height, the
    cells with an image point outside the photo and the largest relief displacement (m,
    :func:`relief_displacement`, on every :data:`RELIEF_ROWS`-th row, cells inside the
    photo).

    With ``slack >= 0`` (px), each row is first split into spans, without touching its
    cells: the edges' conditions ``col >= col0`` etc. are affine in (column, height) once
    multiplied by the homogeneous ``w`` (of one sign over the row's cells x heights, checked at
    the corners), so with the row's heights in the range of its two DEM rows, solving them
    over that range gives the columns surely outside the photo by more than ``slack`` (with
    ``blank``: OUTSIDE at once, counted outside), surely inside by more than ``slack`` (the map
    alone: no tests, no counts), and the rest, tested cell by cell as without spans; 0.01 px
    more covers the float32 rounding. ``slack`` is 0 for a final map, the distortion's largest
    shift for one the distortion pass still moves. An edge window spends nothing on its cells
    outside the photo, an inner one skips the tests (0.53 ms against 1.2 ms per 1024 x 1024
    window, with the relief below, measured). ``slack < 0``: no spans.

    The arithmetic of :func:`heights_on_grid` + :func:`project_tile_projective` (equal results,
    tested), written out in one function rather than calling their helpers, and the box left to
    NumPy (:func:`window_box`): numba compiles every called function on its own, and a cold
    start paid 8.5 s for the helpers against 2 s for this (measured on the loaded 2-core
    machine)."""
    h, w = ys.shape[0], xs.shape[0]
    nrow, ncol = dem.shape
    jj = np.empty(w, dtype=np.uint64)  # as _dem_columns; unsigned: the loops vectorise
    tx = np.empty(w)
    spans = slack >= 0.0  # the rows' spans (below) need every column on the DEM
    for j in range(w):
        fx = (xs[j] - dgx0) / dcx
        inside_dem = fx >= 0.0 and fx <= ncol - 1
        jj[j] = min(int(fx), ncol - 2) if inside_dem else 0
        tx[j] = fx - jj[j] if inside_dem else np.nan
        spans = spans and inside_dem
    # per DEM row its lowest and highest height (NaN if it has a NaN): a grid row between DEM
    # rows r and r + 1 has its heights in the range of the two
    low, high = np.empty(nrow if spans else 0), np.empty(nrow if spans else 0)
    for dem_row in range(low.shape[0]):  # (own names: c and r are the heights' below)
        lo = hi = dem[dem_row, 0]
        for value in dem[dem_row]:
            lo = min(lo, value)
            hi = max(hi, value)
            if math.isnan(value):
                lo = hi = np.nan
                break
        low[dem_row], high[dem_row] = lo, hi
    top, bottom, line = np.empty(w), np.empty(w), np.empty(w)
    held = -2
    a20, a22 = a[2, 0], a[2, 2]
    m00, m02, m10, m12, m20, m22 = m[0, 0], m[0, 2], m[1, 0], m[1, 2], m[2, 0], m[2, 2]
    missing = outside = no_height = 0
    relief_bits = 0  # the largest relief displacement, squared, as the bits of a float64
    x0, y0, z0 = centre[0], centre[1], centre[2]
    dx2 = (xs - x0) ** 2  # the relief's squared x offsets from the projection centre
    relief_line = np.empty(w)
    c_lo, c_hi, r_lo, r_hi = photo[0], photo[1], photo[2], photo[3]
    # margin of the spans' tests, pixels: beyond the float32 rounding of a coordinate
    margin = 0.01 + slack + 1e-6 * max(abs(c_lo), abs(c_hi), abs(r_lo), abs(r_hi))
    empty = np.float32(OUTSIDE if blank else np.nan)
    keep_outside = not blank
    for i in range(h):
        zr = z[i] if z.shape[0] == h else line
        fy = (dgy0 - ys[i]) / dcy
        ud = m[0, 1] * i + m[0, 3]
        vd = m[1, 1] * i + m[1, 3]
        wd = m[2, 1] * i + m[2, 3]
        dd = a[2, 1] * i + a[2, 3]
        # the row's spans: cells [0, p0) and [p1, w) surely outside the photo, [q0, q1) surely
        # inside, the rest tested cell by cell (all of it: p0 = 0, q0 = q1 = p1 = w)
        p0, q0, q1, p1 = 0, w, w, w
        if not (fy >= 0.0 and fy <= nrow - 1):
            zr[:] = np.nan
        else:  # heights: the DEM rows around the grid row along x (kept), blended
            r = min(int(fy), nrow - 2)
            ty = fy - r
            if r != held:
                for k in range(2):
                    d, o = dem[r + k], top if k == 0 else bottom
                    for j in range(w):
                        c, t = jj[j], tx[j]
                        o[j] = d[c] * (1.0 - t) + d[c + 1] * t
                held = r
            for j in range(w):
                zr[j] = top[j] * (1.0 - ty) + bottom[j] * ty
            if spans and not math.isnan(low[r] + low[r + 1]):
                zlo, zhi = min(low[r], low[r + 1]), max(high[r], high[r + 1])
                # the row's cells x [zlo, zhi]: den and the homogeneous w are affine in (j, z),
                # so their extremes are at the corners
                d_hi = dd + max(0.0, a20 * (w - 1)) + max(a22 * zlo, a22 * zhi)
                w_lo = wd + min(0.0, m20 * (w - 1)) + min(m22 * zlo, m22 * zhi)
                w_hi = wd + max(0.0, m20 * (w - 1)) + max(m22 * zlo, m22 * zhi)
                scale = abs(dd) + abs(a20) * w + abs(a22) * max(abs(zlo), abs(zhi))
                if d_hi < -1e-12 * scale and (w_lo > 0.0 or w_hi < 0.0):  # ahead, w one sign
                    sign = 1.0 if w_lo > 0.0 else -1.0
                    p_lo, p_hi, q_lo, q_hi = 0.0, w - 1.0, 0.0, w - 1.0
                    for k in range(8):  # 4 edges x (surely inside, possibly inside)
                        edge, sure = k // 2, k % 2 == 0
                        upper = edge % 2 == 1
                        n0, nj, nz = (ud, m00, m02) if edge < 2 else (vd, m10, m12)
                        bound = photo[edge] + (margin if sure != upper else -margin)
                        # the edge's condition: s·(N - bound·w) >= 0, s = ±sign, affine in j
                        s = -sign if upper else sign
                        alpha = s * (n0 - bound * wd)
                        beta = s * (nj - bound * m20)
                        g_lo, g_hi = s * (nz - bound * m22) * zlo, s * (nz - bound * m22) * zhi
                        alpha += min(g_lo, g_hi) if sure else max(g_lo, g_hi)
                        lo, hi = (q_lo, q_hi) if sure else (p_lo, p_hi)
                        if beta > 0.0:
                            lo = max(lo, -alpha / beta)
                        elif beta < 0.0:
                            hi = min(hi, -alpha / beta)
                        elif alpha < 0.0:
                            lo = np.inf
                        if sure:
                            q_lo, q_hi = lo, hi
                        else:
                            p_lo, p_hi = lo, hi
                    p0 = int(math.ceil(min(max(p_lo, 0.0), w)))
                    p1 = max(int(math.floor(min(max(p_hi, -1.0), w - 1.0))) + 1, p0)
                    q0 = min(max(int(math.ceil(min(max(q_lo, 0.0), w))), p0), p1)
                    q1 = min(max(int(math.floor(min(max(q_hi, -1.0), w - 1.0))) + 1, q0), p1)
                    if not blank:  # no cell blanked: the surely outside ones are tested
                        p0, p1 = 0, w
        for span in range(3):  # [p0, q0) and [q1, p1) tested, [q0, q1) surely inside
            start, stop = (p0, q0) if span == 0 else ((q1, p1) if span == 1 else (q0, q1))
            # zero-based loops on slices (a start from the spans' arithmetic stops LLVM
            # vectorising a loop: 2x slower measured)
            cr, rr, zs = cols[i, start:stop], rows[i, start:stop], zr[start:stop]
            us, vs, ws = ud + m00 * start, vd + m10 * start, wd + m20 * start
            ds = dd + a20 * start
            if span == 2:  # the map alone
                for j in range(zs.shape[0]):
                    zc = zs[j]
                    q = 1.0 / (ws + m20 * j + m22 * zc)
                    cr[j] = np.float32((us + m00 * j + m02 * zc) * q)
                    rr[j] = np.float32((vs + m10 * j + m12 * zc) * q)
                continue
            for j in range(zs.shape[0]):  # the map and the counts, branch-free
                zc = zs[j]
                no_height += 1 if math.isnan(zc) else 0
                ahead = ds + a20 * j + a22 * zc < 0.0  # in front of the camera (False for NaN)
                q = 1.0 / (ws + m20 * j + m22 * zc)
                u = np.float32((us + m00 * j + m02 * zc) * q)
                v = np.float32((vs + m10 * j + m12 * zc) * q)
                inside = (u >= c_lo) & (u <= c_hi) & (v >= r_lo) & (v <= r_hi)
                keep = ahead & (inside | keep_outside)
                cr[j] = u if keep else empty
                rr[j] = v if keep else empty
                missing += 0 if ahead else 1
                outside += 1 if ahead & ~inside else 0
        cr, rr = cols[i], rows[i]
        cr[:p0] = empty
        rr[:p0] = empty
        cr[p1:] = empty
        rr[p1:] = empty
        outside += p0 + w - p1
        if i % RELIEF_ROWS == 0:
            relief_bits = max(relief_bits, _relief_row_bits(
                cr, rr, zr, dx2, (ys[i] - y0) ** 2, photo, reference_height, z0, relief_line))
    stats[STAT_MISSING] = missing
    stats[STAT_OUTSIDE_DEM] = no_height
    stats[STAT_OUTSIDE_PHOTO] = outside
    stats[STAT_MAX_RELIEF] = math.sqrt(np.array([relief_bits]).view(np.float64)[0])


@njit(**FAST)
def count_window(z, xs, ys, cols, rows, centre, reference_height, photo, blank, stats):
    """The counts of :func:`ortho_window_projective` that the distortion changes, recomputed on
    the final map: ``stats[STAT_OUTSIDE_PHOTO]`` and ``stats[STAT_MAX_RELIEF]`` (from the
    window's heights ``z``, on its relief rows only); with ``blank`` the cells outside
    ``photo`` (or without image point) get :data:`~toolbox.raster.warp.OUTSIDE` here. The
    cells without image point or height stay the kernel's counts: the distortion moves a point
    but never makes or removes one (an exact pixel is NaN exactly where the distortion-free
    one is, and a blended block has none)."""
    outside = 0
    relief_bits = 0
    x0, y0, z0 = centre[0], centre[1], centre[2]
    dx2 = (xs - x0) ** 2
    relief_line = np.empty(xs.shape[0])
    c_lo, c_hi, r_lo, r_hi = photo[0], photo[1], photo[2], photo[3]
    empty = np.float32(OUTSIDE)
    for i in range(ys.shape[0]):
        cr, rr = cols[i], rows[i]
        for j in range(xs.shape[0]):  # branch-free, so that it vectorises
            u, v = cr[j], rr[j]
            inside = (u >= c_lo) & (u <= c_hi) & (v >= r_lo) & (v <= r_hi)
            outside += 0 if inside | math.isnan(u) else 1
            if blank:
                cr[j] = u if inside else empty
                rr[j] = v if inside else empty
        if i % RELIEF_ROWS == 0:
            relief_bits = max(relief_bits, _relief_row_bits(
                cr, rr, z[i], dx2, (ys[i] - y0) ** 2, photo, reference_height, z0,
                relief_line))
    stats[STAT_OUTSIDE_PHOTO] = outside
    stats[STAT_MAX_RELIEF] = math.sqrt(np.array([relief_bits]).view(np.float64)[0])


class CollinearityMap:
    """Ground tile + its heights -> photo pixel coordinates (a plain callable).

    ``cmap(transform, z)``: ``transform`` the tile's affine (north-up, pixel corner -> ground),
    ``z`` (h, w) heights of its cell centres (NaN: none). Returns float32 ``(cols, rows)`` in the
    photo's pixel convention (NaN: no image point). ``last_modes`` keeps the block modes of the
    last call (see :func:`block_modes`), ``last_box`` the bounding box of its finite
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
        """``(cols, rows, block modes, box)`` of a tile (thread-safe: no state kept); ``box``
        (col_min, row_min, col_max, row_max, NaN count) of the finite float32 coordinates."""
        z = np.ascontiguousarray(z, dtype="float64")
        cols, rows, modes, a, m = self._setup(transform, *z.shape)
        box = np.empty(5)
        box[4] = project_tile_projective(z, a, m, cols, rows)
        self._distort(z, a, cols, rows, modes, box)
        window_box(cols, rows, box)
        return cols, rows, modes, box

    def _distort(self, z: np.ndarray, a: np.ndarray, cols: np.ndarray, rows: np.ndarray,
                 modes: np.ndarray, box: np.ndarray, recount: bool = True,
                 shift: np.ndarray | None = None, modes_given: bool = False) -> None:
        """Add the distortion to a distortion-free map (in pixels minus ``shift``) in place
        (:func:`block_modes` unless ``modes_given``, :func:`distort_blocks`) and
        (``recount``) count its NaN cells into ``box[4]``; only the modes without
        distortion."""
        s = self.model
        if s.distortion[0] == 0:
            modes[:] = BLOCK_PROJECTIVE
            return
        if not modes_given:
            modes[:] = block_modes(cols, rows, self.block, s.lipschitz * s.f2p_condition,
                                   self.tolerance_px)
        distort_blocks(z, a, s.c, s.pp, *s.distortion, s.f2p, self.block, modes,
                       np.zeros(2) if shift is None else shift, cols, rows)
        if recount:
            box[4] = np.count_nonzero(np.isnan(cols))

    def _setup(self, transform: Any, h: int, w: int, out: tuple | None = None):
        """Output arrays (cols, rows, modes) and the matrices of :func:`tile_matrices`;
        ``out`` two float32 (h, w) arrays for the maps (else new ones)."""
        if transform.b != 0 or transform.d != 0:
            raise InputDataError("the output grid must be north-up")
        cols, rows = out if out is not None else (np.empty((h, w), dtype="float32"),
                                                  np.empty((h, w), dtype="float32"))
        b = self.block
        modes = np.empty(((h + b - 1) // b, (w + b - 1) // b), dtype=np.int8)
        a, m = tile_matrices(self.model, transform.c + 0.5 * transform.a,
                             transform.f + 0.5 * transform.e, transform.a, -transform.e)
        return cols, rows, modes, a, m

    def project_on_dem(self, transform: Any, xs: np.ndarray, ys: np.ndarray, dem: tuple,
                       centre: np.ndarray, reference_height: float, keep_heights: bool = False,
                       shift: tuple[float, float] | None = None, out: tuple | None = None):
        """Heights and map of a tile in one pass (:func:`ortho_window_projective`, then the
        distortion as :meth:`project` adds it): ``dem`` = (array, x and y of the centre of its
        cell [0, 0], cell sizes) as :meth:`DemSampler.part
        <toolbox.photogrammetry.orthophoto.DemSampler.part>` gives it, ``xs``/``ys`` the
        tile's cell centres. Returns ``(cols, rows, modes, stats, z)``: ``stats`` as
        :func:`ortho_window_projective` with the box in ``stats[:4]`` (with distortion its
        counts by :func:`count_window`), ``z`` the heights (None unless ``keep_heights``).

        With ``shift`` (col, row) the map is a planned one
        (:class:`~toolbox.raster.warp.SourcePlan`): ``pixel - shift``, and
        :data:`~toolbox.raster.warp.OUTSIDE` on the cells outside the photo or without image
        point, in the same pass (the shift enters the matrix); the box is then not computed.
        ``out``: two float32 (h, w) arrays to write the maps into."""
        h, w = len(ys), len(xs)
        cols, rows, modes, a, m = self._setup(transform, h, w, out)
        s = self.model
        keep = keep_heights or s.distortion[0] != 0  # the distortion pass needs them
        z = np.empty((h, w) if keep else (0, 0))
        stats = np.full(8, np.nan)
        xs = np.ascontiguousarray(xs, dtype="float64")
        ys = np.ascontiguousarray(ys, dtype="float64")
        offset = np.zeros(2) if shift is None else np.array(shift, dtype="float64")
        m = m - np.outer(np.append(offset, 0.0), m[2])  # (col - sc)·w = col·w - sc·w
        photo = np.array([-offset[0], s.width - offset[0], -offset[1], s.height - offset[1]])
        planned = shift is not None
        head = (np.asarray(centre, dtype="float64"), float(reference_height), photo)
        distorted = s.distortion[0] != 0
        # planned: spans, with the distortion's largest shift as slack when its pass follows
        slack = (s.max_distortion_px if distorted else 0.0) if planned else -1.0
        ortho_window_projective(dem[0], *(float(v) for v in dem[1:]), xs, ys, a, m, *head,
                                planned and not distorted, slack, z, cols, rows, stats)
        if distorted:
            block_modes_on_dem(dem[0], *(float(v) for v in dem[1:]), xs, ys, a, m, self.block,
                               s.lipschitz * s.f2p_condition, self.tolerance_px, modes)
            self._distort(z, a, cols, rows, modes, stats, recount=False, shift=offset,
                          modes_given=True)
            count_window(z, xs, ys, cols, rows, *head, planned, stats)
        else:
            modes[:] = BLOCK_PROJECTIVE
        if not planned:
            window_box(cols, rows, stats)
        return cols, rows, modes, stats, z if keep_heights else None

    def source_box(self, transform: Any, h: int, w: int, z_low: float, z_high: float
                   ) -> tuple[float, float, float, float] | None:
        """A bound of the photo pixels of every cell of an ``h`` x ``w`` tile whose heights lie
        in ``[z_low, z_high]``, before computing them: the cells are inside the 3-D box (tile
        centres x heights), whose image is the convex hull of its 8 corners' images when they
        are all in front of the camera (a central projection keeps convexity there; ``den`` is
        affine, so all corners in front means the whole box). The distortion moves a point by
        at most ``max_distortion_px``; 0.01 px covers the float32 maps. None when a corner is
        not in front of the camera."""
        a, m = tile_matrices(self.model, transform.c + 0.5 * transform.a,
                             transform.f + 0.5 * transform.e, transform.a, -transform.e)
        q = np.array([[0.0, w - 1.0] * 4, [0.0, 0.0, h - 1.0, h - 1.0] * 2,
                      [z_low] * 4 + [z_high] * 4, [1.0] * 8])
        if not (a[2] @ q < 0.0).all():
            return None
        hom = m @ q
        col, row = hom[0] / hom[2], hom[1] / hom[2]
        slack = self.model.max_distortion_px + 0.01
        return (float(col.min() - slack), float(row.min() - slack),
                float(col.max() + slack), float(row.max() + slack))


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
@njit(**FAST)
def heights_on_grid(dem, gx0, gy0, cx, cy, xs, ys, out):
    """Bilinear heights (between DEM cell centres, NaN outside or on nodata) at the grid points
    ``(xs[j], ys[i])``; ``dem`` cell [0, 0] centred at ``(gx0, gy0)``, cells ``cx`` x ``cy``.
    Separable: the column and row of every point are found once per column and once per row
    (the same arithmetic as the per-point ``_dem_height`` of the monoplot kernel)."""
    w = xs.shape[0]
    jj = np.empty(w, dtype=np.uint64)
    tx = np.empty(w)
    _dem_columns(dem.shape[1], gx0, cx, xs, jj, tx)
    _heights_rows(dem, gy0, cy, ys, jj, tx, 0, ys.shape[0], 0, out)


@njit(**FAST)
def _dem_columns(cols, gx0, cx, xs, jj, tx):
    """DEM column ``jj`` (unsigned: no negative-index check) and weight ``tx`` of every grid
    column; outside the DEM column 0 and weight NaN, so that the height is NaN."""
    for j in range(xs.shape[0]):
        fx = (xs[j] - gx0) / cx
        if fx >= 0.0 and fx <= cols - 1:
            jj[j] = min(int(fx), cols - 2)
            tx[j] = fx - jj[j]
        else:
            jj[j] = 0
            tx[j] = np.nan


@njit(**FAST)
def _heights_rows(dem, gy0, cy, ys, jj, tx, i0, i1, zoff, out):
    """Rows ``i0:i1`` of :func:`heights_on_grid` into ``out[i0 - zoff:i1 - zoff]``; returns the
    number of NaN heights. The two DEM rows around a grid row are interpolated along x once
    (kept while the grid rows stay between them), then every grid row is a blend of the two
    (vectorised, no gathers)."""
    rows = dem.shape[0]
    w = jj.shape[0]
    top = np.empty(w)
    bottom = np.empty(w)
    held = -2
    missing = 0
    for i in range(i0, i1):
        o = out[i - zoff]
        fy = (gy0 - ys[i]) / cy
        if not (fy >= 0.0 and fy <= rows - 1):
            o[:] = np.nan
            missing += w
            continue
        r = min(int(fy), rows - 2)
        ty = fy - r
        if r == held + 1:  # the grid rows go south: the old bottom row is the new top
            top, bottom = bottom, top
            _dem_row_along_x(dem[r + 1], jj, tx, bottom)
        elif r != held:
            _dem_row_along_x(dem[r], jj, tx, top)
            _dem_row_along_x(dem[r + 1], jj, tx, bottom)
        held = r
        for j in range(w):
            o[j] = top[j] * (1.0 - ty) + bottom[j] * ty
            missing += 1 if math.isnan(o[j]) else 0
    return missing


@njit(**FAST)
def _dem_row_along_x(d, jj, tx, out):
    """One DEM row interpolated at the grid columns (``jj``, ``tx`` of :func:`_dem_columns`)."""
    for j in range(jj.shape[0]):
        c = jj[j]
        t = tx[j]
        out[j] = d[c] * (1.0 - t) + d[c + 1] * t


@njit(cache=True, nogil=True)
def heights_at_points(dem, gx0, gy0, cx, cy, x, y, out):
    """As :func:`heights_on_grid` at scattered points ``(x[k], y[k])`` (1-D arrays)."""
    for k in range(x.shape[0]):
        out[k] = _dem_height(x[k], y[k], dem, gx0, gy0, cx, cy)[0]


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


def relief_displacement(x: np.ndarray, y: np.ndarray, z: np.ndarray, centre: np.ndarray,
                        reference_height: float) -> np.ndarray:
    """Ground displacement (m) a rectification on the plane ``Z = reference_height`` would leave
    at each cell: ``ρ·|Z - Zref| / (Z0 - Z)`` with ρ the horizontal distance from the nadir
    point (brief section 15, eq. [49] in ground units). ``x``, ``y`` broadcast to ``z`` (e.g.
    ``xs[None, :]`` and ``ys[:, None]``)."""
    dx, dy = x - centre[0], y - centre[1]
    rho = np.sqrt(dx * dx + dy * dy)  # not hypot: the operations of ortho_window_*
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
