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
    """Bilinear samples of ``window`` (grey, whose top-left pixel is full-image pixel ``origin``
    = (col0, row0)) on the grid ``centre + A·(i, j)``, i, j in -half..half (toolbox pixel
    coordinates, centres at +0.5). Shape (2·half + 1, 2·half + 1)."""
    import cv2

    k = np.arange(-half, half + 1, dtype="float64")
    jj, ii = np.meshgrid(k, k)  # jj along columns, ii along rows
    x = centre[0] + affine[0, 0] * jj + affine[0, 1] * ii - origin[0] - 0.5
    y = centre[1] + affine[1, 0] * jj + affine[1, 1] * ii - origin[1] - 0.5
    return cv2.remap(np.ascontiguousarray(window, dtype=np.float32), x.astype(np.float32),
                     y.astype(np.float32), cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


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


@dataclass
class Refined:
    xy: np.ndarray  # refined position in the other photo (2,)
    score: float  # NCC peak
    ok: bool


def refine_pair(ref_window: np.ndarray, ref_origin: tuple[int, int], ref_xy: np.ndarray,
                other_window: np.ndarray, other_origin: tuple[int, int], other_xy: np.ndarray,
                affine: np.ndarray, half: int = 10, radius: int = 4, min_score: float = 0.75
                ) -> Refined:
    """Refine ``other_xy`` so that it matches ``ref_xy``; windows must cover the patches."""
    template = sample(ref_window, ref_origin, ref_xy, np.eye(2), half)
    if float(template.std()) < 1.0:  # flat patch: no information
        return Refined(other_xy, float("nan"), False)
    search = sample(other_window, other_origin, other_xy, affine, half + radius)
    p = peak(scores(search, template))
    if p.on_border or not p.score >= min_score:
        return Refined(other_xy, p.score, False)
    d = np.array([p.x - radius, p.y - radius])
    return Refined(other_xy + affine @ d, p.score, True)
