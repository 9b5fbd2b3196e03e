"""The bundle's Brown (digital, pixel) observation model against OpenCV's ``projectPoints`` and
finite differences, and its inversion (approximate values) against OpenCV's
``undistortPoints``."""

import cv2
import numpy as np
import pytest

from tests.toolbox.triangulation.jacobians import assert_central_differences
from toolbox.triangulation.model import brown_ideal, brown_residuals, rotations

CALIB = np.array([3000.0, 2010.3, 1495.2, -0.11, 0.05, -0.012, 8e-4, -5e-4])
ASPECT = 1.002


def case(m=9, seed=0):
    rng = np.random.default_rng(seed)
    ext = np.column_stack([rng.normal(0, 50, (m, 3)) + [0, 0, 400], rng.normal(0, .1, (m, 3))])
    pts = np.column_stack([rng.uniform(-150, 150, (m, 2)), rng.uniform(0, 40, m)])
    return ext, pts


def opencv_pixels(ext, pts, calib=CALIB, aspect=ASPECT):
    """Product pixels from cv2.projectPoints (OpenCV frame = photogrammetric with y, z flipped;
    OpenCV pixels are the product's minus 0.5)."""
    out = []
    f = calib[0]
    k = np.array([[f, 0, calib[1] - 0.5], [0, aspect * f, calib[2] - 0.5], [0, 0, 1]])
    dist = np.array([calib[3], calib[4], calib[6], calib[7], calib[5]])
    for e, p in zip(ext, pts, strict=True):
        r = rotations(e[None, 3:])[0][0]
        r_cv = np.diag([1.0, -1.0, -1.0]) @ r.T  # ground -> OpenCV camera
        rvec, _ = cv2.Rodrigues(r_cv)
        tvec = -r_cv @ e[:3]
        px, _ = cv2.projectPoints(p[None], rvec, tvec, k, dist)
        out.append(px.reshape(2) + 0.5)
    return np.array(out)


def test_brown_projection_is_opencvs():
    ext, pts = case()
    px = opencv_pixels(ext, pts)
    m = len(px)
    res, depth = brown_residuals(px, ext, pts, np.tile(CALIB, (m, 1)), np.full(m, ASPECT),
                                 jacobians=False)
    assert (depth < 0).all() and np.abs(res).max() < 1e-6


@pytest.mark.parametrize("which", [2, 3, 4])
def test_brown_jacobians_match_central_differences(which):
    ext, pts = case(seed=which)
    m = len(pts)
    px = opencv_pixels(ext, pts) + 0.7
    args = [px, ext, pts, np.tile(CALIB, (m, 1))]
    steps = {2: [1e-3] * 3 + [1e-7] * 3, 3: [1e-3] * 3,
             4: [1e-2, 1e-3, 1e-3, 1e-6, 1e-6, 1e-6, 1e-7, 1e-7]}[which]

    def residuals(*a, jacobians=True):
        return brown_residuals(*a, np.full(m, ASPECT), jacobians=jacobians)

    assert_central_differences(residuals, args, which, steps, atol=1e-9)


def test_brown_ideal_inverts_the_distortion_opencv_applies():
    """brown_ideal's rays, projected again by cv2.projectPoints, land on the pixels."""
    rng = np.random.default_rng(3)
    px = rng.uniform([0, 0], [4000, 3000], (50, 2))
    f = CALIB[0]
    k = np.array([[f, 0, CALIB[1] - 0.5], [0, ASPECT * f, CALIB[2] - 0.5], [0, 0, 1]])
    dist = np.array([CALIB[3], CALIB[4], CALIB[6], CALIB[7], CALIB[5]])
    got = brown_ideal(px, np.tile(CALIB, (50, 1)), np.full(50, ASPECT), iterations=100)
    rays = np.column_stack([got[:, 0] / f, -got[:, 1] / f, np.ones(50)])  # OpenCV frame
    back, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, dist)
    assert np.abs(back.reshape(-1, 2) + 0.5 - px).max() < 1e-6
