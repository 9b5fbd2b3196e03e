"""GNSS projection centres with a shift and a drift per strip, IMU attitudes with boresight
unknowns: synthetic blocks made through the collinearity equations (the toolbox's camera chain),
GNSS and IMU observations made with scipy's rotations (not the bundle's), the recovered
parameters against the truth, and the whole adjustment against scipy.optimize.least_squares on
the same equations written plainly."""

import numpy as np
import pytest
import scipy.sparse as sp
from block_cases import angle_diff, build_case
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from toolbox.errors import InputDataError
from toolbox.triangulation.adjust import adjust
from toolbox.triangulation.block import Options
from toolbox.triangulation.synthetic import SyntheticBlockSpec

SHIFT = np.array([[0.80, -0.90, 1.20], [-1.00, 0.70, -0.80]])  # m, per strip
DRIFT = np.array([[0.15, -0.12, 0.20], [-0.10, 0.18, 0.12]])  # m per photo interval
BORESIGHT = np.array([0.0020, -0.0015, 0.0030])  # rad
GNSS_SIGMA, IMU_SIGMA = 0.02, 5e-5


@pytest.fixture(scope="module")
def case():
    return build_case(SyntheticBlockSpec(digital=True, seed=4), n_control=6)


def _block(case, shift=False, drift=False, imu=False, control=1, seed=0):
    """A copy of the case's block with GNSS (and IMU) observations and ``control`` full
    control points."""
    from dataclasses import replace

    rng = np.random.default_rng(seed)
    b = case.block
    n = b.n_photos
    strip = np.array([int(p.split("_")[0]) - 1 for p in b.photo_ids])
    number = np.array([int(p.split("_")[1]) for p in b.photo_ids], dtype=float)
    time = number - number.mean()
    centres = case.truth_exterior[:, :3] + SHIFT[strip] * shift + \
        DRIFT[strip] * time[:, None] * drift + rng.normal(0, GNSS_SIGMA, (n, 3))
    extra = {}
    if imu:
        r_true = Rotation.from_euler("XYZ", case.truth_exterior[:, 3:])
        seen = (r_true * Rotation.from_euler("XYZ", BORESIGHT)).as_euler("XYZ")
        extra = {"attitude_photo": np.arange(n),
                 "attitude_obs": seen + rng.normal(0, IMU_SIGMA, (n, 3)),
                 "attitude_sigma": np.full((n, 3), IMU_SIGMA), "boresight": True}
    return replace(b, ground_point=b.ground_point[:control], ground_xyz=b.ground_xyz[:control],
                   ground_sigma=b.ground_sigma[:control], centre_photo=np.arange(n),
                   centre_xyz=centres, centre_sigma=np.full((n, 3), GNSS_SIGMA),
                   centre_group=strip, centre_time=time, gnss_shift=shift, gnss_drift=drift,
                   **extra)


def _adjust(case, block):
    return adjust(block, case.exterior0, case.points0, Options(snooping=False))


def test_gnss_shift_per_strip_is_recovered(case):
    # 4 full control points: with a free shift per strip GNSS fixes neither position nor roll
    sol = _adjust(case, _block(case, shift=True, control=4))
    assert 0.8 < sol.sigma0 < 1.2
    err = sol.gnss_shift - SHIFT
    assert np.abs(err / sol.gnss_shift_std).max() < 4.0 and np.abs(err).max() < 0.15
    assert (np.abs(SHIFT) / sol.gnss_shift_std).min() > 2.5  # the shifts are really measured
    # without the shift unknowns the same observations do not fit
    from dataclasses import replace

    wrong = _adjust(case, replace(_block(case, shift=True), gnss_shift=False, ground_point=
                                  case.block.ground_point[:0], ground_xyz=np.zeros((0, 3)),
                                  ground_sigma=np.zeros((0, 3))))
    assert wrong.sigma0 > 1.5  # chi-square with ~600 degrees of freedom: far beyond chance


