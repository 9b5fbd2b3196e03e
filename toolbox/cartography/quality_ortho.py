"""Orthophoto accuracy measured on check points (S002 §2.6.6), by chip matching.

For each check point (surveyed ground X, Y, Z) measured by the operator on a photo (the image
measurement ``col_px``, ``row_px``: the target as the photo shows it), a *reference chip* is
resampled from that photo onto a north-up ground grid centred on the surveyed X, Y, at the
orthophoto's cell size: the ground grid is projected into the photo through the collinearity
equations on the plane Z = the point's height, then moved by the difference between the
operator's measurement and the point's projection, so that the chip's centre is the target by
construction, whatever the orientation's error. The chip is then found in the orthophoto by
normalised cross-correlation (:mod:`toolbox.matching.ncc`, sub-pixel parabola peak) within
``search`` metres. The offset found is where the orthophoto shows the target minus where it
was surveyed: the orthophoto's planimetric error at that point (orientation, DEM and
resampling errors together). The orientation shapes the chip only (scale and rotation over
a few metres), so its error hardly affects the offset. The chip takes the ground around the
point on the orthophoto's DEM when given (its relief, through the point's height), else on the
plane of the point's height: a point well off the orthophoto's DEM (on a roof, or a DEM of
another surface) shifts its surroundings by the relief displacement of that difference, and
the offset measures that too (the job compares each Z with the DEM when given).

Conventions: photo pixels ``(col, row)`` from the top-left corner, centres at +0.5; offsets in
ground units, east and north positive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MATCHED, NO_MATCH, AT_EDGE, OUTSIDE = "matched", "no match", "at search edge", "outside"


@dataclass
class CheckResult:
    """One check point measured on the orthophoto: offsets ``dx``, ``dy`` (ground units; NaN
    unless ``status`` is matched), the NCC ``score`` and the photo the chip came from."""

    point_id: str
    photo: str
    x: float
    y: float
    z: float
    dx: float = float("nan")
    dy: float = float("nan")
    score: float = float("nan")
    status: str = NO_MATCH
    dz_dem: float = float("nan")  # the point's Z minus the DEM's height there (if given)

    @property
    def distance(self) -> float:
        return float(np.hypot(self.dx, self.dy))


def _bilinear(image: np.ndarray, col: np.ndarray, row: np.ndarray) -> np.ndarray:
    """``image`` sampled at 0-based pixel-centre coordinates (NaN outside)."""
    import cv2

    out = cv2.remap(image.astype("float32"), col.astype("float32"), row.astype("float32"),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    return out


def ground_grid(x: float, y: float, cell: float, half: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres of a (2·half+1)² north-up grid centred on (x, y): row 0 is north."""
    k = np.arange(-half, half + 1) * cell
    gx, gy = np.meshgrid(x + k, y - k)
    return gx, gy


def photo_chip(photo, read_window, xyz: np.ndarray, measured_px: np.ndarray, cell: float,
               half: int, dem=None) -> np.ndarray | None:
    """The reference chip of one check point (see the module docstring): ``read_window(c0,
    r0, c1, r1)`` returns the photo's grey values of columns c0..c1-1, rows r0..r1-1 (clipped
    to the photo, with the origin actually read). None when the chip leaves the photo (or lies
    behind it: a wrong point id on an oblique photo).

    ``dem`` (the orthophoto's surface, with ``height(x, y)``): the chip's ground follows its
    relief, raised or lowered to pass through the point (``Z + dem(x, y) - dem(X, Y)``), as the
    orthophoto shows it; on a plane at Z a steep slope around the point is displaced in the
    chip and not in the orthophoto, and the match moves (12 m on a 10 m NGI ortho)."""
    gx, gy = ground_grid(xyz[0], xyz[1], cell, half)
    gz = np.full_like(gx, xyz[2])
    if dem is not None:
        relief = dem.height(gx.ravel(), gy.ravel()).reshape(gx.shape) - \
            dem.height(np.array([xyz[0]]), np.array([xyz[1]]))[0]
        gz = np.where(np.isfinite(relief), gz + relief, gz)  # off the DEM: the point's plane
    pts = np.stack([gx, gy, gz], axis=-1).reshape(-1, 3)
    predicted = photo.ground_to_pixel(np.asarray(xyz, float)[None, :], behind="nan")[0]
    px = photo.ground_to_pixel(pts, behind="nan") + (np.asarray(measured_px, float) - predicted)
    if not np.isfinite(px).all():  # the point (or its chip) behind the photo: no chip
        return None
    c0, r0 = np.floor(px.min(axis=0)).astype(int) - 2
    c1, r1 = np.ceil(px.max(axis=0)).astype(int) + 2
    window, (oc, orow) = read_window(c0, r0, c1, r1)
    if window is None or window.size == 0:
        return None
    col = px[:, 0] - 0.5 - oc  # pixel-centre convention -> 0-based array coordinates
    row = px[:, 1] - 0.5 - orow
    chip = _bilinear(window, col.reshape(gx.shape), row.reshape(gx.shape))
    return None if np.isnan(chip).any() else chip


