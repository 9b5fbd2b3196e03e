"""Relative orientation against the truth of a synthetic pair and against OpenCV's essential
matrix (an independent five-point solver), both parameter sets, the critical cylinder."""

import cv2
import numpy as np
import pytest

from toolbox.errors import InputDataError
from toolbox.photogrammetry.rotation import rotation_matrix
from toolbox.triangulation.relative import RelativeRequest, relative_orientation
from toolbox.triangulation.synthetic import SyntheticBlockSpec, make_block

FLIP = np.diag([1.0, -1.0, -1.0])  # toolbox camera frame (y up, looking down -z) <-> OpenCV


def _pair(noise_mm):
    sb = make_block(SyntheticBlockSpec(digital=False, seed=4, sigma_mm=noise_mm))
    p1, p2 = sb.project.photos["1_01"], sb.project.photos["1_02"]
    xy = sb.xy if noise_mm else sb.true_xy
    on1 = {pt: xy[k] for k, (pt, ph) in enumerate(zip(sb.obs_point, sb.obs_photo)) if ph == "1_01"}
    on2 = {pt: xy[k] for k, (pt, ph) in enumerate(zip(sb.obs_point, sb.obs_photo)) if ph == "1_02"}
    common = sorted(set(on1) & set(on2))
    return p1, p2, np.array([on1[p] for p in common]), np.array([on2[p] for p in common])


def _truth(p1, p2):
    r1, r2 = p1.exterior.rotation, p2.exterior.rotation
    b = r1.T @ (np.asarray(p2.exterior.centre) - p1.exterior.centre)
    return r1.T @ r2, b / b[0]


def test_dependent_set_recovers_the_true_relative_orientation_noise_free():
    p1, p2, xy1, xy2 = _pair(0.0)
    res = relative_orientation(RelativeRequest(xy1, xy2, 153.0, 153.0, "dependent"))
    rel, base = _truth(p1, p2)
    assert np.abs(res.rotation2 - rel).max() < 1e-9
    assert np.abs(res.base - base).max() < 1e-9
    assert np.abs(res.py_mm).max() < 1e-9
    assert not res.warnings and len(xy1) >= 12
    ind = relative_orientation(RelativeRequest(xy1, xy2, 153.0, 153.0, "independent"))
    assert np.abs(ind.rotation1.T @ ind.rotation2 - rel).max() < 1e-9
    assert np.abs(ind.rotation1.T @ ind.base / np.linalg.norm(ind.base) -
                  base / np.linalg.norm(base)).max() < 1e-9


def test_same_rotation_and_base_direction_as_opencv_essential_matrix():
    p1, p2, xy1, xy2 = _pair(0.0)
    res = relative_orientation(RelativeRequest(xy1, xy2, 153.0, 153.0, "dependent"))
    n1 = np.column_stack([xy1[:, 0], -xy1[:, 1]]) / 153.0  # normalised OpenCV coordinates
    n2 = np.column_stack([xy2[:, 0], -xy2[:, 1]]) / 153.0
    e, _ = cv2.findEssentialMat(n1, n2, focal=1.0, pp=(0.0, 0.0), method=cv2.LMEDS)
    _, r_cv, t_cv, _ = cv2.recoverPose(e[:3], n1, n2, focal=1.0, pp=(0.0, 0.0))
    # x2_cv = R_cv·x1_cv + t: R_cv = F·R2ᵀ·F, t ∝ -F·R2ᵀ·b
    assert np.abs(r_cv - FLIP @ res.rotation2.T @ FLIP).max() < 1e-6
    t = -FLIP @ res.rotation2.T @ res.base
    assert np.abs(t_cv.ravel() - t / np.linalg.norm(t)).max() < 1e-6


def test_independent_set_gives_the_same_model_and_parallaxes_with_noise():
    p1, p2, xy1, xy2 = _pair(0.004)
    dep = relative_orientation(RelativeRequest(xy1, xy2, 153.0, 153.0, "dependent"))
    ind = relative_orientation(RelativeRequest(xy1, xy2, 153.0, 153.0, "independent"))
    # equivalent up to second order in the noise: the y-parallax is measured in each set's own
    # model frame (exactly equal without noise)
    assert np.abs(dep.rotation1.T @ dep.rotation2 - ind.rotation1.T @ ind.rotation2).max() < 1e-5
    assert np.abs(np.abs(dep.py_mm) - np.abs(ind.py_mm)).max() < 2e-4
    assert dep.sigma0_mm == pytest.approx(ind.sigma0_mm, rel=2e-2)
    # the y-parallax noise of one point is about sqrt(2) times the coordinate noise
    assert 0.5 * 0.004 < dep.sigma0_mm < 2.5 * 0.004
    rel, base = _truth(p1, p2)
    angle = np.linalg.norm(cv2.Rodrigues(dep.rotation2.T @ rel)[0])
    assert angle < 4 * max(dep.std["omega2"], dep.std["phi2"], dep.std["kappa2"]) * 1.8
    assert set(ind.parameters) == {"phi1", "kappa1", "omega2", "phi2", "kappa2"}


def test_points_on_the_critical_cylinder_raise_a_warning():
    h, radius, base = 1500.0, 900.0, 600.0
    c1, c2 = np.array([0.0, 0.0, h]), np.array([base, 0.0, h])
    axis_z = h - radius  # cylinder through both centres, axis along the base
    theta = np.radians(np.linspace(150, 210, 4))
    xs = np.linspace(50, 550, 4)
    t, x = np.meshgrid(theta, xs)
    pts = np.column_stack([x.ravel(), radius * np.sin(t.ravel()),
                           axis_z + radius * np.cos(t.ravel())])
    r = rotation_matrix(0.0, 0.0, 0.0)

    def project(centre):
        d = (pts - centre) @ r
        return -153.0 * d[:, :2] / d[:, 2:3]

    res = relative_orientation(RelativeRequest(project(c1), project(c2), 153.0, 153.0))
    assert any("critical surface" in w for w in res.warnings)
    # the same pair on flat ground is fine
    pts[:, 2] = 0.0
    pts[:, 1] = np.tile(np.linspace(-400, 400, 4), 4)
    good = relative_orientation(RelativeRequest(project(c1), project(c2), 153.0, 153.0))
    assert not good.warnings


def test_fewer_than_five_points_are_refused():
    with pytest.raises(InputDataError, match="at least 5"):
        relative_orientation(RelativeRequest(np.zeros((4, 2)), np.zeros((4, 2)), 153.0, 153.0))
