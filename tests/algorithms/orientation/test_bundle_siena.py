"""The six Siena photos oriented in one bundle (002 par. 3.5).

Provenance of the measurements: the thesis prints no image coordinates of tie points, so they are
synthesised here: a 7 x 7 grid of ground points over the block (heights from a plane fitted to
the 8 control points, +-15 m of relief) and the 8 control points are projected into every photo
that sees them through the Z-Map final orientations of the block run (2_7139: strip-2 run, the
block log prints none), the real cameras (one with the calibrated distortion table) and each
photo's fiducial interior orientation, then 0.5 px of Gaussian noise is added. The bundle
starts from no orientation at all (START=control) and must give back Z-Map's orientations
within the block log's stated control residuals (0.35 m) and its own predicted precision.
"""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

import toolbox
from toolbox.photogrammetry.project import load_project

SIENA = Path(__file__).resolve().parents[3] / "toolbox" / "demo" / "data" / "siena"
BLOCK_CONTROL = ["ptc_003-1_7150", "ptc_006-2_7140", "ptc_004-1_7151", "ptc_007-2_7140",
                 "ptc_001-1_7150", "ptc_002-1_7151", "ptc_008-2_7139", "ptc_005-2_7139"]


def _control():
    with open(SIENA / "control_points.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["record"] == "coordinates" and
                r["run"] == "block"]
    return {r["id"]: np.array([float(r["X"]), float(r["Y"]), float(r["Z"])]) for r in rows}


@pytest.fixture(scope="module")
def siena_block(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("siena_bundle")
    project = load_project(SIENA / "siena_project.yaml")
    control = _control()
    assert sorted(control) == sorted(BLOCK_CONTROL)
    xyz = np.array(list(control.values()))
    plane, *_ = np.linalg.lstsq(np.column_stack([xyz[:, :2] - xyz[:, :2].mean(0),
                                                 np.ones(len(xyz))]), xyz[:, 2], rcond=None)
    lo, hi = xyz[:, :2].min(0), xyz[:, :2].max(0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 7), np.linspace(lo[1], hi[1], 7))
    rng = np.random.default_rng(11)
    tie = np.column_stack([gx.ravel(), gy.ravel()])
    tz = np.column_stack([tie - xyz[:, :2].mean(0), np.ones(len(tie))]) @ plane
    points = {f"tie{k:02d}": np.array([*tie[k], tz[k] + rng.uniform(-15, 15)])
              for k in range(len(tie))} | control
    rows = [["point_id", "photo", "col_px", "row_px"]]
    for pid, photo in project.photos.items():
        ids = list(points)
        px = photo.ground_to_pixel(np.array([points[i] for i in ids]))
        w, h = 16600, 16400  # the scans' extent (fiducials at about 800-15960 px)
        for i, (u, v) in zip(ids, px, strict=True):
            if 900 < u < w - 900 and 900 < v < h - 900:
                u, v = np.array([u, v]) + rng.normal(0, 0.5, 2)
                rows.append([i, pid, f"{u:.3f}", f"{v:.3f}"])
    seen = [r[0] for r in rows[1:]]
    rows = rows[:1] + [r for r in rows[1:] if r[0] in control or seen.count(r[0]) >= 2]
    meas = tmp / "siena_measurements.csv"
    with open(meas, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    ctrl = tmp / "siena_control.csv"
    with open(ctrl, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "X", "Y", "Z"])
        for i, p in control.items():
            w.writerow([i, *p])
    return project, meas, ctrl, tmp


def test_all_six_siena_photos_in_one_bundle_agree_with_zmap(siena_block):
    project, meas, ctrl, tmp = siena_block
    out = toolbox.run("orientation:bundle", {
        "PROJECT": SIENA / "siena_project.yaml", "INPUT": meas, "CONTROL": ctrl,
        "START": "control", "SIGMA_PX": 0.5, "CONTROL_SIGMA_XY": 0.05,
        "CONTROL_SIGMA_Z": 0.05, "OUTPUT": tmp / "siena_bundle.yaml",
        "REPORT": tmp / "siena_bundle.json"})
    report = json.loads((tmp / "siena_bundle.json").read_text())
    assert out["STATISTICS"]["photos"] == 6
    assert 0.7 < out["STATISTICS"]["sigma0"] < 1.3
    adjusted = load_project(out["OUTPUT"])
    assert len(adjusted.oriented()) == 6
    for row in report["photos"]:
        z = project.photos[row["photo"]].exterior  # Z-Map's final values
        a = adjusted.photos[row["photo"]].exterior
        d = np.array([a.x0 - z.x0, a.y0 - z.y0, a.z0 - z.z0])
        assert np.abs(d).max() < 0.35, (row["photo"], d)  # the block log's control residuals
        std = np.array([row["std_X0"], row["std_Y0"], row["std_Z0"]])
        assert (np.abs(d) < 4 * std).all(), (row["photo"], d, std)
        dang = np.array([a.omega - z.omega, a.phi - z.phi, a.kappa - z.kappa])
        astd = np.array([row["std_omega"], row["std_phi"], row["std_kappa"]])
        assert (np.abs(dang) < 4 * astd).all(), (row["photo"], dang, astd)
        assert np.abs(dang).max() < 5e-4  # half the log's printed resolution (0.001 rad)