def ortho_window(ortho: np.ndarray, transform, x: float, y: float, cell: float, half: int
                 ) -> np.ndarray:
    """The orthophoto (grey array, rasterio ``transform``) sampled on the ground grid of
    (2·half+1)² cells of ``cell`` centred on (x, y) (NaN outside)."""
    gx, gy = ground_grid(x, y, cell, half)
    inverse = ~transform
    col, row = inverse * (gx, gy)
    return _bilinear(ortho, np.asarray(col) - 0.5, np.asarray(row) - 0.5)


def match_offset(chip: np.ndarray, search: np.ndarray, cell: float, min_score: float
                 ) -> tuple[float, float, float, str]:
    """(dx, dy, score, status): where ``chip`` lies in ``search`` (both centred on the same
    ground point, north-up grids of ``cell``) relative to the centre, east and north."""
    from toolbox.matching.ncc import peak, scores

    if np.isnan(search).any():
        return float("nan"), float("nan"), float("nan"), OUTSIDE
    if float(chip.std()) < 1e-6:
        return float("nan"), float("nan"), float("nan"), NO_MATCH
    score = scores(search.astype("float32"), chip.astype("float32"))
    p = peak(score)
    s = (score.shape[1] - 1) / 2.0
    dx, dy = (p.x - s) * cell, -(p.y - s) * cell
    if p.on_border:
        return float("nan"), float("nan"), p.score, AT_EDGE
    if not p.score >= min_score:
        return float("nan"), float("nan"), p.score, NO_MATCH
    return float(dx), float(dy), float(p.score), MATCHED


def summary(results: list[CheckResult]) -> dict:
    """Counts and RMSE (x, y, planimetric) of the matched points; None without any."""
    ok = [r for r in results if r.status == MATCHED]
    out: dict = {"points": len(results), "matched": len(ok),
                 "by_status": {s: sum(r.status == s for r in results)
                               for s in dict.fromkeys(r.status for r in results)}}
    if ok:
        dx = np.array([r.dx for r in ok])
        dy = np.array([r.dy for r in ok])
        out |= {"rmse_x_m": float(np.sqrt(np.mean(dx ** 2))),
                "rmse_y_m": float(np.sqrt(np.mean(dy ** 2))),
                "rmse_planimetric_m": float(np.sqrt(np.mean(dx ** 2 + dy ** 2))),
                "mean_x_m": float(dx.mean()), "mean_y_m": float(dy.mean()),
                "largest_m": float(np.hypot(dx, dy).max()),
                "offsets": [{"id": r.point_id, "photo": r.photo, "x": r.x, "y": r.y,
                             "dx": r.dx, "dy": r.dy, "score": r.score} for r in ok[:2000]]}
    else:
        out |= {"rmse_x_m": None, "rmse_y_m": None, "rmse_planimetric_m": None}
    return out
