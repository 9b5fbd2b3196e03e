"""Camera models against OpenCV as the independent oracle (cv2.projectPoints, undistortPoints,
cv2.fisheye), round trips, the factory's spec schema and the validity limits.

OpenCV's pixels put the top-left pixel's centre at (0, 0), the product's at (0.5, 0.5): every
comparison shifts by 0.5 explicitly."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from toolbox.cameras import (
    CameraModel,
    FrameCamera,
    create_camera,
    create_intrinsics,
    from_opensfm,
)
from toolbox.errors import InputDataError
from toolbox.photogrammetry.exterior import ExteriorOrientation

W, H = 1368, 912
ODM_BROWN = {"type": "brown", "im_size": [W, H], "focal_len": 0.6664614123723713,
             "cx": -0.0015460447606643697, "cy": 0.004751874732641298,
             "k1": -0.2640629100413887, "k2": 0.10188934223670705, "p1": 0.0007345906274317972,
             "p2": 0.0002595206713083041, "k3": -0.02581956399353581}
OPENCV_FULL = {"type": "opencv", "im_size": [W, H], "focal_len": [8.8, 8.7],
               "sensor_size": [13.2, 8.8], "cx": 0.01, "cy": -0.02, "k1": -0.12, "k2": 0.05,
               "k3": -0.01, "k4": 0.02, "k5": 0.004, "k6": 0.001, "p1": 0.0012, "p2": -0.0008,
               "s1": 0.002, "s2": -0.0005, "s3": -0.0015, "s4": 0.0004}
FISHEYE = {"type": "fisheye", "im_size": [1200, 1000], "focal_len": 0.3, "cx": 0.005,
           "cy": -0.01, "k1": -0.03, "k2": 0.004, "k3": -0.0008, "k4": 0.0001}
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)


def points_in_view(model, n=400, seed=0):
    """Camera-frame points whose ideal image lies in (and a little beyond) the image."""
    rng = np.random.default_rng(seed)
    w, h = model.image_size_px
    (fx, fy), (cx, cy) = model.focal_px, model.principal_point_px
    x = (rng.uniform(-0.05 * w, 1.05 * w, n) - cx) / fx * 0.8
    y = (rng.uniform(-0.05 * h, 1.05 * h, n) - cy) / fy * 0.8
    z = rng.uniform(5.0, 80.0, n)
    return np.column_stack([x * z, y * z, z])


def image_pixels(model, step=37):
    w, h = model.image_size_px
    cols, rows = np.meshgrid(np.arange(0.5, w, step), np.arange(0.5, h, step))
    return np.column_stack([cols.ravel(), rows.ravel()])


@pytest.mark.parametrize("spec", [ODM_BROWN, OPENCV_FULL], ids=["brown", "opencv-thin-prism"])
def test_projection_equals_opencv_project_points(spec):
    model = create_intrinsics(spec)
    xyz = points_in_view(model)
    ours = model.camera_to_pixel(xyz)
    theirs, _ = cv2.projectPoints(xyz, np.zeros(3), np.zeros(3), model.matrix(),
                                  model.opencv_coefficients())
    np.testing.assert_allclose(ours - 0.5, theirs.reshape(-1, 2), atol=1e-8)


@pytest.mark.parametrize("spec", [ODM_BROWN, OPENCV_FULL], ids=["brown", "opencv-thin-prism"])
def test_undistortion_equals_opencv_and_round_trips_within_a_thousandth_of_a_pixel(spec):
    model = create_intrinsics(spec)
    px = image_pixels(model)
    rays, failed = model.pixel_to_camera(px)
    assert failed == 0
    ours = rays[:, :2] / rays[:, 2:]
    theirs = cv2.undistortPoints((px - 0.5).reshape(-1, 1, 2), model.matrix(),
                                 model.opencv_coefficients(), criteria=CRITERIA)
    fx = model.focal_px[0]
    # OpenCV's fixed-point iteration is itself converged to ~1e-6 px here
    assert np.abs(ours - theirs.reshape(-1, 2)).max() * fx < 1e-3
    back = model.camera_to_pixel(rays)
    assert np.abs(back - px).max() < 1e-3


def test_fisheye_equals_opencv_fisheye_both_ways():
    model = create_intrinsics(FISHEYE)
    xyz = points_in_view(model)
    ours = model.camera_to_pixel(xyz)
    theirs, _ = cv2.fisheye.projectPoints(xyz.reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                                          model.matrix(), model.opencv_coefficients())
    np.testing.assert_allclose(ours - 0.5, theirs.reshape(-1, 2), atol=1e-8)
    px = image_pixels(model)
    rays, failed = model.pixel_to_camera(px)
    assert failed == 0
    theirs = cv2.fisheye.undistortPoints((px - 0.5).reshape(-1, 1, 2), model.matrix(),
                                         model.opencv_coefficients(), criteria=CRITERIA)
    ahead = rays[:, 2] > 0.05  # OpenCV's normalised coordinates exist in front only
    ours = rays[ahead, :2] / rays[ahead, 2:]
    assert np.abs(ours - theirs.reshape(-1, 2)[ahead]).max() * model.focal_px[0] < 1e-3
    assert np.abs(model.camera_to_pixel(rays) - px).max() < 1e-3
    # the corners of this 1200 x 1000 fisheye see rays past 90 degrees: kept, not dropped
    assert np.degrees(np.arccos(rays[:, 2])).max() > 90


def test_points_past_the_valid_field_have_no_image_where_opencv_folds_them_back():
    """A strong barrel term folds the polynomial back: OpenCV maps a point far outside the
    field into the image; the model says 'no image' (NaN) instead."""
    spec = {"type": "brown", "im_size": [1000, 1000], "focal_len": 1.0, "k1": -0.25}
    model = create_intrinsics(spec)
    assert model.valid_radius == pytest.approx(1 / math.sqrt(3 * 0.25), abs=1e-3)
    far = np.array([[2.0, 0.0, 1.0]])  # 63 degrees off axis, outside the 45-degree field
    theirs, _ = cv2.projectPoints(far, np.zeros(3), np.zeros(3), model.matrix(),
                                  model.opencv_coefficients())
    assert theirs[0, 0] == pytest.approx([499.5, 499.5])  # OpenCV: the image centre
    assert np.isnan(model.camera_to_pixel(far)).all()
    assert np.isnan(model.camera_to_pixel(np.array([[0.1, 0.1, -1.0]]))).all()  # behind


def test_pixels_outside_a_fisheye_field_are_nan_and_counted():
    spec = dict(FISHEYE, k1=-0.2, k2=0.0, k3=0.0, k4=0.0)  # θd stops growing at θ = 1.29
    model = create_intrinsics(spec)
    assert model.valid_radius == pytest.approx(math.sqrt(1 / 0.6), abs=1e-3)
    px = image_pixels(model, step=23)
    rays, failed = model.pixel_to_camera(px)
    (fx, fy), (cx, cy) = model.focal_px, model.principal_point_px
    # θd at the field's edge θ = valid_radius: OpenCV's fisheye distortion of the ray at that angle
    reach = cv2.fisheye.distortPoints(np.array([[[math.tan(model.valid_radius), 0.0]]]),
                                      np.eye(3), model.opencv_coefficients())[0, 0, 0]
    beyond = np.hypot((px[:, 0] - cx) / fx, (px[:, 1] - cy) / fy) > reach
    assert beyond.sum() > 100
    assert failed == beyond.sum()
    assert np.isnan(rays[beyond]).all() and np.isfinite(rays[~beyond]).all()
    assert np.abs(model.camera_to_pixel(rays[~beyond]) - px[~beyond]).max() < 1e-3


def test_posed_camera_equals_opencv_with_the_product_exterior_convention():
    """R(omega, phi, kappa) maps the photogrammetric image frame to the ground; OpenCV's
    world -> camera rotation is diag(1, -1, -1)·Rᵀ and its translation -R_cw·C."""
    eo = ExteriorOrientation.from_angles("p", 1000.0, 2000.0, 300.0, 3.0, -4.0, 35.0, unit="deg")
    camera = create_camera(ODM_BROWN, eo)
    assert isinstance(camera, FrameCamera) and isinstance(camera, CameraModel)
    rng = np.random.default_rng(3)
    ground = np.column_stack([rng.uniform(880, 1120, 300), rng.uniform(1920, 2080, 300),
                              rng.uniform(0, 40, 300)])
    r_cw = np.diag([1.0, -1.0, -1.0]) @ eo.rotation.T
    theirs, _ = cv2.projectPoints(ground, cv2.Rodrigues(r_cw)[0], -r_cw @ eo.centre,
                                  camera.intrinsics.matrix(),
                                  camera.intrinsics.opencv_coefficients())
    ours = camera.project(ground)
    inside = np.isfinite(ours[:, 0])
    assert inside.mean() > 0.9
    np.testing.assert_allclose(ours[inside] - 0.5, theirs.reshape(-1, 2)[inside], atol=1e-6)
    # unproject and pixel_to_ground give the ground point back
    back = camera.pixel_to_ground(ours[inside], ground[inside, 2])
    np.testing.assert_allclose(back, ground[inside], atol=1e-6)
    rays = camera.unproject(ours[inside])
    toward = ground[inside] - eo.centre
    np.testing.assert_allclose(rays, toward / np.linalg.norm(toward, axis=1)[:, None],
                               atol=1e-9)


def test_spec_schema_focal_and_principal_point():
    """Orthority's interior schema: focal_len with sensor_size in its units, else normalised
    by max(w, h); cx, cy offsets from the image centre normalised by max(w, h)."""
    m = create_intrinsics(OPENCV_FULL)
    assert m.focal_px == pytest.approx((8.8 * W / 13.2, 8.7 * H / 8.8))
    assert m.principal_point_px == pytest.approx((W / 2 + 0.01 * W, H / 2 - 0.02 * W))
    portrait = create_intrinsics({"type": "pinhole", "im_size": [600, 800], "focal_len": 0.5,
                                  "cx": 0.1})
    assert portrait.focal_px == (400.0, 400.0)
    assert portrait.principal_point_px == (380.0, 400.0)
    # OpenSfM's camera dict: the same numbers under its own keys
    osfm = from_opensfm({"projection_type": "brown", "width": W, "height": H,
                         "focal_x": ODM_BROWN["focal_len"], "focal_y": ODM_BROWN["focal_len"],
                         "c_x": ODM_BROWN["cx"], "c_y": ODM_BROWN["cy"],
                         **{k: ODM_BROWN[k] for k in ("k1", "k2", "k3", "p1", "p2")}})
    a, b = create_intrinsics(osfm), create_intrinsics(ODM_BROWN)
    assert a.focal_px == b.focal_px and a.principal_point_px == b.principal_point_px
    assert a.coefficients == b.coefficients
    fish = from_opensfm({"projection_type": "fisheye", "width": 100, "height": 80,
                         "focal": 0.4, "k1": 0.01, "k2": 0.0})
    assert fish["type"] == "fisheye" and create_intrinsics(fish).coefficients["k3"] == 0.0


@pytest.mark.parametrize("spec, message", [
    ({"type": "kannala", "im_size": [10, 10], "focal_len": 1}, "type must be one of"),
    ({"type": "brown", "im_size": [10, 10], "focal_len": 1, "k4": 0.1}, "has no k4"),
    ({"type": "brown", "focal_len": 1}, "im_size is required"),
    ({"type": "pinhole", "im_size": [10, 10], "focal_len": -1}, "focal length must be > 0"),
    ({"type": "pinhole", "im_size": [10.5, 10], "focal_len": 1}, "whole numbers"),
    ({"type": "brown", "im_size": [4000, 3000], "focal_len": 0.3, "k1": -0.3},
     "do not fit the image size"),
])
def test_bad_specs_are_one_line_errors(spec, message):
    with pytest.raises(InputDataError, match=message) as info:
        create_intrinsics(spec, "cam")
    assert "\n" not in str(info.value)


def test_bad_opensfm_camera_and_posing():
    with pytest.raises(InputDataError, match="projection_type 'spherical' is not supported"):
        from_opensfm({"projection_type": "spherical", "width": 10, "height": 5})
    with pytest.raises(InputDataError, match="needs an exterior orientation"):
        create_camera(ODM_BROWN)
    with pytest.raises(InputDataError, match="film camera"):
        create_camera({"type": "frame", "principal_distance_mm": 153})


@pytest.mark.parametrize("spec", [ODM_BROWN, OPENCV_FULL, FISHEYE,
                                  {"type": "brown", "im_size": [1000, 1000], "focal_len": 1.0,
                                   "k1": -0.25}], ids=["brown", "opencv", "fisheye", "folding"])
def test_compiled_grid_map_equals_the_model(spec):
    """FrameCamera.project_grid (the ortho's compiled map) against project (numpy): the same
    pixels to float32 rounding and the same cells without image (behind, past the valid
    field, no height)."""
    eo = ExteriorOrientation.from_angles("p", 0.0, 0.0, 100.0, 20.0, -15.0, 30.0, unit="deg")
    camera = create_camera(spec, eo)
    x = np.linspace(-400.0, 400.0, 160)
    gx, gy = np.meshgrid(x, x)
    z = np.random.default_rng(5).uniform(0.0, 30.0, gx.shape)
    z[10:14] = np.nan
    cols, rows, box = camera.project_grid(gx, gy[:, :1], z)  # broadcast rows too
    ref = camera.project(np.column_stack([gx.ravel(), gy.ravel(), z.ravel()]))
    finite = np.isfinite(ref[:, 0])
    assert 0.05 < finite.mean() < 0.98  # some cells without image (no height at least)
    assert np.array_equal(np.isfinite(cols.ravel()), finite)
    scale = np.abs(ref[finite]).max()
    assert np.abs(cols.ravel()[finite] - ref[finite, 0]).max() <= 1e-7 * scale
    assert np.abs(rows.ravel()[finite] - ref[finite, 1]).max() <= 1e-7 * scale
    assert box[4] == (~finite).sum()
    assert box[0] == np.float32(ref[finite, 0]).min() and box[3] == np.float32(ref[finite, 1]).max()