def test_gnss_drift_per_strip_is_recovered(case):
    sol = _adjust(case, _block(case, shift=True, drift=True, control=4))
    assert 0.8 < sol.sigma0 < 1.2
    for est, std, truth in ((sol.gnss_shift, sol.gnss_shift_std, SHIFT),
                            (sol.gnss_drift, sol.gnss_drift_std, DRIFT)):
        assert np.abs((est - truth) / std).max() < 4.0
    assert sol.gnss_drift_std.max() < 0.05
    assert (np.abs(DRIFT) / sol.gnss_drift_std).min() > 2.5  # the drifts are really measured


def test_imu_boresight_is_recovered(case):
    sol = _adjust(case, _block(case, imu=True))
    assert 0.8 < sol.sigma0 < 1.2
    err = sol.boresight - BORESIGHT
    assert np.abs(err / sol.boresight_std).max() < 4.0 and np.abs(err).max() < 1e-4
    assert np.abs(sol.attitude_residuals).max() < 5 * IMU_SIGMA


def test_shift_without_a_full_control_point_is_a_datum_error(case):
    with pytest.raises(InputDataError, match="full"):
        _adjust(case, _block(case, shift=True, control=0))
    with pytest.raises(InputDataError, match="roll"):
        _adjust(case, _block(case, shift=True, control=1))


def _reference(case, block):
    """The same weighted least squares (collinearity, control, GNSS with shift and drift, IMU
    with boresight) written plainly with scipy rotations, solved by scipy."""
    b = block
    origin = np.round(case.points0.mean(axis=0))
    n, p, g = b.n_photos, b.n_points, b.n_groups
    c = b.calibration[b.photo_camera, 0]
    m, h, a = len(b.obs_photo), len(b.centre_photo), len(b.attitude_photo)
    sizes = [6 * n, 3 * p, 3 * g, 3 * g, 3]
    starts = np.cumsum([0, *sizes])

    def unpack(x):
        return [x[starts[k]:starts[k + 1]] for k in range(5)]

    def fun(x):
        ext, pts, shift, drift, bore = unpack(x)
        ext, pts, shift, drift = ext.reshape(n, 6), pts.reshape(p, 3), shift.reshape(g, 3), \
            drift.reshape(g, 3)
        rot = Rotation.from_euler("XYZ", ext[:, 3:])
        d = np.einsum("mji,mj->mi", rot.as_matrix()[b.obs_photo],
                      pts[b.obs_point] - ext[b.obs_photo, :3])
        image = ((-c[b.obs_photo, None] * d[:, :2] / d[:, 2:3] - b.obs_xy) / b.obs_sigma)
        ground = (pts[b.ground_point] + origin - b.ground_xyz) / b.ground_sigma
        gnss = (ext[b.centre_photo, :3] + origin + shift[b.centre_group]
                + drift[b.centre_group] * b.centre_time[:, None] - b.centre_xyz) / b.centre_sigma
        seen = (rot[b.attitude_photo] * Rotation.from_euler("XYZ", bore)).as_euler("XYZ")
        imu = angle_diff(seen, b.attitude_obs) / b.attitude_sigma
        return np.concatenate([image.ravel(), ground.ravel(), gnss.ravel(), imu.ravel()])

    rows, cols = [], []
    for i in range(m):
        for k in range(2):
            rows += [2 * i + k] * 9
            cols += list(range(6 * b.obs_photo[i], 6 * b.obs_photo[i] + 6))
            cols += list(range(starts[1] + 3 * b.obs_point[i], starts[1] + 3 * b.obs_point[i] + 3))
    r0 = 2 * m
    for i, pt in enumerate(b.ground_point):
        for k in range(3):
            rows.append(r0 + 3 * i + k)
            cols.append(starts[1] + 3 * pt + k)
    r0 += 3 * len(b.ground_point)
    for i in range(h):
        for k in range(3):
            row = r0 + 3 * i + k
            ph, gr = b.centre_photo[i], b.centre_group[i]
            rows += [row] * 3
            cols += [6 * ph + k, starts[2] + 3 * gr + k, starts[3] + 3 * gr + k]
    r0 += 3 * h
    for i in range(a):
        for k in range(3):
            rows += [r0 + 3 * i + k] * 6
            cols += [6 * b.attitude_photo[i] + 3 + t for t in range(3)] + \
                [starts[4] + t for t in range(3)]
    sparsity = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(r0 + 3 * a, starts[5]))
    ext0 = case.exterior0.copy()
    ext0[:, :3] -= origin
    x0 = np.concatenate([ext0.ravel(), (case.points0 - origin).ravel(), np.zeros(6 * g + 3)])
    res = least_squares(fun, x0, jac_sparsity=sparsity, method="trf", x_scale="jac",
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200,
                        tr_options={"atol": 1e-14, "btol": 1e-14})
    ext, pts, shift, drift, bore = unpack(res.x)
    ext = ext.reshape(n, 6).copy()
    ext[:, :3] += origin
    return ext, shift.reshape(g, 3), drift.reshape(g, 3), bore, 2 * res.cost


