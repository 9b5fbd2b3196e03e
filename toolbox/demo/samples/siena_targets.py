"""Siena block: the control points measured at the scans' full resolution.

The six block photos of :mod:`.ortho` are rendered at 1/32 of the scans (0.448 mm pixels, 1.7 m
on the ground). Measuring the control points on them would put a measuring error of a few
tenths of such a pixel on each: 0.5 m on the ground, ten times the back-projection residuals
the Z-Map block log states (about 1 scan pixel, 0.014 mm). With 8 control points on 6 photos
that error tilts the whole block: the adjusted projection centres move by 3-7 m (measured,
the bundle's report of this round), although the tie points at 1/32 are good enough (exact
control measurements and the same tie points give the centres to 0.08 m).

So the control points are measured as an operator measures them on the scans: each point is
signalised (a white 2 m square with a black cross, 0.3 m wide arms) and, on every photo whose
frame holds it, a chip of CHIP x CHIP scan pixels (5 cm on the ground) is rendered around its
predicted position through the collinearity equations (the photo's camera, distortion and
fiducial interior orientation, one scan pixel = 1/32 of the sample's pixel; 2 x 2 rays a pixel;
the target on a plane at the point's height). The target's centre is measured on the chip as
the centroid of its white pixels (the cross is symmetric), with no knowledge of where it was
drawn, and written in the sample photos' pixels (scan pixels / 32), with ``sigma_px`` =
SIGMA_SCAN_PX scan pixels. Writes ``siena/control_image_points_block.csv``.
"""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np

CHIP = 96  # scan pixels a side (about 5 m on the ground)
TARGET_HALF_M = 1.0  # the white square's half side
CROSS_HALF_M = 0.15  # half width of the cross's arms
SIGMA_SCAN_PX = 0.5  # a priori sigma of a target measurement, scan pixels


def target_texture(texture, centre_xy):
    """``texture`` with a signalised target (white square, black cross) at ``centre_xy``."""
    cx, cy = centre_xy

    def painted(x, y):
        rgb = np.array(texture(x, y), dtype="float64")
        dx, dy = np.abs(np.asarray(x) - cx), np.abs(np.asarray(y) - cy)
        square = (dx < TARGET_HALF_M) & (dy < TARGET_HALF_M)
        rgb[:, square] = 250.0
        rgb[:, square & ((dx < CROSS_HALF_M) | (dy < CROSS_HALF_M))] = 20.0
        return rgb

    return painted


def chip_photo(photo, reduction: int, origin: tuple[int, int]):
    """``photo`` (sample pixels = ``reduction`` scan pixels) as a CHIP x CHIP window of the scan
    whose top-left corner is scan pixel ``origin`` (col, row)."""
    from toolbox.photogrammetry.fiducials import InteriorOrientation

    to_scan = np.array([[1.0 / reduction, 0.0, origin[0] / reduction],
                        [0.0, 1.0 / reduction, origin[1] / reduction], [0.0, 0.0, 1.0]])
    p2f = photo.interior.pixel_to_fiducial @ to_scan
    camera = replace(photo.camera, image_size_px=(CHIP, CHIP),
                     pixel_size_mm=photo.camera.pixel_size_mm / reduction)
    return replace(photo, camera=camera,
                   interior=InteriorOrientation(p2f / p2f[2, 2], photo.interior.transformation))


def measure_target(chip: np.ndarray) -> tuple[float, float] | None:
    """Centre (col, row; pixel centres at +0.5) of the target on an RGB chip: the centroid of
    its white pixels, weighted by their brightness above the threshold (edge pixels count in
    part); None when no target is seen."""
    grey = chip.astype("float64").mean(axis=0)
    weight = np.clip((grey - 200.0) / 50.0, 0.0, 1.0)
    if weight.sum() < 0.2 * CHIP:
        return None
    rows, cols = np.indices(grey.shape) + 0.5
    return float((weight * cols).sum() / weight.sum()), float((weight * rows).sum() / weight.sum())


def measure_block(project, points: dict, texture, reduction: int) -> list[list]:
    """Rows ``point_id, photo, col_px, row_px, sigma_px`` (sample pixels) of every target
    measured on a full-resolution chip of every photo whose frame holds it."""
    from affine import Affine

    from toolbox.photogrammetry.synthetic import render_photo

    rows = []
    for photo in project.photos.values():
        width, height = photo.camera.image_size_px
        for pid, xyz in points.items():
            col, row = photo.ground_to_pixel(np.array([xyz]))[0] * reduction
            if not (CHIP < col < width * reduction - CHIP and CHIP < row < height * reduction - CHIP):
                continue
            origin = (int(round(col)) - CHIP // 2, int(round(row)) - CHIP // 2)
            plane = np.full((3, 3), xyz[2])
            transform = Affine(20.0, 0.0, xyz[0] - 30.0, 0.0, -20.0, xyz[1] + 30.0)
            chip = render_photo(chip_photo(photo, reduction, origin), plane, transform,
                                target_texture(texture, xyz[:2]), supersample=2,
                                dtype="uint8", fill=0)
            found = measure_target(chip)
            if found is not None:
                rows.append([pid, photo.id, round((found[0] + origin[0]) / reduction, 5),
                             round((found[1] + origin[1]) / reduction, 5),
                             round(SIGMA_SCAN_PX / reduction, 5)])
    return rows


def make(folder: Path, made: dict) -> dict:
    if "siena_block_project" not in made or "siena" not in made:
        return {}
    from toolbox.demo.samples.ortho import REDUCTION, texture
    from toolbox.demo.samples.siena import control_points
    from toolbox.photogrammetry.project import load_project

    project = load_project(made["siena_block_project"])
    rows = measure_block(project, control_points(Path(made["siena"])), texture(), REDUCTION)
    path = Path(made["siena"]) / "control_image_points_block.csv"
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["point_id", "photo", "col_px", "row_px", "sigma_px"])
        writer.writerows(rows)
    return {"siena_block_control_points": path}
