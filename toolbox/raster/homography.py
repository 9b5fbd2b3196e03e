"""The coordinate map of a plane-to-plane homography (rectification): a
:class:`~toolbox.raster.maps.PerspectiveMap` (exact bounds, inside intervals, the matrix for
``cv2.warpPerspective``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.raster.maps import mask_from_intervals, window_parts


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
        col0, row0, width, height = window_parts(window)
        j = np.arange(col0, col0 + width, dtype="float64")
        i = np.arange(row0, row0 + height, dtype="float64")
        m = self.matrix
        return [((m[k, 0] * j).astype("float32")[None, :],
                 (m[k, 1] * i + m[k, 2]).astype("float32")[:, None]) for k in range(3)]

    def corner_coordinates(self, window: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Source (cols, rows) and ``w`` of the window's four corner pixel centres (float64)."""
        col0, row0, width, height = window_parts(window)
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
        col0, row0, _, _ = window_parts(window)
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
        col0, row0, out_w, out_h = window_parts(window)
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