def test_same_result_as_scipy_least_squares_with_gnss_drift_and_boresight(case):
    block = _block(case, shift=True, drift=True, imu=True, control=4, seed=3)
    sol = _adjust(case, block)
    ext, shift, drift, bore, ssq = _reference(case, block)
    assert np.abs(sol.exterior[:, :3] - ext[:, :3]).max() < 1e-4
    # 1e-7 rad moves a ground point 0.1 mm at 1 km, the centres' 1e-4 m (scipy 1.17 stops ~1.4e-8
    # rad from ours in omega and the boresight omega, correlated; the same sum of squares below)
    assert np.abs(angle_diff(sol.exterior[:, 3:], ext[:, 3:])).max() < 1e-7
    assert np.abs(sol.gnss_shift - shift).max() < 1e-4
    assert np.abs(sol.gnss_drift - drift).max() < 1e-5
    assert np.abs(sol.boresight - bore).max() < 1e-7  # correlated with omega: same bound
    assert sol.sigma0 ** 2 * sol.redundancy == pytest.approx(ssq, rel=1e-7)


def test_attitude_jacobians_match_central_differences():
    from toolbox.triangulation.solver import attitude_residuals

    rng = np.random.default_rng(2)
    angles = rng.normal(0, 0.3, (6, 3))
    angles[::2, 2] += np.pi * 0.9
    bore = np.array([0.01, -0.02, 0.03])
    obs = rng.normal(0, 0.3, (6, 3))
    _, j_ang, j_bore = attitude_residuals(angles, bore, obs, jacobians=True)
    h = 1e-6
    for t in range(3):
        step = np.eye(3)[t] * h
        num = (attitude_residuals(angles + step, bore, obs)
               - attitude_residuals(angles - step, bore, obs)) / (2 * h)
        assert np.abs(num - j_ang[:, :, t]).max() < 1e-7
        num = (attitude_residuals(angles, bore + step, obs)
               - attitude_residuals(angles, bore - step, obs)) / (2 * h)
        assert np.abs(num - j_bore[:, :, t]).max() < 1e-7


def test_imu_blunder_is_found_by_data_snooping_and_removed(case):
    """A 40-sigma error on one photo's IMU kappa (2 mrad at 0.05 mrad): the w-test flags that
    very observation, the adjustment is repeated without it and the boresight comes back."""
    block = _block(case, imu=True, control=6)
    blunder_photo = 3
    block.attitude_obs[blunder_photo, 2] += 40 * IMU_SIGMA
    sol = adjust(block, case.exterior0, case.points0, Options())
    attitude = [rj for rj in sol.rejections if rj.kind == "attitude"]
    assert [(rj.index, rj.component) for rj in attitude] == [(blunder_photo, 2)]
    assert abs(attitude[0].w) > 10
    # the estimated error -v/r (Baarda) is the inserted one
    assert -attitude[0].residual / attitude[0].redundancy == pytest.approx(40 * IMU_SIGMA,
                                                                           abs=5 * IMU_SIGMA)
    assert not sol.attitude_active[blunder_photo, 2] and sol.attitude_active.sum() == \
        3 * block.n_photos - 1
    assert (np.abs(sol.boresight - BORESIGHT) < 4 * sol.boresight_std).all()
    assert np.nanmax(np.abs(sol.attitude_w)) < 3.29  # nothing left over the critical value
