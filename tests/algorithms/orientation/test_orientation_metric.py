"""Metric fidelity: resection, absolute orientation and the orientation check, on known truth.

The image measurements here are made with an implementation independent of the toolbox's
kernels: the brief's collinearity formula (section 4) with scipy's rotation (R = Rx(ω)·Ry(φ)·Rz(κ))
and the fiducial -> pixel matrices *printed* in the Siena reports (interior_reports.csv). The
end-to-end check must fail for each of the mutations a local-Jacobian test cannot see: the
interior-orientation origin shifted by 100 px, the principal point by 1 mm, the projection centre
by 10 m.
"""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import toolbox
from toolbox.errors import InputDataError
from toolbox.photogrammetry.absolute import fit_similarity
from toolbox.photogrammetry.accuracy import (
    judge_photo_scale,
    planimetric_tolerance_m,
)
from toolbox.photogrammetry.project import load_project, save_project
from toolbox.photogrammetry.resection import resect

SIENA = Path(__file__).resolve().parents[3] / "toolbox" / "demo" / "data" / "siena"
STRIP1 = ("1_7150", "1_7151", "1_7152")
NOISE_PX = 0.3
CHECK_POINTS = {"ptc_007-2_7140", "ptc_002-1_7151"}


def printed_f2p() -> dict[str, np.ndarray]:
    """Fiducial (mm) -> pixel matrices printed in the block log's IO reports."""
    out = {}
    with open(SIENA / "interior_reports.csv", newline="") as f:
        for r in csv.DictReader(f):
            if r["source"] == "log_block":
                out[r["photo"]] = np.array([[float(r[f"f2p_{i}{j}"]) for j in (1, 2, 3)]
                                            for i in (1, 2, 3)])
    return out


def block_control() -> dict[str, np.ndarray]:
    with open(SIENA / "control_points.csv", newline="") as f:
        return {r["id"]: np.array([float(r["X"]), float(r["Y"]), float(r["Z"])])
                for r in csv.DictReader(f) if r["record"] == "coordinates" and r["run"] == "block"}


def independent_pixels(ground: np.ndarray, eo, c_mm: float, f2p: np.ndarray) -> np.ndarray:
    """Brief section 4 (ξ0 = η0 = 0, no distortion) and the printed fiducial -> pixel matrix."""
    r = Rotation.from_euler("XYZ", [eo.omega, eo.phi, eo.kappa]).as_matrix()
    d = (ground - [eo.x0, eo.y0, eo.z0]) @ r  # rows: Rᵀ (P - C)
    xi, eta = -c_mm * d[:, 0] / d[:, 2], -c_mm * d[:, 1] / d[:, 2]
    h = np.column_stack([xi, eta, np.ones_like(xi)]) @ f2p.T
    return h[:, :2] / h[:, 2:3]


@pytest.fixture(scope="module")
def siena_inputs(tmp_path_factory):
    """Measurements of the 8 block control points on the strip-1 photos (0.3 px noise) and the
    control file (2 check points)."""
    folder = tmp_path_factory.mktemp("metric")
    project = load_project(SIENA / "siena_project.yaml")
    f2p = printed_f2p()
    control = block_control()
    ids = list(control)
    xyz = np.array([control[i] for i in ids])
    rng = np.random.default_rng(17)
    rows = []
    for pid in STRIP1:
        photo = project.photos[pid]
        px = independent_pixels(xyz, photo.exterior, photo.camera.c, f2p[pid])
        inside = ((px > 300) & (px < 16300)).all(axis=1)
        px = px + rng.normal(0, NOISE_PX, px.shape)
        rows += [[i, pid, *p] for i, p, ok in zip(ids, px, inside, strict=True) if ok]
    measurements = folder / "measurements.csv"
    with open(measurements, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["point_id", "photo", "col_px", "row_px"])
        w.writerows(rows)
    control_csv = folder / "control.csv"
    with open(control_csv, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "X", "Y", "Z", "role"])
        for i in ids:
            w.writerow([i, *control[i], "check" if i in CHECK_POINTS else "control"])
    return {"folder": folder, "project": SIENA / "siena_project.yaml",
            "measurements": measurements, "control": control_csv, "rows": rows}


