"""Measuring a control point automatically against a reference orthophoto.

The ortho chip is reprojected into the photo: the photo pixels around the predicted position
(``2·half + 1`` square, on the pixel centres around the prediction) are cast to the ground
through the APPROXIMATE orientation (onto the DEM, or the plane ``Z = Z_control``) and the
orthophoto is sampled there (bilinear, grey = mean of the first three bands). That synthetic chip is what the
photo would show if the orientation were right; with the orientation a little off, the real
photo shows the same chip shifted by the prediction error. The shift is the peak of the
normalised cross-correlation (:mod:`toolbox.matching.ncc`) over ``±radius`` pixels, finished by
least-squares matching (shift and radiometry, :func:`toolbox.matching.refine.lsm`).

With a DEM the pixels are cast onto it (monoplotting): the chip then has the photo's relief
displacement. Without one, the plane through the point is exact at the point only: relief
around it displaces the chip's pixels by ``Δh·r/H`` and biases the peak (measured on the demo
landscape, 30 m of relief, 430 m flying height: up to 2 px without the DEM, 0.02 px with it).

Statuses: ``matched`` (position measured), ``low_correlation`` (peak below ``min_score``),
``ambiguous`` (a second peak, farther than ``half`` pixels, within ``ambiguity`` of the best:
a repeated pattern), ``on_border`` (the peak at the edge of the search: the point may lie
farther than ``radius``), ``flat`` (no texture in the chip), ``off_ortho`` (the chip leaves the
orthophoto), ``off_photo`` (the search window leaves the photo), ``diverged`` (least squares
moved more than 1.5 px from the NCC peak). Only ``matched`` moves the point.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.errors import InputDataError
from toolbox.matching.images import ImageSource
from toolbox.matching.ncc import peak, scores
from toolbox.matching.refine import lsm
from toolbox.raster.photo_grid import open_photo_grid


@dataclass
class OrthoReference:
    """A georeferenced orthophoto on disk (any band count; grey = mean of the first three; its
    CRS, None when it has none, is for the caller to judge)."""

    path: Path
    transform: object  # affine.Affine, pixel corner -> ground
    crs: object
    width: int
    height: int
    bands: int

    @classmethod
    def open(cls, path: str | Path, name: str = "ORTHO") -> OrthoReference:
        import rasterio

        path = Path(path)
        try:
            with open_photo_grid(path) as src:  # a paletted one: its colours
                from toolbox.io.raster import dataset_transform

                info = cls(path, dataset_transform(src),
                           src.crs, src.width, src.height, src.count)
        except rasterio.errors.RasterioError as exc:
            raise InputDataError(f"{name}: cannot read {path}: "
                                 f"{str(exc).splitlines()[0]}") from None
        t = info.transform
        if t.b != 0 or t.d != 0 or t.a <= 0 or t.e >= 0:  # its CRS: the caller's to judge
            raise InputDataError(f"{name}: {path} must be a north-up georeferenced raster (a "
                                 f"transform without rotation), got transform={tuple(t)[:6]}")
        return info

    def sample(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Grey values (float32, bilinear) at ground ``x``, ``y`` (same shape); NaN outside and
        next to nodata."""
        import cv2
        from rasterio.windows import Window

        t = self.transform
        col = (np.asarray(x, dtype="float64") - t.c) / t.a - 0.5  # pixel-centre coordinates
        row = (np.asarray(y, dtype="float64") - t.f) / t.e - 0.5
        out = np.full(np.shape(col), np.nan, dtype="float32")
        inside = (col >= 0) & (row >= 0) & (col <= self.width - 1) & (row <= self.height - 1)
        if not inside.any():
            return out
        c0, r0 = int(np.floor(col[inside].min())), int(np.floor(row[inside].min()))
        c1 = min(self.width, int(np.ceil(col[inside].max())) + 2)
        r1 = min(self.height, int(np.ceil(row[inside].max())) + 2)
        from toolbox.io.raster import read_dataset_masked

        with open_photo_grid(self.path) as src:  # one mask: a (0, 3, 8) shadow is data
            data = read_dataset_masked(src, [1, 2, 3] if self.bands >= 3 else [1],
                                       Window(c0, r0, c1 - c0, r1 - r0))
        grey = np.ascontiguousarray(data.data.astype("float32").mean(axis=0))
        grey[np.ma.getmaskarray(data)[0]] = np.nan  # nodata: NaN spreads to the chip
        values = cv2.remap(grey, (col - c0).astype(np.float32).reshape(1, -1),
                           (row - r0).astype(np.float32).reshape(1, -1), cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_REPLICATE).reshape(out.shape)
        out[inside] = values[inside]
        return out


