"""Sample block for orientation:bundle: 2 strips x 4 digital photos, 60/25 % overlap, hilly terrain.

Made by :func:`toolbox.triangulation.synthetic.make_block` (collinearity through the toolbox's
camera chain, seed 7): ``bundle_project.yaml`` (camera c = 153 mm, 0.012 mm pixels, no exterior
orientations: the bundle computes its start values), ``bundle_measurements.csv`` (``point_id,
photo, col_px, row_px``; sigma 0.3 px of noise; one blunder of 15 px inserted on purpose at the
first measurement of point ``t00184``) and ``bundle_control.csv`` (``id, X, Y, Z, role``: 4 full
corner points, one height-only point, 2 check points), in EPSG:3003; ``bundle_models.csv``
(``model, point_id, x, y, z``): the stereo models of consecutive photos of each strip, their
common points and both projection centres (``O_<photo>``) in an arbitrary model frame each (a
random 7-parameter similarity of the true coordinates, 2 cm of noise), for orientation:models.

Also ``python -m toolbox.demo.samples.bundle_block OUT_DIR``.
"""

from __future__ import annotations

import csv
import sys
from dataclasses import replace
from pathlib import Path

BLUNDER_POINT = "t00184"
BLUNDER_PX = (15.0, 0.0)


def make(folder: Path, made: dict) -> dict[str, Path]:
    from toolbox.photogrammetry.project import Project, save_project
    from toolbox.triangulation.synthetic import SyntheticBlockSpec, corner_control, make_block

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    sb = make_block(SyntheticBlockSpec(digital=True, seed=7))
    project = sb.project
    bare = Project(project.crs, project.cameras,
                   {k: replace(p, exterior=None) for k, p in project.photos.items()})
    paths = {"bundle_project": folder / "bundle_project.yaml",
             "bundle_measurements": folder / "bundle_measurements.csv",
             "bundle_control": folder / "bundle_control.csv",
             "bundle_models": folder / "bundle_models.csv"}
    save_project(bare, paths["bundle_project"])
    xy = sb.xy.copy()
    first = sb.obs_point.index(BLUNDER_POINT)
    xy[first] += BLUNDER_PX
    with open(paths["bundle_measurements"], "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["point_id", "photo", "col_px", "row_px"])
        for p, ph, (u, v) in zip(sb.obs_point, sb.obs_photo, xy, strict=True):
            w.writerow([p, ph, f"{u:.3f}", f"{v:.3f}"])
    chosen = corner_control(sb, 7)
    with open(paths["bundle_control"], "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["id", "X", "Y", "Z", "role"])
        for n, k in enumerate(chosen):
            x, y, z = sb.points[k]
            role = "check" if n in (5, 6) else "control"
            if n == 4:  # a height point
                w.writerow([sb.point_ids[k], "", "", f"{z:.3f}", role])
            else:
                w.writerow([sb.point_ids[k], f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", role])
    _models(sb, paths["bundle_models"])
    return paths


def _models(sb, path: Path) -> None:
    import numpy as np

    from toolbox.photogrammetry.rotation import rotation_matrix

    rng = np.random.default_rng(8)
    truth = dict(zip(sb.point_ids, sb.points, strict=True))
    on: dict[str, set[str]] = {}
    for p, ph in zip(sb.obs_point, sb.obs_photo, strict=True):
        on.setdefault(ph, set()).add(p)
    strips: dict[str, list[str]] = {}
    for pid, photo in sb.project.photos.items():
        strips.setdefault(photo.strip, []).append(pid)
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["model", "point_id", "x", "y", "z"])
        for photos in strips.values():
            for a, b in zip(photos[:-1], photos[1:], strict=True):
                scale = rng.uniform(500.0, 2000.0)
                rot = rotation_matrix(*rng.normal(0.0, [0.01, 0.01, 1.0]))
                shift = rng.normal(0.0, 1000.0, 3) + [*sb.points[:, :2].mean(axis=0), 0.0]
                points = {p: truth[p] for p in sorted(on[a] & on[b])}
                for ph in (a, b):
                    points[f"O_{ph}"] = np.asarray(sb.project.photos[ph].exterior.centre)
                for pid, xyz in points.items():
                    m = rot.T @ (xyz + rng.normal(0.0, 0.02, 3) - shift) / scale
                    w.writerow([f"{a}-{b}", pid, *(f"{v:.8f}" for v in m)])


if __name__ == "__main__":  # pragma: no cover - convenience entry point
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "bundle_sample")
    for name, path in make(out, {}).items():
        print(f"{name}: {path}")
