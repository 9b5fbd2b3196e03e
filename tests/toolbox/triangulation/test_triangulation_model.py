"""The observation model against independent references: scipy's rotations, the toolbox's own
camera chain and finite differences."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tests.toolbox.triangulation.jacobians import assert_central_differences
from toolbox.photogrammetry.synthetic import frame_photo
from toolbox.triangulation.model import image_residuals, rotations


def test_rotation_is_omega_phi_kappa_of_scipy():
    rng = np.random.default_rng(0)
    angles = rng.uniform(-1, 1, (20, 3))
    r, _ = rotations(angles)
    ref = Rotation.from_euler("XYZ", angles).as_matrix()  # intrinsic X, Y', Z''
    assert np.abs(r - ref).max() < 1e-14


def test_projection_matches_the_toolbox_camera_chain():
    photo = frame_photo((1000.0, 2000.0, 1500.0), (0.02, -0.03, 0.4), principal_distance_mm=150.0)
    ground = np.array([[900.0, 2100.0, 120.0], [1200.0, 1800.0, 300.0], [1000.0, 2000.0, 0.0]])
    xy = photo.ground_to_image(ground)
    eo = photo.exterior
    ext = np.tile([*eo.centre, eo.omega, eo.phi, eo.kappa], (3, 1))
    calib = np.tile([150.0, 0, 0, 0, 0, 0, 0, 0], (3, 1))
    f, depth = image_residuals(xy, ext, ground, calib, jacobians=False)
    assert np.abs(f).max() < 1e-9 and (depth < 0).all()


def _random_observations(rng: np.random.Generator, m: int) -> tuple[np.ndarray, ...]:
    """``m`` random image points, exterior orientations (1500 m up, small angles), ground points
    and film calibrations (c = 150 mm, small distortion): the arguments of image_residuals."""
    xy = rng.normal(0, 60, (m, 2))
    ext = np.column_stack([rng.normal(0, 100, (m, 3)) + [0, 0, 1500], rng.normal(0, .05, (m, 3))])
    pt = rng.normal(0, 300, (m, 3))
    cal = np.column_stack([np.full(m, 150.0), rng.normal(0, .01, (m, 2)),
                           rng.normal(0, 1e-6, m), rng.normal(0, 1e-10, m),
                           rng.normal(0, 1e-14, m), rng.normal(0, 1e-6, (m, 2))])
    return xy, ext, pt, cal


@pytest.mark.parametrize("which", [2, 3, 4])
def test_jacobians_match_central_differences(which):
    args = list(_random_observations(np.random.default_rng(which), 7))
    steps = {2: [1e-3] * 3 + [1e-7] * 3, 3: [1e-3] * 3,
             4: [1e-4, 1e-5, 1e-5, 1e-9, 1e-13, 1e-17, 1e-8, 1e-8]}[which]
    assert_central_differences(image_residuals, args, which, steps, atol=1e-12)


@pytest.mark.parametrize("angle", [30.0, -60.0, 90.0])
def test_error_ellipse_of_a_rotated_covariance(angle):
    from toolbox.triangulation.outputs import error_ellipse

    t = np.radians(angle)
    r = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    a, b, direction = error_ellipse(r @ np.diag([4.0, 1.0]) @ r.T)
    assert (a, b) == pytest.approx((2.0, 1.0)) and direction == pytest.approx(angle)


def test_self_calibration_specification_per_camera():
    from toolbox.errors import ParameterError
    from toolbox.triangulation.block import FIXED, FREE, WEIGHTED
    from toolbox.triangulation.inputs import calibration_settings, parse_self_calibration

    spec = parse_self_calibration("c, k1:weighted:1e-6, x0@wild 303.55, c@rc30:fixed")
    modes, sig = calibration_settings(spec, ["wild 303.55", "rc30"], ["wild 303.55", "rc30"])
    assert modes[0].tolist() == [FREE, FREE, FIXED, WEIGHTED, FIXED, FIXED, FIXED, FIXED]
    assert modes[1].tolist() == [FIXED, FIXED, FIXED, WEIGHTED, FIXED, FIXED, FIXED, FIXED]
    assert sig[1, 3] == 1e-6
    with pytest.raises(ParameterError, match="SELF_CALIBRATION.*'nope'"):
        calibration_settings(parse_self_calibration("c@nope"), ["a"], ["a"])
    assert parse_self_calibration("f, cx, cy") == parse_self_calibration("c, x0, y0")  # Brown
    for bad in ("k4", "c:sometimes", "k1:weighted", "k1:weighted:-1"):
        with pytest.raises(ParameterError, match="SELF_CALIBRATION"):
            parse_self_calibration(bad)


@pytest.mark.parametrize("jacobians", [True, False])
def test_compiled_collinearity_kernel_is_the_numpy_formula(jacobians):
    """image_residuals (compiled kernel) against image_residuals_numpy, element by element."""
    from toolbox.triangulation.model import image_residuals_numpy

    xy, ext, pt, cal = _random_observations(np.random.default_rng(9), 500)
    got = image_residuals(xy, ext, pt, cal, jacobians)
    ref = image_residuals_numpy(xy, ext, pt, cal, jacobians)
    assert len(got) == len(ref) == (5 if jacobians else 2)
    for a, b in zip(got, ref, strict=True):
        assert a.shape == b.shape and np.abs(a - b).max() <= 1e-12 * np.abs(b).max()


def test_compiled_point_block_inverses_and_their_singularity_flags():
    from toolbox.triangulation.schur import inverse_blocks

    rng = np.random.default_rng(4)
    a = rng.normal(size=(50, 3, 3))
    c = a @ np.transpose(a, (0, 2, 1)) + 0.1 * np.eye(3)
    c[3] = np.outer([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])  # rank 1: parallel rays
    c[7] = np.diag([1.0, 1.0, 1e-16])  # nearly singular
    c[9] = -np.eye(3)  # not positive definite
    inv, ok = inverse_blocks(c, 1e14)
    assert ok.tolist() == [k not in (3, 7, 9) for k in range(50)]
    assert np.abs(inv[ok] - np.linalg.inv(c[ok])).max() < 1e-9
