"""Self-calibration of a digital Brown camera (f, cx, cy, k1, k2, p1, p2; pixel observations)
on a block rendered with OpenCV's projectPoints (:mod:`brown_block`): the adjustment recovers the
perturbed camera within its own standard deviations, agrees with scipy's least_squares on the
same observations written with OpenCV's projection, and orientation:bundle writes the Brown
camera into the project YAML, from which the adjusted photos project as OpenCV does."""

import csv

import numpy as np
import pytest
import scipy.sparse as sp
import yaml
from brown_block import NOMINAL, SIZE, TRUE, make_brown_block, project
from scipy.optimize import least_squares

from toolbox.triangulation.adjust import adjust
from toolbox.triangulation.approximations import from_exteriors
from toolbox.triangulation.block import FIXED, FREE, Block, Options

FREE_TERMS = [0, 1, 2, 3, 4, 6, 7]  # f, cx, cy, k1, k2, p1, p2 (k3 fixed at 0)
SIGMA_PX = 0.3


@pytest.fixture(scope="module")
def case():
    b = make_brown_block(SIGMA_PX)
    modes = np.full((1, 8), FIXED)
    modes[0, FREE_TERMS] = FREE
    block = Block(b.photo_ids, np.zeros(len(b.photo_ids)), ["drone"], NOMINAL, b.point_ids,
                  b.obs_photo, b.obs_point, b.px, np.full((len(b.px), 2), SIGMA_PX), modes,
                  None, b.control, b.points[b.control], np.full((len(b.control), 3), 0.01),
                  camera_kind=[1], camera_aspect=[1.0])
    rng = np.random.default_rng(5)
    ext0 = b.exterior + np.column_stack([rng.normal(0, 1.0, (len(b.exterior), 3)),
                                         rng.normal(0, 0.01, (len(b.exterior), 3))])
    return b, block, ext0, from_exteriors(block, ext0)


def test_self_calibration_recovers_the_perturbed_brown_camera(case):
    b, block, ext0, pts0 = case
    sol = adjust(block, ext0, pts0, Options())
    assert 0.85 < sol.sigma0 < 1.15
    cal, std = sol.calibration[0], sol.calibration_std[0]
    z = (cal[FREE_TERMS] - TRUE[FREE_TERMS]) / std[FREE_TERMS]
    assert np.abs(z).max() < 4, z
    # really determined, not just loosely: f to 0.1 %, k1 to 1 % of its value, p1/p2 to 1e-4
    assert std[0] < 3.0 and std[3] < 8e-4 and std[6:8].max() < 1e-4
    assert abs(cal[0] - NOMINAL[0]) > 10 * std[0]  # it moved away from the nominal 2950
    d = sol.exterior[:, :3] - b.exterior[:, :3]
    assert (np.abs(d) < 4 * sol.exterior_std[:, :3]).all()


def _scipy_reference(case):
    """The same weighted problem with OpenCV's projection, solved by scipy."""
    b, block, ext0, pts0 = case
    n, p = len(b.photo_ids), len(b.point_ids)
    origin = np.round(pts0.mean(axis=0))
    g = np.array(b.control)
    by_photo = [np.flatnonzero(b.obs_photo == j) for j in range(n)]

    def unpack(x):
        cal = NOMINAL.copy()
        cal[FREE_TERMS] = x[-len(FREE_TERMS):]
        return x[:6 * n].reshape(n, 6), x[6 * n:6 * n + 3 * p].reshape(p, 3), cal

    def fun(x):
        ext, pts, cal = unpack(x)
        res = np.empty((len(b.px), 2))
        for j, rows in enumerate(by_photo):
            res[rows] = project(cal, ext[j], pts[b.obs_point[rows]]) - b.px[rows]
        ground = (pts[g] + origin - b.points[g]) / 0.01
        return np.concatenate([(res / SIGMA_PX).ravel(), ground.ravel()])

    m = len(b.px)
    rows = np.repeat(np.arange(2 * m), 9 + len(FREE_TERMS))
    cols = np.concatenate([np.r_[6 * b.obs_photo[i] + np.arange(6),
                                 6 * n + 3 * b.obs_point[i] + np.arange(3),
                                 6 * n + 3 * p + np.arange(len(FREE_TERMS))]
                           for i in range(m) for _ in range(2)])
    gr = 2 * m + np.arange(3 * len(g))
    gc = 6 * n + 3 * np.repeat(g, 3) + np.tile(np.arange(3), len(g))
    sparsity = sp.coo_matrix((np.ones(len(rows) + len(gr)), (np.r_[rows, gr], np.r_[cols, gc])),
                             shape=(2 * m + len(gr), 6 * n + 3 * p + len(FREE_TERMS)))
    e0 = ext0.copy()
    e0[:, :3] -= origin
    x0 = np.concatenate([e0.ravel(), (pts0 - origin).ravel(), NOMINAL[FREE_TERMS]])
    res = least_squares(fun, x0, jac_sparsity=sparsity, method="trf", x_scale="jac",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=100)
    ext, pts, cal = unpack(res.x)
    ext = ext.copy()
    ext[:, :3] += origin
    return ext, pts + origin, cal, 2 * res.cost