def run_check(inputs, project_path, name):
    report = inputs["folder"] / f"{name}.json"
    out = toolbox.run("orientation:check", {
        "PROJECT": project_path, "INPUT": inputs["measurements"], "CONTROL": inputs["control"],
        "THRESHOLD_PX": 1.5, "MAP_SCALE": 5000, "REPORT": report,
        "OUTPUT": inputs["folder"] / f"{name}.gpkg"}, overwrite=True)
    return out["STATISTICS"], json.loads(report.read_text())


def test_check_recovers_the_measuring_noise(siena_inputs):
    stats, report = run_check(siena_inputs, siena_inputs["project"], "truth")
    rms_px = np.sqrt(np.mean([o["res_px"] ** 2 for o in report["observations"]]))
    # 0.3 px per coordinate: expected radial RMS 0.42 px (2 degrees of freedom)
    assert 0.25 < rms_px < 0.6
    assert stats["flagged"] == 0
    assert report["residual_sign"] == "computed minus observed"
    # intersected from 2-3 rays of 0.3 px (4 µm, ~1.6 cm on the ground at 1:3800)
    assert stats["check_rmse_xy_m"] < 0.1 and stats["check_rmse_z_m"] < 0.3
    assert report["judgement"]["passes"]
    assert report["judgement"]["tolerance_m"] == pytest.approx(2.5)  # 0.5 mm at 1:5000


def test_residual_sign_is_computed_minus_observed(siena_inputs):
    _, report = run_check(siena_inputs, siena_inputs["project"], "sign")
    project = load_project(siena_inputs["project"])
    measured = {(r[0], r[1]): np.array(r[2:4], float) for r in siena_inputs["rows"]}
    obs = report["observations"][0]
    photo = project.photos[obs["photo"]]
    computed = photo.ground_to_pixel(np.array([obs["xyz"]]))[0]
    v_px = computed - measured[(obs["point_id"], obs["photo"])]
    v_um = photo.pixel_transform.pixel_to_image(computed[None])[0] - \
        photo.pixel_transform.pixel_to_image(computed[None] - v_px)[0]
    assert np.allclose([obs["res_x_um"], obs["res_y_um"]], v_um * 1e3, atol=1e-3)


def mutated_project(folder: Path, name: str, edit) -> Path:
    project = load_project(SIENA / "siena_project.yaml")
    photos = dict(project.photos)
    cameras = dict(project.cameras)
    for pid in STRIP1:
        photos[pid] = edit(photos[pid])
        cameras[photos[pid].camera.name] = photos[pid].camera
    path = folder / f"{name}.yaml"
    save_project(replace(project, photos=photos, cameras=cameras), path, relative_images=False)
    return path


def _shift_io(photo):
    io = photo.interior
    p2f = np.array(io.pixel_to_fiducial)
    shift = np.array([[1, 0, -100.0], [0, 1, 0], [0, 0, 1]])  # origin moved 100 px
    return replace(photo, interior=replace(io, pixel_to_fiducial=p2f @ shift))


def _shift_pp(photo):
    return replace(photo, camera=replace(photo.camera, principal_point_mm=(1.0, 0.0)))


def _shift_centre(photo):
    eo = photo.exterior
    return replace(photo, exterior=replace(eo, x0=eo.x0 + 10.0))


@pytest.mark.parametrize("name, edit", [("io_origin_100px", _shift_io),
                                        ("principal_point_1mm", _shift_pp),
                                        ("centre_10m", _shift_centre)])
def test_end_to_end_check_has_teeth(siena_inputs, name, edit):
    path = mutated_project(siena_inputs["folder"], name, edit)
    stats, report = run_check(siena_inputs, path, name)
    rms_px = np.sqrt(np.mean([o["res_px"] ** 2 for o in report["observations"]]))
    assert rms_px > 10, f"{name}: the chain did not notice (RMS {rms_px:.2f} px)"
    assert stats["flagged"] > 0


