"""orientation:precision of digital frame cameras (camera models): the covariance of the
least-squares intersection, against an independent computation (pixels by OpenCV's
projectPoints, derivatives by scipy.differentiate.jacobian, the inverse normal matrix), a
Monte-Carlo intersection, and the normal-case formula where it is exact."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from scipy.differentiate import jacobian
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import toolbox
from tests.helpers_cli import assert_refused

ORIGIN = np.array([680000.0, 4990000.0, 0.0])  # local origin: UTM numbers are large
TERRAIN = 20.0
BROWN = {"type": "brown", "im_size": [4000, 3000], "focal_len": 0.9, "cx": 0.012,
         "cy": -0.008, "k1": -0.12, "k2": 0.06, "k3": -0.015, "p1": 0.0012, "p2": -0.0007}
# (id, X0, Y0, Z0, omega, phi, kappa): a strip along a slightly curving line, tilted photos
PHOTOS = [("d1", 680000.0, 4990000.0, 140.0, 0.03, -0.04, 0.05),
          ("d2", 680036.0, 4990004.0, 143.0, -0.02, 0.05, 0.08),
          ("d3", 680071.0, 4990011.0, 138.0, 0.06, 0.01, 0.12)]


def write_project(path, camera, photos=PHOTOS):
    lines = ["version: 1", "crs: EPSG:32632", "angle_unit: rad", "cameras:",
             f"  - {{name: drone, model: {json.dumps(camera)}}}", "photos:"]
    for pid, x, y, z, o, p, k in photos:
        lines.append(f"  - {{id: {pid}, camera: drone, strip: '1', exterior: {{X0: {x}, "
                     f"Y0: {y}, Z0: {z}, omega: {o}, phi: {p}, kappa: {k}}}}}")
    path.write_text("\n".join(lines) + "\n")
    return path


def opencv_pixels(camera, photo, xyz):
    """Pixels (N, 2) of ground points (N, 3) by cv2.projectPoints: R = Rx(ω)·Ry(φ)·Rz(κ)
    (scipy), the OpenCV camera frame diag(1, -1, -1)·Rᵀ·(X - X0)."""
    _, x0, y0, z0, o, p, k = photo
    rot = np.diag([1.0, -1.0, -1.0]) @ Rotation.from_euler("XYZ", [o, p, k]).as_matrix().T
    centre = np.array([x0, y0, z0]) - ORIGIN
    w, h = camera["im_size"]
    s = max(w, h)
    f = camera["focal_len"] * s
    matrix = np.array([[f, 0, w / 2 + camera["cx"] * s - 0.5],
                       [0, f, h / 2 + camera["cy"] * s - 0.5], [0, 0, 1]])
    dist = np.array([camera.get(key, 0.0) for key in ("k1", "k2", "p1", "p2", "k3")])
    pts = np.asarray(xyz, dtype="float64").reshape(-1, 3) - ORIGIN
    px, _ = cv2.projectPoints(pts, cv2.Rodrigues(rot)[0], -rot @ centre, matrix, dist)
    return px.reshape(-1, 2) + 0.5


def oracle_covariance(camera, pair, point, sigma):
    """σ²·(JᵀJ)⁻¹ with J of both photos' OpenCV pixels by scipy.differentiate.jacobian."""
    def pixels(xyz):  # (3, ...) -> (4, ...)
        flat = xyz.reshape(3, -1).T
        out = np.hstack([opencv_pixels(camera, photo, flat) for photo in pair]).T
        return out.reshape((4,) + xyz.shape[1:])

    j = jacobian(pixels, np.asarray(point, dtype="float64"), initial_step=0.5).df
    return sigma ** 2 * np.linalg.inv(j.T @ j)


def ground_at_pixel(camera, photo, pixel, height):
    """The point at ``height`` that OpenCV projects to ``pixel`` (scipy least squares)."""
    x0, y0 = photo[1], photo[2]
    fit = least_squares(lambda v: opencv_pixels(camera, photo, [[*v, height]])[0] - pixel,
                        [x0, y0], xtol=1e-14, ftol=1e-14)
    return np.array([*fit.x, height])


def run(tmp_path, project, **extra):
    return toolbox.run("orientation:precision", {"PROJECT": project, "MEAN_HEIGHT": TERRAIN,
                                                 "OUTPUT": tmp_path / "p.json", **extra}
                       )["PRECISION"]


def test_brown_block_equals_the_inverse_normal_matrix_of_opencv_pixels(tmp_path):
    rows = run(tmp_path, write_project(tmp_path / "b.yaml", BROWN), SIGMA_PIXEL=0.4)
    assert [(r["photo_a"], r["photo_b"]) for r in rows] == [("d1", "d2"), ("d2", "d3")]
    for row, pair in zip(rows, [PHOTOS[:2], PHOTOS[1:]], strict=True):
        assert row["method"] == "intersection through the camera models"
        assert row["principal_distance_mm"] is None and row["sigma_parallax_um"] is None
        assert row["principal_distance_px"] == pytest.approx(3600.0)
        a, b = (np.array(p[1:4]) for p in pair)
        middle = [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, TERRAIN]
        truth = np.sqrt(np.diag(oracle_covariance(BROWN, pair, middle, 0.4)))
        got = [row["sigma_x_centre_m"], row["sigma_y_centre_m"], row["sigma_z_m"]]
        assert got == pytest.approx(truth, rel=1e-4)
        corners = [[0, 0], [4000, 0], [4000, 3000], [0, 3000]]
        edge = np.array([np.sqrt(np.diag(oracle_covariance(
            BROWN, pair, ground_at_pixel(BROWN, pair[0], c, TERRAIN), 0.4))) for c in corners])
        got = [row["sigma_x_edge_m"], row["sigma_y_edge_m"], row["sigma_z_edge_m"]]
        assert got == pytest.approx(edge.max(axis=0), rel=1e-4)
        assert row["sigma_z_edge_m"] > 1.05 * row["sigma_z_m"]  # the corners are worse


