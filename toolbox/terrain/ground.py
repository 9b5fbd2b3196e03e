"""Ground filtering: which points (or DSM cells) lie on the bare earth.

The simple morphological filter SMRF (Pingel, Clarke and McBride 2013, ISPRS J. 77: 21-30),
itself a refinement of Zhang et al.'s progressive morphological filter (2003, IEEE TGRS 41(4)):

1. **minimum surface** ``Zmin``: the lowest point of each ``cell`` x ``cell`` cell; empty cells
   are inpainted (OpenCV Navier-Stokes), as Pingel et al. inpaint them: a nearest-value fill
   would leave steps, a linear or harmonic one kinks and cones at sparse points, which the
   openings take for objects;
2. **progressive opening** (the grid padded by odd reflection, so slopes run on past its
   edges): for window radius r = 1, 2, ..., ceil(max_window / cell) cells,
   ``Zopen = opening(Zlast, (2r+1) x (2r+1) square)`` (scipy.ndimage grey opening, flat square
   window: separable, fast); a cell whose drop ``Zlast - Zopen`` exceeds
   ``slope * r * cell`` is an object; ``Zlast = Zopen``. Objects wider than ``2 max_window`` stay;
3. **provisional DTM**: ``Zmin`` without the object cells, the holes filled by harmonic
   interpolation from the ground cells around them (Laplace's equation: smooth, exact for
   planes; inpainting above 400,000 hole cells);
4. **points**: a point is ground when ``|z - DTM(x, y)| <= elevation_threshold +
   elevation_scalar * s(x, y)``, with ``DTM`` bilinear and ``s`` its slope (rise/run).

Arrays in, arrays out; coordinates local (shifted), the grid row 0 at the north edge.
The filter grid is held in memory (cells = extent / cell^2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DIRECT_SOLVE_LIMIT = 400_000  # hole cells solved directly; more are inpainted


@dataclass(frozen=True)
class GroundFilter:
    """SMRF parameters (lengths in CRS units; slope as rise/run)."""

    cell: float = 1.0  # cell of the minimum surface
    slope: float = 0.15  # terrain slope allowed between openings (rise/run)
    max_window: float = 18.0  # largest opening window (about the largest building)
    elevation_threshold: float = 0.5  # height above the surface still called ground
    elevation_scalar: float = 1.25  # extra threshold per unit of local slope

    @property
    def radii(self) -> range:
        return range(1, max(1, math.ceil(self.max_window / self.cell)) + 1)


@dataclass
class MinimumSurface:
    """The minimum-height grid: ``z`` (rows, cols) with NaN where no point fell;
    ``x0``, ``y1`` the west and north edges; ``cell`` the side."""

    z: np.ndarray
    x0: float
    y1: float
    cell: float

    def rowcol(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional (row, col) of map points in pixel-centre units (centre of cell 0 = 0)."""
        return (self.y1 - y) / self.cell - 0.5, (x - self.x0) / self.cell - 0.5