def test_resection_recovers_the_printed_orientation(tmp_path):
    """12 synthetic ground points per strip-1 photo (independent projection, 0.3 px noise):
    the resected orientations equal the printed ones within 4 standard deviations."""
    project = load_project(SIENA / "siena_project.yaml")
    f2p = printed_f2p()
    rng = np.random.default_rng(11)
    rows, ground_rows = [], []
    for pid in STRIP1:
        photo = project.photos[pid]
        eo = photo.exterior
        xyz = np.column_stack([eo.x0 + rng.uniform(-800, 800, 120), eo.y0 + rng.uniform(-800, 800, 120),
                               rng.uniform(250, 420, 120)])
        px = independent_pixels(xyz, eo, photo.camera.c, f2p[pid])
        on = ((px >= 0) & (px <= photo.camera.image_size_px)).all(axis=1)  # measurable points
        xyz = xyz[on][:12]
        px = px[on][:12] + rng.normal(0, NOISE_PX, (12, 2))
        for k, (p, g) in enumerate(zip(px, xyz, strict=True)):
            rows.append(f"{pid}_g{k},{pid},{p[0]},{p[1]}\n")
            ground_rows.append(f"{pid}_g{k},{g[0]},{g[1]},{g[2]}\n")
    (tmp_path / "m.csv").write_text("point_id,photo,col_px,row_px\n" + "".join(rows))
    (tmp_path / "c.csv").write_text("id,X,Y,Z\n" + "".join(ground_rows))
    out, report = tmp_path / "resected.yaml", tmp_path / "resection.json"
    toolbox.run("orientation:resection", {
        "PROJECT": SIENA / "siena_project.yaml", "INPUT": tmp_path / "m.csv",
        "CONTROL": tmp_path / "c.csv", "OUTPUT": out, "REPORT": report})
    fitted = load_project(out)
    doc = json.loads(report.read_text())
    for pid in STRIP1:
        t, f = project.photos[pid].exterior, fitted.photos[pid].exterior
        std = doc["photos"][pid]["std"]
        err = np.array([f.x0 - t.x0, f.y0 - t.y0, f.z0 - t.z0, f.omega - t.omega,
                        f.phi - t.phi, f.kappa - t.kappa])
        sig = np.array([std[k] for k in ("X0", "Y0", "Z0", "omega", "phi", "kappa")])
        assert np.all(np.abs(err) < 4 * sig), (pid, err / sig)
        assert np.all(sig[:3] < 0.5)  # decimetre-level centre from 12 points at 0.3 px
        # 0.3 px = 4.2 µm per coordinate
        assert 2.0 < doc["photos"][pid]["sigma0_um"] < 7.0
    # the photos not measured keep their orientation
    assert fitted.photos["2_7139"].exterior == replace(project.photos["2_7139"].exterior,
                                                       crs=fitted.crs)


def test_resection_monte_carlo_within_covariance():
    """Synthetic vertical photo, 12 points over 150 m of relief, 3 µm noise: the normalised
    errors of the six parameters over 40 trials have unit spread (covariance is honest)."""
    rng = np.random.default_rng(5)
    truth = np.array([1_688_000.0, 4_799_500.0, 1500.0, 0.02, -0.015, 1.2])
    c = 150.0
    ground = np.column_stack([truth[0] + rng.uniform(-700, 700, 12),
                              truth[1] + rng.uniform(-700, 700, 12), rng.uniform(200, 350, 12)])
    r = Rotation.from_euler("XYZ", truth[3:]).as_matrix()
    d = (ground - truth[:3]) @ r
    ideal = -c * d[:, :2] / d[:, 2:3]
    z = []
    for _ in range(40):
        fit = resect(ideal + rng.normal(0, 0.003, ideal.shape), ground, c)
        z.append((fit.parameters - truth) / fit.std)
    z = np.array(z)
    assert np.all(np.abs(z.mean(axis=0)) < 0.6)
    assert np.all((0.6 < z.std(axis=0)) & (z.std(axis=0) < 1.5))


