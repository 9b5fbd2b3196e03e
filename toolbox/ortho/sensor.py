"""The film camera as a compiled coordinate map: a photo's ground -> pixel model as plain arrays
(:class:`SensorModel`, its distortion bounds) and :class:`CollinearityMap`, the map of an output
window on its heights.

The collinearity equations without distortion are a 3 x 4 projective matrix applied to
``(j, i, Z, 1)`` (:func:`tile_matrices`): the kernels (:mod:`toolbox.ortho.kernels`) evaluate
them exactly at every cell; the radial distortion is added by :mod:`toolbox.ortho.distortion`,
blended on blocks only where its error bound (0.05 px by default) is proven.

Conventions as :mod:`toolbox.photogrammetry`: photo pixels ``(col, row)`` from the top-left
corner, centres at +0.5; output grids north-up, column ``j`` centre ``x = xmin + (j + 0.5)·cell``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.ortho.distortion import (
    BLOCK_PROJECTIVE,
    DEFAULT_BLOCK,
    DEFAULT_TOLERANCE_PX,
    block_modes,
    block_modes_on_dem,
    distort_blocks,
)
from toolbox.ortho.kernels import (
    count_window,
    ortho_window_projective,
    project_tile_projective,
    window_box,
)
from toolbox.raster.maps import OUTSIDE


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
    """Bound of the distortion's shift of a point (mm) for measured radii up to ``radius_mm``
    (:meth:`~toolbox.photogrammetry.camera.RadialDistortion.magnitude_bound`); 0 without."""
    return 0.0 if distortion is None else distortion.magnitude_bound(radius_mm)


def distortion_lipschitz(distortion: Any, radius_mm: float) -> float:
    """Bound of the Jacobian norm of ``δ(p) = distort(p) - p`` for radii up to ``radius_mm``
    (:meth:`~toolbox.photogrammetry.camera.RadialDistortion.lipschitz_bound`); 0 without."""
    return 0.0 if distortion is None else distortion.lipschitz_bound(radius_mm)


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
        <toolbox.ortho.dem.DemSampler.part>` gives it, ``xs``/``ys`` the
        tile's cell centres. Returns ``(cols, rows, modes, stats, z)``: ``stats`` as
        :func:`ortho_window_projective` with the box in ``stats[:4]`` (with distortion its
        counts by :func:`count_window`), ``z`` the heights (None unless ``keep_heights``).

        With ``shift`` (col, row) the map is a planned one
        (:class:`~toolbox.raster.maps.SourcePlan`): ``pixel - shift``, and
        :data:`~toolbox.raster.maps.OUTSIDE` on the cells outside the photo or without image
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
        blank = float(OUTSIDE) if planned else np.nan  # the planned map's empty cells
        head = (np.asarray(centre, dtype="float64"), float(reference_height), photo)
        distorted = s.distortion[0] != 0
        # planned: spans, with the distortion's largest shift as slack when its pass follows
        slack = (s.max_distortion_px if distorted else 0.0) if planned else -1.0
        ortho_window_projective(dem[0], *(float(v) for v in dem[1:]), xs, ys, a, m, *head,
                                blank if not distorted else np.nan, slack, z, cols, rows,
                                stats)
        if distorted:
            block_modes_on_dem(dem[0], *(float(v) for v in dem[1:]), xs, ys, a, m, self.block,
                               s.lipschitz * s.f2p_condition, self.tolerance_px, modes)
            self._distort(z, a, cols, rows, modes, stats, recount=False, shift=offset,
                          modes_given=True)
            count_window(z, xs, ys, cols, rows, *head, blank, stats)
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
