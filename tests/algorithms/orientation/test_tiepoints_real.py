"""orientation:tiepoints on real aerial frames: the four NGI photos of Orthority's test data
(Intergraph DMC, pinhole, f = 120 mm, 92.16 x 165.888 mm sensor, 640 x 1152 px) with their
published orientations (camera_pos_ori.txt: X Y Z omega phi kappa in degrees, Orthority's
omega-phi-kappa, the photogrammetric convention of this toolbox).

Truth: every tie point, intersected with the PUBLISHED orientations, reprojects within 1.5 px
in every photo measuring it (the matcher does not use the orientations except to choose pairs)."""

from __future__ import annotations

import csv

import numpy as np
import yaml

import toolbox


def ngi_project(data, folder):
    ngi = data / "ngi"
    photos = []
    for line in (ngi / "camera_pos_ori.txt").read_text().splitlines():
        if line.strip():
            name, *values = line.split()
            photos.append({"id": name, "camera": "dmc", "image": str(ngi / f"{name}.tif"),
                           "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                                map(float, values), strict=True))})
    doc = {"format": "orientation-project", "version": 1,
           "crs": "+proj=tmerc +lon_0=25 +datum=WGS84 +units=m", "angle_unit": "deg",
           "cameras": [{"name": "dmc", "principal_distance_mm": 120.0,
                        "image_size_px": [640, 1152], "pixel_size_mm": 0.144,
                        "frame_size_mm": [92.16, 165.888]}], "photos": photos}
    path = folder / "ngi.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def test_ngi_tie_points_agree_with_the_published_orientations(orthority_data, tmp_path):
    from toolbox.photogrammetry.forward_intersection import camera_observations, intersect
    from toolbox.photogrammetry.project import load_project

    project = ngi_project(orthority_data, tmp_path)
    out = toolbox.run("orientation:tiepoints", {
        "PROJECT": project, "TERRAIN_HEIGHT": 300.0, "OUTPUT": tmp_path / "tie.csv",
        "PAIRS": tmp_path / "pairs.csv"})
    stats = out["STATISTICS"]
    assert stats["untied_photos"] == [] and stats["pairs_tied"] >= 5
    with open(tmp_path / "tie.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    photos = load_project(project).photos
    ids = list(dict.fromkeys(r["point_id"] for r in rows))
    assert len(ids) >= 80
    index = {pid: k for k, pid in enumerate(ids)}
    point = np.array([index[r["point_id"]] for r in rows])
    obs = np.array([[float(r["col_px"]), float(r["row_px"])] for r in rows])
    ph = [photos[r["photo"]] for r in rows]
    res = intersect(point, camera_observations(ph, obs, "pixel"),
                    np.array([p.exterior.centre for p in ph]),
                    np.array([p.exterior.rotation for p in ph]),
                    np.array([p.camera.c for p in ph]), len(ids))
    assert res.ok.all()
    back = np.vstack([ph[m].ground_to_pixel(res.xyz[point[m]][None]) for m in range(len(rows))])
    error = np.hypot(*(back - obs).T)
    assert error.max() <= 1.5, np.percentile(error, [50, 99, 100])
    # the ground is where the NGI DEM says (independent of the matcher and the intersection)
    import rasterio

    with rasterio.open(orthority_data / "ngi" / "dem.tif") as dem:
        z = np.array([v[0] for v in dem.sample(res.xyz[:, :2])])
    assert np.median(np.abs(res.xyz[:, 2] - z)) < 10.0