def test_resection_refuses_too_few_and_collinear_points():
    ground = np.array([[0, 0, 0], [100, 0, 0], [0, 100, 0]], float)
    with pytest.raises(InputDataError, match="at least 4"):
        resect(np.zeros((3, 2)), ground, 150.0)
    line = np.column_stack([np.linspace(0, 500, 6), np.linspace(0, 500, 6) * 0.5, np.zeros(6)])
    cam = np.column_stack([np.linspace(-50, 50, 6), np.linspace(-25, 25, 6)])
    with pytest.raises(InputDataError, match="collinear"):
        resect(cam, line, 150.0)


def umeyama(model: np.ndarray, ground: np.ndarray):
    """Independent closed form (Umeyama 1991) with numpy's SVD."""
    mm, mg = model.mean(0), ground.mean(0)
    a, b = model - mm, ground - mg
    u, s, vt = np.linalg.svd(b.T @ a / len(a))
    d = np.diag([1, 1, np.sign(np.linalg.det(u @ vt))])
    rot = u @ d @ vt
    scale = np.trace(np.diag(s) @ d) / (a ** 2).sum(1).mean()
    return scale, rot, mg - scale * rot @ mm


def test_absolute_orientation_matches_umeyama_and_recovers_truth():
    rng = np.random.default_rng(3)
    model = rng.uniform(-50, 50, (9, 3))
    rot = Rotation.from_euler("XYZ", [0.1, -0.2, 2.5]).as_matrix()
    ground = 7.5 * model @ rot.T + [1_688_000.0, 4_799_500.0, 300.0]
    fit = fit_similarity(model, ground)
    assert fit.scale == pytest.approx(7.5, rel=1e-10)
    assert np.allclose(fit.rotation, rot, atol=1e-10)
    assert np.allclose(fit.apply(model), ground, atol=1e-6)
    noisy = ground + rng.normal(0, 0.05, ground.shape)
    fit = fit_similarity(model, noisy)
    scale, r_u, t_u = umeyama(model, noisy)
    assert fit.scale == pytest.approx(scale, rel=1e-6)
    assert np.allclose(fit.rotation, r_u, atol=1e-6)
    assert np.allclose(fit.translation, t_u, atol=1e-3)
    assert 0.02 < fit.sigma0 < 0.09
    assert np.allclose(fit.residuals, fit.apply(model) - noisy, atol=1e-9)  # computed - observed


def test_absolute_orientation_algorithm_reports_check_points(tmp_path):
    rng = np.random.default_rng(4)
    model = rng.uniform(-50, 50, (8, 3))
    rot = Rotation.from_euler("XYZ", [0.05, 0.02, -1.0]).as_matrix()
    ground = 2.0 * model @ rot.T + [1_688_000.0, 4_799_500.0, 300.0]
    with open(tmp_path / "model.csv", "w") as f:
        f.write("id,X,Y,Z\n" + "".join(f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(model)))
    with open(tmp_path / "control.csv", "w") as f:
        f.write("id,X,Y,Z,role\n" + "".join(
            f"p{k},{x},{y},{z + (0.2 if k == 7 else 0)},{'check' if k >= 6 else 'control'}\n"
            for k, (x, y, z) in enumerate(ground)))
    out = toolbox.run("orientation:absolute", {
        "INPUT": tmp_path / "model.csv", "CONTROL": tmp_path / "control.csv", "CRS": "EPSG:3003",
        "OUTPUT": tmp_path / "abs.gpkg", "REPORT": tmp_path / "abs.json"})
    stats = out["STATISTICS"]
    assert stats["control_points"] == 6 and stats["sigma0"] < 1e-6
    # the check point p7 was surveyed 0.2 m high: it shows there, and only there
    assert stats["check_rmse_xyz"][2] == pytest.approx(0.2 / np.sqrt(2), abs=1e-6)


def test_map_scale_rules():
    assert planimetric_tolerance_m(5000) == pytest.approx(2.5)    # 0.5 mm, large scale
    assert planimetric_tolerance_m(10000) == pytest.approx(3.0)   # 0.3 mm, small scale
    assert judge_photo_scale(15000, 5000)["passes"]               # Table 3: 1:12,000-18,000
    assert not judge_photo_scale(25000, 5000)["passes"]


