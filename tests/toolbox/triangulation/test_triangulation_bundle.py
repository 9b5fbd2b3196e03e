"""Bundle adjustment of synthetic 2 x 4 blocks (60/25 % overlap, hilly terrain, film in mm and
digital in pixels, Gaussian noise of known sigma): truth, predicted precision, an independent
scipy solver, blunders and self-calibration."""

import numpy as np
import pytest
import scipy.sparse as sp
from block_cases import angle_diff, build_case
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from toolbox.triangulation.adjust import adjust
from toolbox.triangulation.block import Options
from toolbox.triangulation.synthetic import SyntheticBlockSpec


@pytest.fixture(scope="session")
def film_case():
    return build_case(SyntheticBlockSpec(digital=False, seed=2), n_control=6, checks=(1,))


@pytest.fixture(scope="session")
def digital_case():
    return build_case(SyntheticBlockSpec(digital=True, seed=1), n_control=6, checks=(1,))



def _errors(case, sol):
    d_ext = sol.exterior - case.truth_exterior
    d_ext[:, 3:] = angle_diff(sol.exterior[:, 3:], case.truth_exterior[:, 3:])
    return d_ext, sol.points - case.truth_points


@pytest.mark.parametrize("which", ["film_case", "digital_case"])
def test_block_recovers_truth_within_its_predicted_precision(which, request):
    case = request.getfixturevalue(which)
    sol = adjust(case.block, case.exterior0, case.points0, Options())
    # no blunder in the data: at alpha0 = 0.1 % per test, ~1 false alarm in ~1200 tests, and
    # those only just above the critical value
    assert len(sol.rejections) <= 3 and all(abs(r.w) < 4.5 for r in sol.rejections)
    # sigma0 ~ 1 when the a priori sigmas are the noise's: chi-square with r ~ 400 dof
    assert 0.85 < sol.sigma0 < 1.15, sol.sigma0
    d_ext, d_pts = _errors(case, sol)
    z_ext = d_ext / sol.exterior_std
    assert np.abs(z_ext).max() < 4.0, z_ext
    # every tie point: Mahalanobis distance of its error with its own 3 x 3 covariance
    tie = np.ones(case.block.n_points, bool)
    tie[case.block.ground_point] = False
    chi = np.einsum("pi,pij,pj->p", d_pts[tie], np.linalg.inv(sol.point_cov[tie]), d_pts[tie])
    assert 0.5 < chi.mean() / 3 < 2.0
    assert np.quantile(chi, 0.99) < 25.0
    # the check point (not in the adjustment) is within 4 sigma of the truth
    check = case.control.ids[case.control.roles.index("check")]
    k = case.block.point_ids.index(check)
    assert check in case.info["checks"]
    assert (np.abs(d_pts[k]) < 4 * sol.point_std[k]).all()
    # redundancy numbers sum to the redundancy
    r = np.nansum(sol.image_r) + np.nansum(sol.ground_r)
    assert r == pytest.approx(sol.redundancy, rel=1e-6)


def _reference_solver(case):
    """The same weighted least-squares problem written plainly and handed to scipy."""
    b = case.block
    origin = np.round(case.points0.mean(axis=0))
    n, p = b.n_photos, b.n_points
    c = b.calibration[b.photo_camera, 0]
    gmask = np.isfinite(b.ground_xyz)

    def unpack(x):
        return x[:6 * n].reshape(n, 6), x[6 * n:].reshape(p, 3)

    def fun(x):
        ext, pts = unpack(x)
        rot = Rotation.from_euler("XYZ", ext[:, 3:]).as_matrix()
        d = np.einsum("mji,mj->mi", rot[b.obs_photo], pts[b.obs_point] - ext[b.obs_photo, :3])
        proj = -c[b.obs_photo, None] * d[:, :2] / d[:, 2:3]
        image = ((proj - b.obs_xy) / b.obs_sigma).ravel()
        ground = ((pts[b.ground_point] + origin - b.ground_xyz) / b.ground_sigma)[gmask]
        return np.concatenate([image, ground])

    m = len(b.obs_photo)
    rows, cols = [], []
    for i in range(m):
        for a in range(2):
            rows += [2 * i + a] * 9
            cols += list(range(6 * b.obs_photo[i], 6 * b.obs_photo[i] + 6))
            cols += list(range(6 * n + 3 * b.obs_point[i], 6 * n + 3 * b.obs_point[i] + 3))
    gi, gc = np.nonzero(gmask)
    rows += list(2 * m + np.arange(len(gi)))
    cols += list(6 * n + 3 * b.ground_point[gi] + gc)
    sparsity = sp.coo_matrix((np.ones(len(rows)), (rows, cols)),
                             shape=(2 * m + len(gi), 6 * n + 3 * p))
    ext0 = case.exterior0.copy()
    ext0[:, :3] -= origin
    x0 = np.concatenate([ext0.ravel(), (case.points0 - origin).ravel()])
    res = least_squares(fun, x0, jac_sparsity=sparsity, method="trf", x_scale="jac",
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200,
                        tr_options={"atol": 1e-14, "btol": 1e-14})
    ext, pts = unpack(res.x)
    ext = ext.copy()
    ext[:, :3] += origin
    return ext, pts + origin, 2 * res.cost


