"""Writing a tie-point result: the image-measurement CSV that orientation:intersect,
orientation:resection and orientation:bundle read, the per-pair table, and ground positions of
the tie points by forward intersection when every photo of a track is oriented."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toolbox.matching.block import TiePointResult
from toolbox.matching.matching import has_camera, normaliser
from toolbox.photogrammetry.tables import write_csv

MEASUREMENT_COLUMNS = ["point_id", "photo", "col_px", "row_px", "sigma_px"]
PAIR_COLUMNS = ["photo_a", "photo_b", "overlap_percent", "candidates", "verified", "kept",
                "cells_3x3", "median_residual_px", "median_epipolar_px", "status"]


def point_ids(result: TiePointResult) -> list[str]:
    width = max(6, len(str(len(result.tracks))))
    return [f"T{k + 1:0{width}d}" for k in range(len(result.tracks))]


def write_measurements(path: Path, result: TiePointResult) -> int:
    """One row per observation (pixels: top-left pixel centre at (0.5, 0.5)); returns the rows."""
    rows = []
    for pid, track in zip(point_ids(result), result.tracks, strict=True):
        for p, (col, row), s in zip(track.photos, track.xy, track.sigma, strict=True):
            rows.append([pid, result.photos[p].id, round(float(col), 4), round(float(row), 4),
                         round(float(s), 3)])
    write_csv(path, MEASUREMENT_COLUMNS, rows)
    return len(rows)


def write_pairs(path: Path, result: TiePointResult) -> None:
    def num(v, digits=3):
        return None if v is None else round(float(v), digits)

    write_csv(path, PAIR_COLUMNS, [
        [r.a, r.b, num(r.overlap_percent, 2), r.candidates, r.verified, r.kept, r.cells_3x3,
         num(r.median_f_residual_px), num(r.median_epipolar_px), r.status] for r in result.pairs])


def ground_points(result: TiePointResult) -> tuple[np.ndarray, np.ndarray]:
    """Intersected ground positions (P, 3; NaN where a track has an unoriented photo or does
    not intersect) and the largest reprojection residual per track (px)."""
    from toolbox.photogrammetry.forward_intersection import intersect

    n = len(result.tracks)
    xyz = np.full((n, 3), np.nan)
    worst = np.full(n, np.nan)
    usable = [k for k, t in enumerate(result.tracks)
              if all(result.photos[p].photo is not None
                     and result.photos[p].photo.exterior is not None
                     and has_camera(result.photos[p].photo) for p in t.photos)]
    if not usable:
        return xyz, worst
    index, photos, obs = [], [], []
    for k in usable:
        t = result.tracks[k]
        for p, xy in zip(t.photos, t.xy, strict=True):
            index.append(k)
            photos.append(result.photos[p].photo)
            obs.append(xy)
    index = np.array(index)
    obs = np.array(obs)
    # normalised camera coordinates (principal distance 1): film and model cameras alike
    cam = np.empty_like(obs)
    ids = np.array([p.id for p in photos])
    for pid in dict.fromkeys(ids.tolist()):
        rows = np.flatnonzero(ids == pid)
        cam[rows] = normaliser(photos[rows[0]])(obs[rows])
    res = intersect(index, cam, np.array([p.exterior.centre for p in photos]),
                    np.array([p.exterior.rotation for p in photos]), np.ones(len(photos)), n)
    ok = res.ok
    xyz[ok] = res.xyz[ok]
    for pid in dict.fromkeys(ids.tolist()):
        rows = np.flatnonzero((ids == pid) & ok[index])
        if len(rows):
            back = photos[rows[0]].ground_to_pixel(res.xyz[index[rows]], behind="nan")
            np.fmax.at(worst, index[rows], np.hypot(*(back - obs[rows]).T))
    return xyz, worst
