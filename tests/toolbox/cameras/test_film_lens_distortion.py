"""The film camera's full lens distortion (radial k1-k3, decentring p1, p2; correction form of
toolbox.photogrammetry.camera) against OpenCV.

Unit mapping to OpenCV: a measured point ``m = (u, v)`` mm (reduced to the principal point) is
the object point ``(u, v, c)`` seen by a camera at the origin with ``K = diag(c, c, 1)``; OpenCV
then distorts ``m/c`` and multiplies by c, so its "distortion" is our *correction* when its
coefficients are ``k1' = -k1·c²``, ``k2' = -k2·c⁴``, ``k3' = -k3·c⁶``, ``p1' = -p2·c``,
``p2' = -p1·c`` (OpenCV pairs p2 with ``r² + 2x²``). ``cv2.projectPoints`` is then the oracle of
image -> camera (closed form) and ``cv2.undistortPoints`` run to convergence (OpenCV's own
iterative inverse) of camera -> image."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from toolbox.errors import InputDataError
from toolbox.photogrammetry.camera import Camera, RadialDistortion
from toolbox.photogrammetry.collinearity import ground_to_image, image_to_ground
from toolbox.photogrammetry.project import load_project, save_project
from toolbox.photogrammetry.synthetic import frame_photo

C = 153.0
TERMS = {"k1": 2e-8, "k2": -4e-13, "k3": 6e-18, "p1": 3e-7, "p2": -2e-7}  # mm units
PP = (0.012, -0.021)


def opencv_coefficients(terms: dict, c: float = C) -> np.ndarray:
    """Our correction's coefficients as OpenCV's distortion (k1, k2, p1, p2, k3)."""
    return -np.array([terms["k1"] * c ** 2, terms["k2"] * c ** 4, terms["p2"] * c,
                      terms["p1"] * c, terms["k3"] * c ** 6])


def opencv_correct(measured: np.ndarray, terms: dict = TERMS) -> np.ndarray:
    obj = np.column_stack([measured, np.full(len(measured), C)])
    k = np.diag([C, C, 1.0])
    out, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), k, opencv_coefficients(terms))
    return out.reshape(-1, 2)


def opencv_distort(ideal: np.ndarray, terms: dict = TERMS) -> np.ndarray:
    k = np.diag([C, C, 1.0])
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-16)
    out = cv2.undistortPoints(ideal.reshape(-1, 1, 2).astype(np.float64), k,
                              opencv_coefficients(terms), None, None, k, crit)
    return out.reshape(-1, 2)


def frame_points(n: int = 400, half: float = 115.0, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-half, half, (n, 2))


@pytest.fixture(scope="module")
def camera() -> Camera:
    return Camera("film", C, PP, distortion=RadialDistortion.from_polynomial(**TERMS))


def test_image_to_camera_is_opencv_projectpoints(camera):
    measured = frame_points()
    ours = camera.image_to_camera(measured + PP)
    np.testing.assert_allclose(ours, opencv_correct(measured), atol=1e-10, rtol=0)
    # every term matters: each alone moves a corner point by more than 1 µm
    corner = np.array([[110.0, -95.0]])
    for term in TERMS:
        alone = Camera("x", C, distortion=RadialDistortion.from_polynomial(
            **{k: (v if k == term else 0.0) for k, v in TERMS.items()}))
        shift = np.hypot(*(alone.image_to_camera(corner) - corner)[0])
        assert shift > 1e-3, term
        np.testing.assert_allclose(alone.image_to_camera(corner), opencv_correct(
            corner, {k: (v if k == term else 0.0) for k, v in TERMS.items()}), atol=1e-10)


def test_camera_to_image_is_opencvs_iterative_inverse_and_round_trips(camera):
    ideal = frame_points(seed=1)
    ours = camera.camera_to_image(ideal) - PP
    np.testing.assert_allclose(ours, opencv_distort(ideal), atol=1e-6, rtol=0)  # 0.001 µm
    # round trip to within 0.001 µm, both directions
    np.testing.assert_allclose(camera.image_to_camera(ours + PP), ideal, atol=1e-9, rtol=0)
    measured = frame_points(seed=2)
    back = camera.camera_to_image(camera.image_to_camera(measured + PP))
    np.testing.assert_allclose(back, measured + PP, atol=1e-9, rtol=0)


def nadir(points: np.ndarray, distortion: RadialDistortion, to_image: bool) -> np.ndarray:
    """The compiled collinearity kernels through their public functions, for a camera at the
    origin looking down (R = I): ground (x, y, -c) has the ideal image (x, y), and the ray of
    image point m meets the plane Z = -c at (corrected m, -c)."""
    if to_image:
        ground = np.column_stack([points, np.full(len(points), -C)])
        return ground_to_image(ground, (0.0, 0.0, 0.0), np.eye(3), C, distortion=distortion,
                               behind="nan")
    return image_to_ground(points, -C, (0.0, 0.0, 0.0), np.eye(3), C,
                           distortion=distortion)[:, :2]


def test_compiled_kernels_equal_opencv_both_ways(camera):
    ideal = frame_points(seed=3)
    measured = frame_points(seed=4)
    fwd = nadir(ideal, camera.distortion, to_image=True)
    inv = nadir(measured, camera.distortion, to_image=False)
    np.testing.assert_allclose(fwd, opencv_distort(ideal), atol=1e-6, rtol=0)
    np.testing.assert_allclose(inv, opencv_correct(measured), atol=1e-10, rtol=0)
    back = nadir(fwd, camera.distortion, to_image=False)
    np.testing.assert_allclose(back, ideal, atol=1e-9, rtol=0)


def test_a_distortion_that_folds_gives_nan_not_a_wrong_point():
    """correct(m) = m·(1 - k1·r²) peaks at r = 1/√(3 k1): ideal radii beyond its value
    (38.5 mm for k1 = 1e-4) have no measured point; with decentring too."""
    for terms in ({"k1": 1e-4}, {"k1": 1e-4, "p1": 1e-5}):
        d = RadialDistortion.from_polynomial(**terms)
        far, near = np.array([[45.0, 0.0]]), np.array([[10.0, 5.0]])
        assert np.isnan(d.distort(far)).all()
        assert np.isnan(nadir(far, d, to_image=True)).all()  # the compiled kernel too
        np.testing.assert_allclose(d.correct(d.distort(near)), near, atol=1e-9)


def test_film_photo_projects_ground_points_as_opencv_renders_them():
    """Ground -> pixel of a film photo with the full distortion (the compiled collinearity
    kernel every photo algorithm uses), against collinearity written out here, OpenCV's
    inverse of the distortion and the photo's pixel grid; and back through the camera
    protocol (pixel -> ray -> ground at the point's height)."""
    dist = RadialDistortion.from_polynomial(**TERMS)
    photo = frame_photo((1000.0, 2000.0, 1800.0), (0.02, -0.015, 0.4), width=2300, height=2300,
                        principal_distance_mm=C, principal_point_mm=PP, distortion=dist)
    rng = np.random.default_rng(5)
    ground = np.column_stack([rng.uniform(300, 1700, 300), rng.uniform(1300, 2700, 300),
                              rng.uniform(100, 400, 300)])
    r = photo.exterior.rotation
    d = (ground - photo.exterior.centre) @ r  # Rᵀ·(X - X0) per row
    ideal = -C * d[:, :2] / d[:, 2:]
    inside = (np.abs(ideal) < 110).all(axis=1)
    ideal, ground = ideal[inside], ground[inside]
    mm = opencv_distort(ideal) + PP
    pixel = 0.1  # mm: 2300 px over 230 mm, image centre at the fiducial centre, y up
    expected = np.column_stack([1150.0 + mm[:, 0] / pixel, 1150.0 - mm[:, 1] / pixel])
    np.testing.assert_allclose(photo.ground_to_pixel(ground), expected, atol=1e-5)  # px
    sensor = photo.sensor()
    np.testing.assert_allclose(sensor.project(ground), expected, atol=1e-5)
    back = sensor.pixel_to_ground(expected, ground[:, 2])
    np.testing.assert_allclose(back, ground, atol=1e-4)  # m


def test_bounds_hold_for_the_decentring():
    """The ortho's bounds of the distortion's shift and of its Lipschitz constant hold on a
    dense sample of the frame (finite differences of distort(p) - p)."""
    d = RadialDistortion.from_polynomial(**TERMS)
    radius = 160.0
    p = frame_points(4000, 110.0, seed=6)
    shift = d.distort(p) - p
    assert np.hypot(*shift.T).max() <= d.magnitude_bound(radius)
    h = 1e-3
    jx = (d.distort(p + [h, 0]) - d.distort(p - [h, 0])) / (2 * h) - [1, 0]
    jy = (d.distort(p + [0, h]) - d.distort(p - [0, h])) / (2 * h) - [0, 1]
    norms = np.linalg.norm(np.stack([jx, jy], axis=-1), ord=2, axis=(1, 2))
    assert norms.max() <= d.lipschitz_bound(radius)
    assert d.lipschitz_bound(radius) < 5 * norms.max()  # and not uselessly loose


def test_project_yaml_keeps_k3_p1_p2_and_reads_old_files(tmp_path):
    from toolbox.io.crs import parse_crs
    from toolbox.photogrammetry.project import Project

    photo = frame_photo((0.0, 0.0, 1000.0), (0.0, 0.0, 0.0), crs=parse_crs("EPSG:3003"),
                        distortion=RadialDistortion.from_polynomial(**TERMS))
    project = Project(photo.exterior.crs, {photo.camera.name: photo.camera},
                      {photo.id: photo})
    save_project(project, tmp_path / "p.yaml")
    text = (tmp_path / "p.yaml").read_text()
    assert "p1:" in text and "k3:" in text
    back = load_project(tmp_path / "p.yaml").cameras[photo.camera.name].distortion
    assert {k: getattr(back, k) for k in TERMS} == TERMS
    # an old file: k1 (and k2) only, the others 0 and not written
    old = RadialDistortion.from_dict({"polynomial": {"k1": -1.2e-8}})
    assert (old.k2, old.k3, old.p1, old.p2) == (0.0, 0.0, 0.0, 0.0)
    assert old.as_dict() == {"polynomial": {"k1": -1.2e-8, "k2": 0.0}}
    with pytest.raises(InputDataError, match=r"polynomial has no p3 \(terms: k1, k2, k3, p1, p2"):
        RadialDistortion.from_dict({"polynomial": {"k1": 1e-8, "p3": 1e-7}})
    with pytest.raises(InputDataError, match="polynomial.p1 must be a number, got 'x'"):
        RadialDistortion.from_dict({"polynomial": {"k1": 1e-8, "p1": "x"}})
    with pytest.raises(InputDataError, match="polynomial lacks 'k1'"):
        RadialDistortion.from_dict({"polynomial": {"p1": 1e-7}})