def test_same_result_as_scipy_least_squares_on_the_plain_equations(film_case):
    sol = adjust(film_case.block, film_case.exterior0, film_case.points0,
                 Options(snooping=False))
    ext, pts, ssq = _reference_solver(film_case)
    assert np.abs(sol.exterior[:, :3] - ext[:, :3]).max() < 1e-4  # m
    assert np.abs(angle_diff(sol.exterior[:, 3:], ext[:, 3:])).max() < 1e-8  # rad
    assert np.abs(sol.points - pts).max() < 1e-4
    assert sol.sigma0 ** 2 * sol.redundancy == pytest.approx(ssq, rel=1e-8)


def test_two_blunders_are_both_flagged_and_removed():
    spec = SyntheticBlockSpec(digital=True, seed=1)
    from toolbox.triangulation.synthetic import make_block

    sb = make_block(spec)
    counts = {p: sb.obs_point.count(p) for p in set(sb.obs_point)}
    # points seen on >= 6 photos: a blunder there is separable from the other rays (on a point
    # with 4 rays, 2 per strip, the w-tests of the y-coordinates are too correlated to tell)
    targets = [k for k, p in enumerate(sb.obs_point) if counts[p] >= 6]
    bad = [targets[0], targets[len(targets) // 2]]
    assert sb.obs_point[bad[0]] != sb.obs_point[bad[1]]
    xy = sb.xy.copy()
    xy[bad[0]] += (6.0, 0.0)  # 20 sigma
    xy[bad[1]] += (-3.0, 4.5)
    case = build_case(spec, n_control=6, xy=xy)
    sol = adjust(case.block, case.exterior0, case.points0, Options(robust=True))
    flagged = {r.index: abs(r.w) for r in sol.rejections if r.kind == "image"}
    assert set(bad) <= set(flagged)
    assert min(flagged[i] for i in bad) > 10.0
    assert all(w < 4.5 for i, w in flagged.items() if i not in bad)  # chance alarms only
    assert 0.85 < sol.sigma0 < 1.15
    # without them the orientations are as good as on clean data
    d_ext, _ = _errors(case, sol)
    assert np.abs(d_ext / sol.exterior_std).max() < 4.0


def test_self_calibration_recovers_principal_distance_and_k1():
    from dataclasses import replace

    from toolbox.photogrammetry.project import Project

    spec = SyntheticBlockSpec(digital=False, seed=3, distortion_k1=2e-8, relief=250.0,
                              sigma_mm=0.002)
    from toolbox.triangulation.synthetic import make_block

    truth = make_block(spec).project
    cam = truth.cameras["film"]
    wrong = replace(cam, principal_distance_mm=153.25, distortion=None)  # c off by 250 µm
    project = Project(truth.crs, {"film": wrong},
                      {k: replace(p, camera=wrong) for k, p in truth.photos.items()})
    case = build_case(spec, n_control=7, project=project, self_calibration="c, k1")
    sol = adjust(case.block, case.exterior0, case.points0, Options(snooping=False))
    c_hat, k1_hat = sol.calibration[0, 0], sol.calibration[0, 3]
    c_std, k1_std = sol.calibration_std[0, 0], sol.calibration_std[0, 3]
    assert abs(c_hat - 153.0) < 4 * c_std and c_std < 0.05, (c_hat, c_std)
    assert abs(k1_hat - 2e-8) < 4 * k1_std and k1_std < 2e-9, (k1_hat, k1_std)
    assert 0.85 < sol.sigma0 < 1.15
    # without self-calibration the same block fits badly
    case_fixed = build_case(spec, n_control=7, project=project)
    fixed = adjust(case_fixed.block, case_fixed.exterior0, case_fixed.points0,
                   Options(snooping=False))
    assert fixed.sigma0 > 1.5  # chi-square with r ~ 400: far beyond chance


def test_flat_terrain_with_free_principal_distance_is_a_near_singular_error():
    from toolbox.errors import InputDataError

    # vertical photos of flat ground: c and the flying heights trade exactly, x = -c·X/(Z - Z0)
    spec = SyntheticBlockSpec(digital=False, seed=2, relief=0.0, attitude_sigma=0.0)
    case = build_case(spec, n_control=6, self_calibration="c")
    with pytest.raises(InputDataError, match="near-singular.*weak geometry in photo .* Z0"):
        adjust(case.block, case.exterior0, case.points0, Options(snooping=False))
    # slightly tilted photos: determined, barely; a warning names the weak parameters
    spec = SyntheticBlockSpec(digital=False, seed=2, relief=0.0)
    case = build_case(spec, n_control=6, self_calibration="c")
    sol = adjust(case.block, case.exterior0, case.points0, Options(snooping=False))
    assert any(n.startswith("weak geometry") for n in sol.notes)
    assert sol.calibration_std[0, 0] > 1.0  # mm: c is not really determined


def test_divergence_reports_the_iteration_and_the_worst_observations():
    from toolbox.errors import ConvergenceError

    case = build_case(SyntheticBlockSpec(digital=False, seed=2), n_control=6)
    with pytest.raises(ConvergenceError, match=r"did not converge in 1 iterations.*worst "
                                               r"observations: .*sigma\)"):
        adjust(case.block, case.exterior0 + [30, -20, 10, 0.01, 0.01, 0.02], case.points0,
               Options(max_iterations=1))


def test_gnss_with_lever_arm_fixes_the_datum_and_is_needed():
    from toolbox.triangulation.model import rotations

    spec = SyntheticBlockSpec(digital=True, seed=1)
    lever = np.array([0.3, -0.2, 1.8])  # antenna 1.8 m above the camera
    case = build_case(spec, n_control=6)
    b = case.block
    rng = np.random.default_rng(9)
    r = rotations(case.truth_exterior[:, 3:])[0]
    b.centre_photo = np.arange(b.n_photos)
    b.centre_xyz = case.truth_exterior[:, :3] + r @ lever + rng.normal(0, 0.03, (b.n_photos, 3))
    b.centre_sigma = np.full((b.n_photos, 3), 0.03)
    b.ground_point, b.ground_xyz, b.ground_sigma = b.ground_point[:1], b.ground_xyz[:1], \
        b.ground_sigma[:1]  # one control point: GNSS carries the datum
    b.lever_arm = lever
    sol = adjust(b, case.exterior0, case.points0, Options(snooping=False))
    assert 0.85 < sol.sigma0 < 1.15
    d_ext, _ = _errors(case, sol)
    assert np.abs(d_ext / sol.exterior_std).max() < 4.0
    assert np.abs(sol.centre_residuals).max() < 4 * 0.03
    b.lever_arm = np.zeros(3)  # ignoring it leaves 1.8 m between antenna and camera
    wrong = adjust(b, case.exterior0, case.points0, Options(snooping=False))
    assert wrong.sigma0 > 1.5  # chi-square with ~600 degrees of freedom: far beyond chance


def test_sparse_control_block_starts_from_the_plane_similarity_block():
    # 3 strips x 6 photos, control only at the corners and the long sides' middles: no photo
    # sees 4 control points, the chained resections would drift; the plane block does not
    case = build_case(SyntheticBlockSpec(strips=3, photos_per_strip=6, digital=True, seed=4),
                      n_control=6)
    from toolbox.triangulation.approximations import by_resection

    ext0, pts0, notes = by_resection(case.block)
    assert any("plane similarity block" in n for n in notes)
    sol = adjust(case.block, ext0, pts0, Options(snooping=False))
    assert 0.85 < sol.sigma0 < 1.15
    d_ext, _ = _errors(case, sol)
    assert np.abs(d_ext / sol.exterior_std).max() < 4.5


def test_a_blunder_on_control_is_rejected_but_never_the_datum_itself():
    case = build_case(SyntheticBlockSpec(digital=True, seed=1), n_control=6)
    b = case.block
    b.ground_xyz = b.ground_xyz.copy()
    b.ground_xyz[5, 2] += 0.5  # 50 sigma on one height
    sol = adjust(b, case.exterior0, case.points0, Options())
    assert any(r.kind == "ground" and r.index == 5 and r.component == 2 for r in sol.rejections)
    assert 0.85 < sol.sigma0 < 1.15
    # with only the minimum control (2 XY + 3 Z), the same blunder cannot be rejected
    keep = [0, 1, 5]
    b.ground_point, b.ground_xyz, b.ground_sigma = (b.ground_point[keep], b.ground_xyz[keep],
                                                    b.ground_sigma[keep])
    sol = adjust(b, case.exterior0, case.points0, Options())
    assert not any(r.kind == "ground" for r in sol.rejections)
