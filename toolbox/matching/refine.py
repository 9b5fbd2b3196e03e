"""Sub-pixel refinement of a match on full-resolution patches (NCC, :mod:`toolbox.matching.ncc`).

The reference photo's patch (``2·half + 1`` pixels square, centred on the reference point) is
searched in the other photo resampled into the reference's frame by the local affine ``A``
(2 x 2: a displacement in the reference -> in the other photo; from the neighbouring matches),
so rotation, scale and shear between the photos do not reduce the correlation. The NCC peak
gives the shift ``d`` (reference frame); the refined point is ``x_o + A·d``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolbox.matching.ncc import peak, scores


def sample(window: np.ndarray, origin: tuple[int, int], centre: np.ndarray, affine: np.ndarray,
           half: int) -> np.ndarray:
    """Lanczos (8 x 8) samples of ``window`` (grey, whose top-left pixel is full-image pixel ``origin``
    = (col0, row0)) on the grid ``centre + A·(i, j)``, i, j in -half..half (toolbox pixel
    coordinates, centres at +0.5). Shape (2·half + 1, 2·half + 1)."""
    import cv2

    k = np.arange(-half, half + 1, dtype="float64")
    jj, ii = np.meshgrid(k, k)  # jj along columns, ii along rows
    x = centre[0] + affine[0, 0] * jj + affine[0, 1] * ii - origin[0] - 0.5
    y = centre[1] + affine[1, 0] * jj + affine[1, 1] * ii - origin[1] - 0.5
    return cv2.remap(np.ascontiguousarray(window, dtype=np.float32), x.astype(np.float32),
                     y.astype(np.float32), cv2.INTER_LANCZOS4, borderMode=cv2.BORDER_REPLICATE)


def local_affine(ref_xy: np.ndarray, other_xy: np.ndarray, at: np.ndarray, k: int = 12
                 ) -> np.ndarray | None:
    """2 x 2 linear part of the affine fitted (least squares) on the ``k`` matches nearest to
    ``at`` in the reference photo; None with fewer than 4 matches or a degenerate fit."""
    if len(ref_xy) < 4:
        return None
    d = np.hypot(*(ref_xy - at).T)
    near = np.argsort(d)[:k]
    a = np.column_stack([ref_xy[near] - at, np.ones(len(near))])
    sol, _, rank, _ = np.linalg.lstsq(a, other_xy[near], rcond=None)
    if rank < 3:
        return None
    lin = sol[:2].T
    det = np.linalg.det(lin)
    if not np.isfinite(det) or abs(det) < 1e-3:
        return None
    return lin


def lsm(template: np.ndarray, window: np.ndarray, origin: tuple[int, int], xy: np.ndarray,
        affine: np.ndarray, half: int, iterations: int = 8, tolerance: float = 0.002
        ) -> np.ndarray | None:
    """Least-squares matching (Gruen 1985), shift and radiometry only: Gauss-Newton on
    ``T(u) = r0 + r1·S(u + d)`` with ``S`` the other photo resampled by the affine around
    ``xy``; returns the refined ``xy`` or None when it diverges (more than 1.5 px)."""
    start = xy.copy()
    t = template.astype("float64").ravel()
    for _ in range(iterations):
        big = sample(window, origin, xy, affine, half + 1).astype("float64")
        core = big[1:-1, 1:-1]
        gx = 0.5 * (big[1:-1, 2:] - big[1:-1, :-2])
        gy = 0.5 * (big[2:, 1:-1] - big[:-2, 1:-1])
        design = np.column_stack([np.ones(core.size), core.ravel(), gx.ravel(), gy.ravel()])
        sol, *_ = np.linalg.lstsq(design, t, rcond=None)
        if not abs(sol[1]) > 1e-6:
            return None
        d = sol[2:] / sol[1]
        xy = xy + affine @ d
        if np.hypot(*(xy - start)) > 1.5:
            return None
        if np.hypot(*d) < tolerance:
            break
    return xy


@dataclass
class Refined:
    xy: np.ndarray  # refined position in the other photo (2,)
    score: float  # NCC peak
    ok: bool


def refine_pair(ref_window: np.ndarray, ref_origin: tuple[int, int], ref_xy: np.ndarray,
                other_window: np.ndarray, other_origin: tuple[int, int], other_xy: np.ndarray,
                affine: np.ndarray, half: int = 10, radius: int = 4, min_score: float = 0.75
                ) -> Refined:
    """Refine ``other_xy`` so that it matches ``ref_xy``; windows must cover the patches.

    The template is taken on the reference's own pixels (centred on the pixel holding
    ``ref_xy``, no interpolation); the offset to ``ref_xy`` is carried over by ``A``.
    """
    centre = np.floor(ref_xy) + 0.5
    other_xy = other_xy + affine @ (centre - ref_xy)
    template = sample(ref_window, ref_origin, centre, np.eye(2), half)
    if float(template.std()) < 1.0:  # flat patch: no information
        return Refined(other_xy + affine @ (ref_xy - centre), float("nan"), False)
    search = sample(other_window, other_origin, other_xy, affine, half + radius)
    p = peak(scores(search, template))
    if p.on_border or not p.score >= min_score:
        return Refined(other_xy + affine @ (ref_xy - centre), p.score, False)
    xy = other_xy + affine @ np.array([p.x - radius, p.y - radius])
    # NCC's parabola is biased by a few hundredths of a pixel (an NCC surface is not symmetric
    # about its peak for a finite template): finish by least-squares matching
    xy = lsm(template, other_window, other_origin, xy, affine, half)
    if xy is None:
        return Refined(other_xy + affine @ (ref_xy - centre), p.score, False)
    return Refined(xy + affine @ (ref_xy - centre), p.score, True)