def minimum_surface(xyz: np.ndarray, cell: float) -> MinimumSurface:
    """Lowest z per cell of ``xyz`` (local coordinates), on a grid covering the points."""
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    x0, y1 = math.floor(x.min() / cell) * cell, math.ceil(y.max() / cell) * cell
    if y1 == y.max():
        y1 += cell
    cols = np.minimum((x - x0) // cell, np.inf).astype(np.int64)
    rows = ((y1 - y) // cell).astype(np.int64)
    height, width = int(rows.max()) + 1, int(cols.max()) + 1
    flat = np.full(height * width, np.inf)
    np.minimum.at(flat, rows * width + cols, z)
    flat[np.isinf(flat)] = np.nan
    return MinimumSurface(flat.reshape(height, width), x0, y1, cell)


def object_cells(zmin_filled: np.ndarray, flt: GroundFilter) -> np.ndarray:
    """Step 2: boolean grid, True where the progressive opening flags an object."""
    from scipy import ndimage

    # odd reflection continues the slopes across the edges (a plane stays a plane), so the
    # openings do not cut the terrain rising towards the grid's border
    pad = max(flt.radii)
    last = np.pad(zmin_filled, pad, mode="reflect", reflect_type="odd") \
        if min(zmin_filled.shape) > pad else np.pad(zmin_filled, pad, mode="edge")
    objects = np.zeros(last.shape, dtype=bool)
    for r in flt.radii:
        opened = ndimage.grey_opening(last, size=(2 * r + 1, 2 * r + 1), mode="nearest")
        objects |= (last - opened) > flt.slope * r * flt.cell
        last = opened
    return objects[pad:-pad, pad:-pad]


def fill_harmonic(z: np.ndarray) -> np.ndarray:
    """NaN cells filled by harmonic interpolation (Laplace's equation over the holes, the known
    cells as boundary values, no flux across the grid's edges): exact on the known cells, smooth
    across holes, and exact for planes (a linear surface is harmonic). A sparse direct solve
    (scipy SuperLU) over the hole cells only; above :data:`DIRECT_SOLVE_LIMIT` hole cells,
    :func:`fill_inpaint`."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    holes = np.isnan(z)
    if not holes.any():
        return z.copy()
    if holes.all():
        raise ValueError("the grid has no value to fill from")
    if holes.sum() > DIRECT_SOLVE_LIMIT:  # the direct solve's memory grows faster than n
        return fill_inpaint(z)
    rows, cols = z.shape
    index = np.full(z.shape, -1, dtype=np.int64)
    hr, hc = np.nonzero(holes)
    n = len(hr)
    index[hr, hc] = np.arange(n)
    diag = np.zeros(n)
    rhs = np.zeros(n)
    i_parts, j_parts = [], []
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        nr, nc = hr + dr, hc + dc
        ok = (nr >= 0) & (nr < rows) & (nc >= 0) & (nc < cols)
        diag += ok
        unknown = np.zeros(n, bool)
        unknown[ok] = holes[nr[ok], nc[ok]]
        known = ok & ~unknown
        rhs[known] += z[nr[known], nc[known]]
        i_parts.append(np.flatnonzero(unknown))
        j_parts.append(index[nr[unknown], nc[unknown]])
    i, j = np.concatenate(i_parts), np.concatenate(j_parts)
    matrix = sparse.csr_matrix((np.r_[diag, -np.ones(len(i))],
                                (np.r_[np.arange(n), i], np.r_[np.arange(n), j])), shape=(n, n))
    out = z.copy()
    out[hr, hc] = spsolve(matrix.tocsc(), rhs)
    return out


def fill_inpaint(z: np.ndarray) -> np.ndarray:
    """NaN cells filled by OpenCV's Navier-Stokes inpainting (``cv2.INPAINT_NS``, radius 3
    cells, float32 heights relative to their minimum): smooth across scattered or large holes,
    fast, exact on the known cells (not exact for planes: see :func:`fill_harmonic`)."""
    import cv2

    holes = np.isnan(z)
    if not holes.any():
        return z.copy()
    if holes.all():
        raise ValueError("the grid has no value to fill from")
    base = float(np.nanmin(z))
    src = np.where(holes, 0.0, z - base).astype(np.float32)
    filled = cv2.inpaint(src, holes.astype(np.uint8), 3, cv2.INPAINT_NS)
    return np.where(holes, filled.astype(np.float64) + base, z)


def provisional_dtm(zmin: np.ndarray, objects: np.ndarray) -> np.ndarray:
    """Step 3: ``zmin`` with object and empty cells filled from the ground cells."""
    ground = np.where(objects, np.nan, zmin)
    if np.isnan(ground).all():
        raise ValueError("every cell is an object: lower SLOPE or MAX_WINDOW")
    return fill_harmonic(ground)


def classify_points(xyz: np.ndarray, surface: MinimumSurface, dtm: np.ndarray,
                    flt: GroundFilter) -> np.ndarray:
    """Step 4: boolean (N,), True for ground points."""
    from scipy import ndimage

    rows, cols = surface.rowcol(xyz[:, 0], xyz[:, 1])
    coords = np.vstack([rows, cols])
    height = ndimage.map_coordinates(dtm, coords, order=1, mode="nearest")
    # a grid one cell wide (a strip of points, a one-row DSM) has no slope across it
    gy, gx = (np.gradient(dtm, flt.cell, axis=axis) if dtm.shape[axis] > 1
              else np.zeros_like(dtm) for axis in (0, 1))
    slope = ndimage.map_coordinates(np.hypot(gx, gy), coords, order=1, mode="nearest")
    return np.abs(xyz[:, 2] - height) <= flt.elevation_threshold + flt.elevation_scalar * slope


@dataclass
class GroundResult:
    """``ground`` (N,) bool per point; the filter's grids for inspection."""

    ground: np.ndarray
    surface: MinimumSurface
    objects: np.ndarray
    dtm: np.ndarray


def smrf(xyz: np.ndarray, flt: GroundFilter) -> GroundResult:
    """Classify ``xyz`` (N, 3, local coordinates) into ground / non-ground (steps 1-4)."""
    surface = minimum_surface(xyz, flt.cell)
    zmin = fill_inpaint(surface.z)
    objects = object_cells(zmin, flt)
    objects |= np.isnan(surface.z)  # empty cells are filled from ground cells, not kept
    dtm = provisional_dtm(zmin, objects)
    return GroundResult(classify_points(xyz, surface, dtm, flt), surface, objects, dtm)
