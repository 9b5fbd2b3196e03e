"""Camera model: radial distortion (table and polynomial), image <-> camera coordinates."""

import numpy as np
import pytest

from toolbox.errors import InputDataError
from toolbox.photogrammetry.camera import Camera, RadialDistortion

SIENA_R = [10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 148]
SIENA_DR = [0.0, 0.1, -0.1, -0.3, -0.5, -0.9, -1.0, -1.1, -0.3, 0.2, 1.2, 1.3, 0.5, -0.4, -1.4]


def test_table_values_at_nodes_between_and_beyond():
    d = RadialDistortion.from_table(SIENA_R, SIENA_DR, "um")
    np.testing.assert_allclose(d.delta_r(np.array(SIENA_R, float)), np.array(SIENA_DR) / 1000)
    assert d.delta_r(np.array([0.0]))[0] == 0.0  # (0, 0) prepended
    assert d.delta_r(np.array([5.0]))[0] == 0.0  # between (0, 0) and (10, 0)
    assert d.delta_r(np.array([85.0]))[0] == pytest.approx(-0.7e-3)  # halfway -1.1 .. -0.3 um
    assert d.delta_r(np.array([160.0]))[0] == pytest.approx(-1.4e-3)  # last value held


def test_correct_moves_points_radially_by_minus_delta_r():
    d = RadialDistortion.from_table(SIENA_R, SIENA_DR, "um")
    xy = np.array([[60.0, 80.0]])  # r = 100 mm, dr = +0.2 um
    corrected = d.correct(xy)
    assert np.hypot(*corrected[0]) == pytest.approx(100.0 - 0.2e-3, abs=1e-12)
    np.testing.assert_allclose(corrected[0] / np.hypot(*corrected[0]), [0.6, 0.8])


@pytest.mark.parametrize("distortion", [
    RadialDistortion.from_table(SIENA_R, SIENA_DR, "um"),
    RadialDistortion.from_polynomial(-3e-8, 2e-13),
    RadialDistortion.from_table([0, 50, 100, 150], [0, 0.02, -0.03, 0.05], "mm"),
])
def test_distort_inverts_correct(distortion):
    rng = np.random.default_rng(0)
    xy = rng.uniform(-115, 115, (500, 2))
    np.testing.assert_allclose(distortion.correct(distortion.distort(xy)), xy, atol=1e-12)
    np.testing.assert_allclose(distortion.distort(distortion.correct(xy)), xy, atol=1e-12)


def test_polynomial_matches_formula():
    d = RadialDistortion.from_polynomial(-2e-8, 1e-13)
    r = np.array([50.0, 100.0, 150.0])
    np.testing.assert_allclose(d.delta_r(r), -2e-8 * r ** 3 + 1e-13 * r ** 5)


def test_camera_image_camera_round_trip_with_principal_point():
    cam = Camera("c", 153.0, (0.012, -0.008),
                 distortion=RadialDistortion.from_polynomial(-5e-8))
    xy = np.array([[10.0, -20.0], [100.0, 100.0], [0.012, -0.008]])
    camera_xy = cam.image_to_camera(xy)
    np.testing.assert_allclose(camera_xy[2], [0.0, 0.0], atol=1e-15)  # the PP is the origin
    np.testing.assert_allclose(cam.camera_to_image(camera_xy), xy, atol=1e-12)


def test_bad_distortion_and_camera_refused():
    with pytest.raises(InputDataError, match="strictly increasing"):
        RadialDistortion.from_table([10, 5], [0, 0])
    with pytest.raises(InputDataError, match="as many radii"):
        RadialDistortion.from_table([10, 20], [0])
    with pytest.raises(InputDataError, match="'table' or 'polynomial'"):
        RadialDistortion.from_dict({"k1": 1.0})
    with pytest.raises(InputDataError, match="lacks 'k1'"):
        RadialDistortion.from_dict({"polynomial": {"k2": 1.0}})
    with pytest.raises(InputDataError, match="principal distance must be > 0"):
        Camera("c", -150.0)
    with pytest.raises(InputDataError, match="pixel size"):
        Camera("c", 150.0, pixel_size_mm=0.0)


def test_distortion_dict_round_trip():
    d = RadialDistortion.from_table(SIENA_R, SIENA_DR, "um")
    again = RadialDistortion.from_dict(d.as_dict())
    np.testing.assert_allclose(again.r_mm, d.r_mm)
    np.testing.assert_allclose(again.dr_mm, d.dr_mm)