def test_relief_rule_applies_at_the_map_scale():
    """1:15,000 photos (c = 150 mm, H = 2250 m) for a 1:5000 map: Table 4's 1:5000 column
    allows 7.5 m at 100 mm from the centre; the photo scale alone would allow 22.5 m."""
    from toolbox.transforms.relief import relief_check

    at_map = relief_check(150.0, 2250.0, 16.0, edge_radius=100.0, map_scale=5000)
    assert at_map.allowed_departure_m == pytest.approx(7.5)
    assert not at_map.flat_enough and at_map.rule_scale_number == 5000
    assert at_map.displacement_rule_mm == pytest.approx(8.0 * 100 / 150 * 1000 / 5000)
    assert relief_check(150.0, 2250.0, 14.0, edge_radius=100.0, map_scale=5000).flat_enough
    at_photo = relief_check(150.0, 2250.0, 16.0, edge_radius=100.0)
    assert at_photo.allowed_departure_m == pytest.approx(22.5) and at_photo.flat_enough


def test_footprints_flag_the_flight_design_rules(tmp_path):
    """Siena: forward overlaps 70-77 %, side overlaps >= 28 %, photos 1:3,770. They pass the
    thesis' 60 % / 20 % and Table 3 for 1:5000; raised minimums flag exactly the short pairs."""
    import pyogrio

    project = SIENA / "siena_project.yaml"
    ok = toolbox.run("orientation:footprints", {
        "PROJECT": project, "MEAN_HEIGHT": 320, "MAP_SCALE": 5000,
        "OUTPUT": tmp_path / "ok.gpkg"})["STATISTICS"]
    assert ok["design"]["passes"] and ok["partial_footprints"] == 0
    strict = toolbox.run("orientation:footprints", {
        "PROJECT": project, "MEAN_HEIGHT": 320, "FORWARD_OVERLAP": 75, "SIDE_OVERLAP": 100,
        "OUTPUT": tmp_path / "strict.gpkg"})["STATISTICS"]
    fp = pyogrio.read_dataframe(tmp_path / "strict.gpkg", layer="footprints")
    short = fp[fp["forward_overlap_pct"] < 75]["photo"].tolist()
    assert short and sorted(fp[fp["forward_ok"] == False]["photo"]) == sorted(short)  # noqa: E712
    assert (fp["side_ok"] == False).all()  # noqa: E712 - nothing overlaps 100 %
    assert len(strict["design"]["failures"]) == len(short) + len(fp)


# S000 l.653-659: σXY / σZ per base ratio B/Z, in the row's unit (metres per unit)
RULES_TABLE = {50000: (1.0, [(0.36, 0.25), (0.43, 0.75), (0.90, 2.50), (1.70, 5.00)]),
               10000: (0.1, [(0.72, 0.50), (0.86, 1.5), (1.81, 5.00), (3.41, 10.00)]),
               1000: (0.01, [(0.72, 0.50), (0.86, 1.5), (1.81, 5.00), (3.41, 10.00)]),
               100: (0.001, [(0.72, 0.50), (0.86, 1.5), (1.81, 5.00), (3.41, 10.00)]),
               25: (0.001, [(0.18, 0.13), (0.22, 0.38), (0.45, 1.25), (0.85, 2.50)])}


@pytest.mark.parametrize("scale", list(RULES_TABLE))
def test_precision_reproduces_both_columns_of_the_rules_table(scale):
    from algorithms.orientation.precision import pair_precision

    unit, rows = RULES_TABLE[scale]
    c = 150.0
    distance = scale * c / 1000.0
    for ratio, (sxy, sz) in zip((1, 3, 10, 20), rows, strict=True):
        r = pair_precision(c, distance / ratio, distance, 5.0, None, 115.0, 115.0)
        # printed to 2 decimals (25: 0.13 is 0.125 rounded up)
        assert r["sigma_z_m"] / unit == pytest.approx(sz, abs=0.006)
        assert r["sigma_xy_table_m"] / unit == pytest.approx(sxy, abs=0.011)
        # the per-axis centre figure is what a reader must not confuse with it (about half)
        assert r["sigma_x_centre_m"] < 0.6 * r["sigma_xy_table_m"]