@dataclass
class ChipMatch:
    """Result for one point on one photo: measured (or, unless matched, predicted) pixel, the
    NCC peak, the runner-up peak (NaN if none), the shift from the prediction (px), status."""

    col_px: float
    row_px: float
    score: float
    runner_up: float
    shift_px: float
    status: str


def ortho_chip(photo, ortho: OrthoReference, centre: np.ndarray, z: float, half: int,
               surface=None) -> np.ndarray:
    """The orthophoto seen through ``photo``'s orientation: grey values at the photo pixels
    ``centre + (i, j)``, i, j in -half..half, cast to the DEM ``surface`` (a
    :class:`~toolbox.photogrammetry.surface.DemSurface`) or, without one, to the plane
    ``Z = z``. Shape (2h+1, 2h+1); NaN where a ray misses."""
    k = np.arange(-half, half + 1, dtype="float64")
    jj, ii = np.meshgrid(k, k)
    pixels = np.column_stack([(centre[0] + jj).ravel(), (centre[1] + ii).ravel()])
    if surface is None:
        ground = photo.pixel_to_ground(pixels, z, invalid="nan")
    else:
        hit = photo.monoplot_pixels(pixels, surface)
        ground = np.where(hit.ok[:, None], hit.xyz, np.nan)
    return ortho.sample(ground[:, 0], ground[:, 1]).reshape(jj.shape)


def match_point(photo, source: ImageSource, ortho: OrthoReference, predicted: np.ndarray,
                z: float, half: int = 15, radius: int = 20, min_score: float = 0.7,
                ambiguity: float = 0.05, surface=None) -> ChipMatch:
    """Measure the control point predicted at pixel ``predicted`` (col, row) at height ``z`` on
    ``photo`` against the orthophoto (module docstring); ``surface``: the DEM, when known."""
    predicted = np.asarray(predicted, dtype="float64")
    centre = np.floor(predicted) + 0.5  # the pixel centre holding the prediction
    offset = predicted - centre

    def flagged(status: str, score: float = float("nan"), runner: float = float("nan")):
        return ChipMatch(float(predicted[0]), float(predicted[1]), score, runner, 0.0, status)

    template = ortho_chip(photo, ortho, centre, z, half, surface)
    if not np.isfinite(template).all():
        return flagged("off_ortho")
    if float(template.std()) < 1.0:
        return flagged("flat")
    reach = half + radius + 2
    if not (reach <= centre[0] <= source.width - reach
            and reach <= centre[1] <= source.height - reach):
        return flagged("off_photo")
    c0, r0 = int(centre[0]) - reach, int(centre[1]) - reach
    window = source.window(c0, r0, 2 * reach + 1, 2 * reach + 1).astype("float32")
    h = half + radius
    search = window[reach - h:reach + h + 1, reach - h:reach + h + 1]
    p = peak(scores(search, template), exclusion=max(3.0, half / 2))
    if not p.score >= min_score:
        return flagged("low_correlation", p.score, p.runner_up)
    if p.on_border:
        return flagged("on_border", p.score, p.runner_up)
    if np.isfinite(p.runner_up) and p.runner_up >= p.score - ambiguity:
        return flagged("ambiguous", p.score, p.runner_up)
    found = centre + np.array([p.x - radius, p.y - radius])
    refined = lsm(template, window, (c0, r0), found, np.eye(2), half)
    if refined is None:
        return flagged("diverged", p.score, p.runner_up)
    xy = refined + offset
    return ChipMatch(float(xy[0]), float(xy[1]), p.score, p.runner_up,
                     float(np.hypot(*(xy - predicted))), "matched")
