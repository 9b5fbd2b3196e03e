"""R(omega, phi, kappa) element by element against the domain brief (S000 l.336), its inverse,
angle units and the refusal of bad matrices and units."""

import math

import numpy as np
import pytest

from toolbox.errors import InputDataError, ParameterError
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.rotation import (
    angle_unit,
    angles_from_matrix,
    check_rotation,
    from_radians,
    rotation_matrix,
    to_radians,
)

ANGLES = [(0.014, -0.001, 0.050), (0.016, 0.016, 3.122), (-0.3, 0.7, -2.5), (1.2, -1.1, 0.4)]


def brief_matrix(o, p, k):
    """The nine elements exactly as printed in the brief, section 3 (S000 l.336)."""
    so, co, sp, cp, sk, ck = math.sin(o), math.cos(o), math.sin(p), math.cos(p), math.sin(k), \
        math.cos(k)
    return np.array([
        [ck * cp, -sk * cp, sp],
        [ck * sp * so + co * sk, ck * co - sp * so * sk, -so * cp],
        [so * sk - ck * sp * co, co * sp * sk + ck * so, cp * co],
    ])


@pytest.mark.parametrize("o, p, k", ANGLES)
def test_rotation_matrix_element_by_element(o, p, k):
    r = rotation_matrix(o, p, k)
    expected = brief_matrix(o, p, k)
    for i in range(3):
        for j in range(3):
            assert r[i, j] == pytest.approx(expected[i, j], abs=1e-15), f"r{i + 1}{j + 1}"


@pytest.mark.parametrize("o, p, k", ANGLES)
def test_rotation_is_rx_ry_rz_and_inverse_of_elementary_product(o, p, k):
    rx = np.array([[1, 0, 0], [0, math.cos(o), -math.sin(o)], [0, math.sin(o), math.cos(o)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(k), -math.sin(k), 0], [math.sin(k), math.cos(k), 0], [0, 0, 1]])
    r = rotation_matrix(o, p, k)
    np.testing.assert_allclose(r, rx @ ry @ rz, atol=1e-15)
    # S000 l.310-328: the printed elementary matrices take object axes to rotated axes and
    # X' = R^-1 X = R_kappa R_phi R_omega X
    r_o, r_p, r_k = rx.T, ry.T, rz.T
    np.testing.assert_allclose(np.linalg.inv(r), r_k @ r_p @ r_o, atol=1e-14)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-15)


def test_small_angle_approximation_of_the_thesis():
    """S002 eq. [13]: R ~ [[1, -k, p], [k, 1, -o], [-p, o, 1]] below 5 gon."""
    o, p, k = 1e-4, -2e-4, 3e-4
    approx = np.array([[1, -k, p], [k, 1, -o], [-p, o, 1]])
    np.testing.assert_allclose(rotation_matrix(o, p, k), approx, atol=1e-7)


def test_vectorised_shapes():
    o = np.array([0.1, 0.2, 0.3])
    r = rotation_matrix(o, 0.0, np.array([[0.0], [1.0]]))
    assert r.shape == (2, 3, 3, 3)
    np.testing.assert_allclose(r[1, 2], rotation_matrix(0.3, 0.0, 1.0))


def test_angles_from_matrix_round_trip_random():
    rng = np.random.default_rng(3)
    for _ in range(200):
        o, k = rng.uniform(-math.pi, math.pi, 2)
        p = rng.uniform(-1.5, 1.5)
        back = angles_from_matrix(rotation_matrix(o, p, k))
        np.testing.assert_allclose(back, (o, p, k), atol=1e-12)


def test_gimbal_lock_gives_a_matrix_equal_to_the_input():
    r = rotation_matrix(0.3, math.pi / 2, 0.5)
    o, p, k = angles_from_matrix(r)
    assert o == 0.0 and p == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(rotation_matrix(o, p, k), r, atol=1e-12)


def test_non_orthonormal_and_reflection_refused():
    r = rotation_matrix(0.1, 0.2, 0.3)
    with pytest.raises(InputDataError, match="not orthonormal"):
        angles_from_matrix(r * 1.01)
    with pytest.raises(InputDataError, match="reflection"):
        check_rotation(r @ np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InputDataError, match="3 x 3"):
        check_rotation(np.eye(2))
    with pytest.raises(InputDataError, match="not orthonormal"):
        ExteriorOrientation.from_matrix("p1", (0, 0, 1000), np.array([[1, 0.1, 0], [0, 1, 0],
                                                                      [0, 0, 1.0]]))


def test_angle_units():
    assert to_radians(200.0, "gon") == pytest.approx(math.pi)
    assert to_radians(180.0, "degrees") == pytest.approx(math.pi)
    assert from_radians(math.pi / 2, "grad") == pytest.approx(100.0)
    np.testing.assert_allclose(to_radians(np.array([90.0, 45.0]), "deg"), [math.pi / 2, math.pi / 4])
    assert angle_unit("RADIANS") == "rad" and angle_unit(" Gon ") == "gon"
    eo = ExteriorOrientation.from_angles("p", 0, 0, 1000, 1.0, -2.0, 100.0, unit="gon")
    assert eo.kappa == pytest.approx(math.pi / 2) and eo.source_unit == "gon"
    assert eo.angles("deg") == pytest.approx((0.9, -1.8, 90.0))
    np.testing.assert_allclose(eo.rotation, rotation_matrix(*eo.angles("rad")))


def test_unknown_angle_unit_is_a_parameter_error():
    with pytest.raises(ParameterError, match=r"ANGLE_UNIT must be one of rad, deg, gon.*'mil'"):
        ExteriorOrientation.from_angles("p", 0, 0, 1000, 1, 2, 3, unit="mil")
    with pytest.raises(ParameterError, match="UNIT"):
        to_radians(1.0, "turns", "UNIT")


def test_exterior_orientation_requires_finite_values():
    with pytest.raises(InputDataError, match="photo 'x'"):
        ExteriorOrientation("x", 0.0, float("nan"), 1000.0, 0.0, 0.0, 0.0)