def test_monte_carlo_intersection_agrees(tmp_path):
    """Pixels of the middle point perturbed by N(0, σ) and intersected again (scipy least
    squares on OpenCV's projection): the spread is the algorithm's σ within sampling error
    (and √2 times σ is not: a wrong factor fails)."""
    sigma = 0.5
    row = run(tmp_path, write_project(tmp_path / "b.yaml", BROWN), SIGMA_PIXEL=sigma)[0]
    pair = PHOTOS[:2]
    a, b = (np.array(p[1:4]) for p in pair)
    truth = np.array([(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, TERRAIN])
    pixels = np.hstack([opencv_pixels(BROWN, photo, [truth])[0] for photo in pair])
    rng = np.random.default_rng(11)
    def residuals(v, seen):
        return np.hstack([opencv_pixels(BROWN, photo, [v])[0] for photo in pair]) - seen

    points = [least_squares(residuals, truth, args=(pixels + rng.normal(0.0, sigma, 4),)).x
              for _ in range(300)]
    spread = np.std(points, axis=0, ddof=1)
    got = np.array([row["sigma_x_centre_m"], row["sigma_y_centre_m"], row["sigma_z_m"]])
    assert spread == pytest.approx(got, rel=0.15)  # 300 samples: std of a std about 4 %
    assert spread != pytest.approx(got * np.sqrt(2), rel=0.15)


def test_vertical_pinhole_pair_gives_the_normal_case_formula(tmp_path):
    """Two vertical distortion-free photos, base B, height Z above the terrain: at the middle
    of the base σZ = (Z/B)·(Z/f)·√2·σ and σX = σY = (Z/f)·σ/√2, exactly."""
    pinhole = {"type": "pinhole", "im_size": [5000, 4000], "focal_len": 0.8}
    photos = [("n1", 680000.0, 4990000.0, 320.0, 0.0, 0.0, 0.0),
              ("n2", 680090.0, 4990000.0, 320.0, 0.0, 0.0, 0.0)]
    row = run(tmp_path, write_project(tmp_path / "n.yaml", pinhole, photos), SIGMA_PIXEL=0.3)[0]
    z, base, f, sigma = 300.0, 90.0, 4000.0, 0.3
    assert row["sigma_z_m"] == pytest.approx(z / base * z / f * np.sqrt(2) * sigma, rel=1e-6)
    assert row["sigma_x_centre_m"] == pytest.approx(z / f * sigma / np.sqrt(2), rel=1e-6)
    assert row["sigma_y_centre_m"] == pytest.approx(z / f * sigma / np.sqrt(2), rel=1e-6)
    assert row["gsd_m"] == pytest.approx(z / f) and row["base_ratio"] == pytest.approx(0.3)


def test_model_pairs_bad_input_is_one_line(tmp_path):
    project = write_project(tmp_path / "b.yaml", BROWN)
    out = tmp_path / "o.json"
    args = ["run", "orientation:precision", "--MEAN_HEIGHT", TERRAIN, "--OUTPUT", out]
    assert_refused([*args, "--PROJECT", project, "--XI", 100], "XI", (out,))
    assert_refused([*args, "--PROJECT", project, "--SIGMA_PIXEL", 0], "SIGMA_PIXEL", (out,))
    mixed = project.read_text().replace(
        "photos:", "  - {name: film, principal_distance_mm: 150.0, frame_size_mm: [230, 230]}"
        "\nphotos:").replace("{id: d2, camera: drone", "{id: d2, camera: film")
    (tmp_path / "m.yaml").write_text(mixed)
    assert_refused([*args, "--PROJECT", tmp_path / "m.yaml"], "film camera", (out,))


def test_a_pair_that_does_not_see_one_point_is_skipped(tmp_path):
    """Consecutive photos 2 km apart are no stereo pair: skipped with a warning, the rest kept."""
    far = [*PHOTOS[:2], ("d3", 682000.0, 4990000.0, 140.0, 0.0, 0.0, 0.0)]
    feedback = toolbox.Feedback()
    rows = toolbox.run("orientation:precision", {
        "PROJECT": write_project(tmp_path / "f.yaml", BROWN, far), "MEAN_HEIGHT": TERRAIN,
        "OUTPUT": tmp_path / "p.json"}, feedback=feedback)["PRECISION"]
    assert [(r["photo_a"], r["photo_b"]) for r in rows] == [("d1", "d2")]
    assert any("d2, d3 skipped" in w and "not a stereo pair" in w for w in feedback.warnings)


def test_odm_drone_block_near_the_normal_case(orthority_data, tmp_path):
    """Orthority's ODM frames (OpenSfM Brown camera, reconstruction.json read directly) on its
    DSM: every consecutive pair intersects, σZ at the middle of the base within 15 % of the
    normal case's (Z/B)·(Z/f)·√2·σ (the photos are nearly vertical)."""
    odm = orthority_data / "odm"
    rows = toolbox.run("orientation:precision", {
        "PROJECT": odm / "opensfm" / "reconstruction.json", "DEM": odm / "odm_dem" / "dsm.tif",
        "SIGMA_PIXEL": 0.5, "OUTPUT": tmp_path / "p.json"})["PRECISION"]
    assert len(rows) == 3
    for r in rows:
        z, b, f = r["distance_m"], r["base_m"], r["principal_distance_px"]
        assert r["sigma_z_m"] == pytest.approx(z / b * z / f * np.sqrt(2) * 0.5, rel=0.15)
        assert r["sigma_z_edge_m"] > r["sigma_z_m"]