def test_same_brown_solution_as_scipy_least_squares_with_opencvs_projection(case):
    b, block, ext0, pts0 = case
    sol = adjust(block, ext0, pts0, Options(snooping=False))
    ext, pts, cal, ssq = _scipy_reference(case)
    assert sol.sigma0 ** 2 * sol.redundancy == pytest.approx(ssq, rel=1e-5)
    # within 5 % of the adjustment's own standard deviations (measured: <= 2.1 %, the finite
    # differences of scipy's Jacobian stopping it that close)
    assert (np.abs(sol.calibration[0] - cal)[FREE_TERMS]
            < 0.05 * sol.calibration_std[0][FREE_TERMS]).all()
    assert (np.abs(sol.exterior[:, :3] - ext[:, :3]) < 0.05 * sol.exterior_std[:, :3]).all()
    assert np.abs(sol.points - pts).max() < 1e-3


def _write(path, rows):
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return path


def test_bundle_writes_the_brown_camera_that_the_project_reads_back(case, tmp_path):
    from toolbox.photogrammetry.project import load_project

    b = case[0]
    spec = {"type": "brown", "im_size": list(SIZE), "focal_len": float(NOMINAL[0] / max(SIZE))}
    out = _model_run(case, tmp_path, spec, SELF_CALIBRATION="f, cx, cy, k1, k2, p1, p2")
    assert 0.85 < out["STATISTICS"]["sigma0"] < 1.15
    written = yaml.safe_load((tmp_path / "out.yaml").read_text())["cameras"][0]["model"]
    assert written["type"] == "brown" and {"k3", "p1", "p2"} <= set(written)
    loaded = load_project(tmp_path / "out.yaml")
    cam = loaded.cameras["cam"]
    assert abs(cam.focal_px[0] - TRUE[0]) < 5 and abs(cam.coefficients["k1"] - TRUE[3]) < 3e-3
    # the adjusted photos, as the product reads them, project ground points as OpenCV does with
    # the adjusted values (the reader's conventions agree with the bundle's)
    adjusted = np.array([cam.focal_px[0], *cam.principal_point_px,
                         *(cam.coefficients[k] for k in ("k1", "k2", "k3", "p1", "p2"))])
    for j, pid in enumerate(b.photo_ids[:3]):
        ground = b.points[b.obs_point[b.obs_photo == j]]  # points inside the photo
        photo = loaded.photos[pid]
        e = photo.exterior
        seen = photo.ground_to_pixel(ground, behind="nan")
        ref = project(adjusted, np.r_[e.centre, e.omega, e.phi, e.kappa], ground)
        ok = np.isfinite(seen[:, 0])
        assert ok.all() and np.abs(seen - ref).max() < 1e-5


def _model_run(case, tmp_path, spec, **extra):
    import toolbox

    b, block, ext0, _ = case
    doc = {"format": "orientation-project", "version": 1, "crs": "EPSG:3003",
           "cameras": [{"name": "cam", "model": spec}],
           "photos": [{"id": pid, "camera": "cam", "exterior": dict(zip(
               ("X0", "Y0", "Z0", "omega", "phi", "kappa"), map(float, ext0[j]), strict=True))}
               for j, pid in enumerate(b.photo_ids)]}
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    _write(tmp_path / "obs.csv", [["point_id", "photo", "col_px", "row_px"]] + [
        [b.point_ids[k], b.photo_ids[j], x, y]
        for j, k, (x, y) in zip(b.obs_photo, b.obs_point, b.px, strict=True)])
    _write(tmp_path / "control.csv", [["id", "X", "Y", "Z"]] + [
        [b.point_ids[k], *b.points[k]] for k in b.control])
    return toolbox.run("orientation:bundle", {
        "PROJECT": tmp_path / "p.yaml", "INPUT": tmp_path / "obs.csv", "SIGMA_PX": SIGMA_PX,
        "CONTROL": tmp_path / "control.csv", "CONTROL_SIGMA_XY": 0.01, "CONTROL_SIGMA_Z": 0.01,
        "START": "project", "OUTPUT": tmp_path / "out.yaml", "REPORT": tmp_path / "r.json",
        **extra})


