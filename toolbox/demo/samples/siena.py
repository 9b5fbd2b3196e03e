"""Siena case-study sample: the bundled orientation data, plus image measurements with a known truth.

Copies ``toolbox/demo/data/siena`` (thesis data, logs and the orientation project; see the README
and ``siena_orientation.md`` there) to ``<data>/siena`` and derives two small inputs from the
project's orientations:

- ``control_image_points.csv``: the 8 block-adjustment control points (l.3199-3206, EPSG:3003)
  projected into every photo whose frame sees them, in pixels, plus a deterministic measuring
  noise of 0.3 px (seeded); intersecting them recovers the printed coordinates to a few cm;
- ``monoplot_points.csv``: a 5 x 5 grid of pixels over photo 1_7150 and one pixel far outside
  its frame (``outside``), whose ray misses the demo DEM and must come out flagged;
- ``control_ground.csv``: the 8 control points (id, X, Y, Z, role), two of them as check points,
  for orientation:check and orientation:resection;
- ``model_points.csv``: the same 8 points in an arbitrary model system (a known 7-parameter
  similarity: scale 1/3800, rotated and shifted), for orientation:absolute.
"""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np

BUNDLED = Path(__file__).resolve().parents[1] / "data" / "siena"
NOISE_PX = 0.3
CHECK_POINTS = ("ptc_007-2_7140", "ptc_002-1_7151")


def control_points(folder: Path) -> dict[str, tuple[float, float, float]]:
    """The block run's recomputed control points ``{id: (X, Y, Z)}`` as printed."""
    with open(folder / "control_points.csv", newline="") as f:
        return {r["id"]: (float(r["X"]), float(r["Y"]), float(r["Z"]))
                for r in csv.DictReader(f) if r["record"] == "coordinates" and r["run"] == "block"}


def make(folder: Path, made: dict) -> dict:
    from toolbox.photogrammetry.project import load_project

    target = Path(folder) / "siena"
    target.mkdir(parents=True, exist_ok=True)
    for item in BUNDLED.iterdir():
        if item.is_file():
            shutil.copy2(item, target / item.name)
    project = load_project(target / "siena_project.yaml")
    rng = np.random.default_rng(20090515)
    points = control_points(target)
    control_csv = target / "control_image_points.csv"
    _write_measurements(control_csv, project, points, rng)
    grid = np.linspace(1500.0, 15100.0, 5)
    mono_csv = target / "monoplot_points.csv"
    with open(mono_csv, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["point_id", "photo", "col_px", "row_px"])
        k = 0
        for row in grid:
            for col in grid:
                k += 1
                writer.writerow([f"g{k:02d}", "1_7150", col, row])
        writer.writerow(["outside", "1_7150", -30000.0, 8000.0])
    ground_csv = target / "control_ground.csv"
    with open(ground_csv, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "X", "Y", "Z", "role"])
        for pid, xyz in points.items():
            writer.writerow([pid, *xyz, "check" if pid in CHECK_POINTS else "control"])
    model_csv = target / "model_points.csv"
    xyz = np.array(list(points.values()))
    angle = 0.3
    rot = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0],
                    [0, 0, 1]])
    model = (xyz - xyz.mean(axis=0)) @ rot / 3800.0 + [10.0, 20.0, 0.4]
    with open(model_csv, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "X", "Y", "Z"])
        for pid, m in zip(points, model, strict=True):
            writer.writerow([pid, *(round(float(v), 7) for v in m)])
    return {"siena": target, "siena_project": target / "siena_project.yaml",
            "siena_control_ground": ground_csv, "siena_model_points": model_csv,
            "siena_fiducials": target / "fiducials.csv", "siena_control_image_points": control_csv,
            "siena_monoplot_points": mono_csv}


def _write_measurements(path: Path, project, points: dict, rng) -> None:
    """The control points' image positions on every photo that sees them, with NOISE_PX of
    noise, as the image-measurement CSV (point_id, photo, col_px, row_px)."""
    rows = []
    xyz = np.array(list(points.values()))
    for photo in project.photos.values():
        width, height = photo.camera.image_size_px
        px = photo.ground_to_pixel(xyz)
        inside = (px[:, 0] > 0) & (px[:, 0] < width) & (px[:, 1] > 0) & (px[:, 1] < height)
        noise = rng.normal(0.0, NOISE_PX, px.shape)
        for pid, (col, row), dn, keep in zip(points, px, noise, inside, strict=True):
            if keep:
                rows.append([pid, photo.id, round(col + dn[0], 3), round(row + dn[1], 3)])
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["point_id", "photo", "col_px", "row_px"])
        writer.writerows(rows)
