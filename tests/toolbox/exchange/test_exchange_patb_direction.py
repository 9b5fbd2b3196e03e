"""PAT-B's rotation-matrix direction, checked on a documented example: the NGI aerial block of
Orthority's test data (io/ngi_xyz_opk.csv + .prj, omega/phi/kappa in degrees). Orthority documents
these angles as rotating "from camera (PATB convention) to world" (docs/background/
coordinates.rst, camera.py), and Pix4D defines "R, the rotation matrix that defines the camera
orientation with angles omega, phi, kappa (PATB convention)", ``X' = R^T (X - T)``: the PAT-B
matrix is Rx(omega)·Ry(phi)·Rz(kappa), camera (x right, y up, z back) -> world, stored row by
row (a11 a12 a13 a21 a22 / a23 a31 a32 a33). The matrices orientation:convert writes are
compared with scipy's intrinsic X-Y-Z Euler matrix of the published angles (an independent
oracle), the camera axis they give must look down, a ground point projected through them with
OpenCV (world -> OpenCV camera = diag(1, -1, -1)·R^T) must land where the product's camera puts
it, and reading the file back gives the published angles (round trip through
orientation:convert both ways)."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import toolbox


def read_ori(path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    records = [ln.split() for ln in path.read_text().splitlines() if ln.strip()]
    out = {}
    for k in range(0, len(records), 3):
        head, first, second = records[k:k + 3]
        out[head[0]] = (np.array(head[1:], float), np.array(first + second, float).reshape(3, 3))
    return out


def test_patb_matrices_are_the_documented_camera_to_world_rotation(orthority_data, tmp_path):
    source = orthority_data / "io" / "ngi_xyz_opk.csv"
    with source.open() as f:
        published = {r["filename"]: r for r in csv.DictReader(f)}
    out = tmp_path / "ngi.ori"
    toolbox.run("orientation:convert", {"INPUT": str(source), "FORMAT_OUT": "patb",
                                        "OUTPUT": out})
    written = read_ori(out)
    assert set(written) == set(published)
    for pid, (centre, matrix) in written.items():
        row = published[pid]
        angles = [float(row[k]) for k in ("omega", "phi", "kappa")]
        oracle = Rotation.from_euler("XYZ", angles, degrees=True).as_matrix()  # Rx·Ry·Rz
        np.testing.assert_allclose(matrix, oracle, atol=2e-12)
        assert not np.allclose(matrix, matrix.T, atol=1e-4)  # the direction matters here
        np.testing.assert_allclose(centre, [float(row[k]) for k in "xyz"], atol=5e-6)
        # camera z points back: the optical axis -R[:, 2] looks down on an aerial photo
        assert (-matrix[:, 2])[2] < -0.999


def test_patb_projection_and_round_trip(orthority_data, tmp_path):
    """OpenCV's projectPoints through the file's matrix (as PAT-B/Pix4D define it) equals the
    product's camera of the orientation read back from the file; the angles come back."""
    from toolbox.cameras import create_camera
    from toolbox.exchange import patb
    from toolbox.photogrammetry.exterior import ExteriorOrientation

    source = orthority_data / "io" / "ngi_xyz_opk.csv"
    out = tmp_path / "ngi.ori"
    toolbox.run("orientation:convert", {"INPUT": str(source), "FORMAT_OUT": "patb",
                                        "OUTPUT": out})
    spec = {"type": "pinhole", "im_size": [640, 1152], "focal_len": 120.0,
            "sensor_size": [92.16, 165.888]}
    fx = 120.0 * 640 / 92.16
    k = np.array([[fx, 0, 319.5], [0, fx, 575.5], [0, 0, 1]])  # OpenCV pixels: centres at 0
    back = patb.read_patb(out, None)
    for pid, (centre, matrix) in read_ori(out).items():
        world_to_cv = np.diag([1.0, -1.0, -1.0]) @ matrix.T
        rng = np.random.default_rng(3)
        ground = centre + np.column_stack([rng.uniform(-800, 800, 20),
                                           rng.uniform(-800, 800, 20), np.full(20, -5000.0)])
        rvec, _ = cv2.Rodrigues(world_to_cv)
        tvec = -world_to_cv @ centre
        px, _ = cv2.projectPoints(ground, rvec, tvec, k, None)
        photo = back.photos[pid]
        eo = ExteriorOrientation.from_angles(pid, *photo.xyz, *photo.opk, unit="rad")
        ours = create_camera(spec, eo).project(ground)
        np.testing.assert_allclose(ours, px.reshape(-1, 2) + 0.5, atol=1e-6)
    # and back to omega/phi/kappa in degrees: the published angles
    csv_out = tmp_path / "again.csv"
    toolbox.run("orientation:convert", {"INPUT": str(out), "CRS": source.with_suffix(".prj").read_text(),
                                        "FORMAT_OUT": "csv", "ANGLE_UNIT_OUT": "deg",
                                        "OUTPUT": csv_out})
    with source.open() as f, csv_out.open() as g:
        first = {r["filename"]: r for r in csv.DictReader(f)}
        again = {r["filename"]: r for r in csv.DictReader(g)}
    for pid, row in first.items():
        for key in ("omega", "phi", "kappa"):
            assert float(again[pid][key]) == pytest.approx(float(row[key]), abs=1e-9)