def test_an_opencv_model_camera_is_adjusted_with_its_interior_fixed(case, tmp_path):
    """The block rendered by cv2.projectPoints with the true camera, declared as an opencv
    model (k4-k6 = 0, the same projection): the bundle through Intrinsics.camera_to_pixel
    (numerical derivatives) gives sigma0 ~ 1 and the true centres within 4 sigma; asking to
    self-calibrate it is a one-line error."""
    import json

    from toolbox.errors import ToolboxError
    from toolbox.photogrammetry.project import load_project

    b = case[0]
    f, cx, cy, k1, k2, k3, p1, p2 = map(float, TRUE)
    s = float(max(SIZE))
    spec = {"type": "opencv", "im_size": list(SIZE), "focal_len": f / s,
            "cx": (cx - SIZE[0] / 2) / s, "cy": (cy - SIZE[1] / 2) / s, "k1": k1, "k2": k2,
            "k3": k3, "p1": p1, "p2": p2}
    out = _model_run(case, tmp_path, spec)
    assert 0.85 < out["STATISTICS"]["sigma0"] < 1.15
    report = {p["photo"]: p for p in json.loads((tmp_path / "r.json").read_text())["photos"]}
    adjusted = load_project(tmp_path / "out.yaml")
    assert adjusted.cameras["cam"].kind == "opencv"
    for j, pid in enumerate(b.photo_ids):
        d = adjusted.photos[pid].exterior.centre - b.exterior[j, :3]
        std = np.array([report[pid][k] for k in ("std_X0", "std_Y0", "std_Z0")])
        assert (np.abs(d) < 4 * std).all() and std.max() < 0.1, (pid, d, std)
    with pytest.raises(ToolboxError, match="SELF_CALIBRATION.*opencv model.*held fixed") as info:
        _model_run(case, tmp_path / "x" if (tmp_path / "x").mkdir() is None else None, spec,
                   SELF_CALIBRATION="f")
    assert "\n" not in str(info.value)


def test_a_fisheye_camera_block_rendered_by_opencv_is_adjusted(case, tmp_path):
    """The same block's points re-imaged by cv2.fisheye.projectPoints (k1-k4 = 0.03, -0.01,
    0.002, 0), 0.3 px noise: the bundle through the product's fisheye model (held fixed)
    gives sigma0 ~ 1 and the true centres within 4 sigma."""
    import json

    import cv2

    from toolbox.photogrammetry.project import load_project
    from toolbox.triangulation.model import rotations

    b = case[0]
    f, cx, cy = map(float, TRUE[:3])
    dist = np.array([0.03, -0.01, 0.002, 0.0])
    k = np.array([[f, 0, cx - 0.5], [0, f, cy - 0.5], [0, 0, 1.0]])
    rng = np.random.default_rng(8)
    px = np.empty_like(b.px)
    for j, e in enumerate(b.exterior):
        on = np.flatnonzero(b.obs_photo == j)
        r_cv = np.diag([1.0, -1.0, -1.0]) @ rotations(e[None, 3:])[0][0].T
        rvec, _ = cv2.Rodrigues(r_cv)
        tvec = -r_cv @ (e[:3] - b.points[0])
        pts = (b.points[b.obs_point[on]] - b.points[0])[:, None, :]
        out, _ = cv2.fisheye.projectPoints(pts, rvec, tvec, k, dist)
        px[on] = out.reshape(-1, 2) + 0.5 + rng.normal(0, SIGMA_PX, (len(on), 2))
    fisheye_case = (type(b)(**{**b.__dict__, "px": px}),) + tuple(case[1:])
    s = float(max(SIZE))
    spec = {"type": "fisheye", "im_size": list(SIZE), "focal_len": f / s,
            "cx": (cx - SIZE[0] / 2) / s, "cy": (cy - SIZE[1] / 2) / s,
            **dict(zip(("k1", "k2", "k3", "k4"), map(float, dist), strict=True))}
    out = _model_run(fisheye_case, tmp_path, spec)
    assert 0.85 < out["STATISTICS"]["sigma0"] < 1.15
    report = {p["photo"]: p for p in json.loads((tmp_path / "r.json").read_text())["photos"]}
    adjusted = load_project(tmp_path / "out.yaml")
    for j, pid in enumerate(b.photo_ids):
        d = adjusted.photos[pid].exterior.centre - b.exterior[j, :3]
        std = np.array([report[pid][k] for k in ("std_X0", "std_Y0", "std_Z0")])
        assert (np.abs(d) < 4 * std).all() and std.max() < 0.1, (pid, d, std)
