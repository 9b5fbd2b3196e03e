"""Self-calibration of a film camera's k3 and decentring p1, p2 (besides c and k1) on a
synthetic block whose image points are rendered with the collinearity equations and OpenCV's
inverse of the distortion; the adjusted project, written and read back, projects check points
to their true image positions."""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from block_cases import build_case

from toolbox.photogrammetry.project import Project, load_project, save_project
from toolbox.triangulation.adjust import adjust
from toolbox.triangulation.block import Options
from toolbox.triangulation.outputs import adjusted_project
from toolbox.triangulation.synthetic import SyntheticBlockSpec, make_block

sys.path.insert(0, str(Path(__file__).parents[1] / "cameras"))
from test_film_lens_distortion import opencv_distort  # noqa: E402

TRUE = {"k1": 2e-8, "k2": 0.0, "k3": 1.5e-17, "p1": 2e-7, "p2": -1.5e-7}  # mm units
FREE = ("c", "k1", "k3", "p1", "p2")
PIXEL_MM = 0.012  # a 12 µm scan


def calibrate(sigma_mm: float, sigma_control: float, folder: Path):
    """The block with image noise ``sigma_mm`` (control weighted at ``sigma_control`` m),
    adjusted from a camera without distortion and with c 200 µm off, self-calibrating c, k1,
    k3, p1, p2; the adjusted project written to ``folder`` and read back."""
    spec = SyntheticBlockSpec(digital=False, seed=5, relief=250.0, sigma_mm=sigma_mm,
                              distortion_terms=TRUE)
    sb = make_block(spec)
    truth = sb.project
    cam = truth.cameras["film"]
    wrong = replace(cam, principal_distance_mm=153.2, distortion=None)
    project = Project(truth.crs, {"film": wrong},
                      {k: replace(p, camera=wrong) for k, p in truth.photos.items()})
    case = build_case(spec, n_control=5, checks=(1, 2), project=project,
                      self_calibration=", ".join(FREE), control_sigma_xy=sigma_control,
                      control_sigma_z=sigma_control)
    sol = adjust(case.block, case.exterior0, case.points0, Options(snooping=False))
    path = folder / "adjusted.yaml"
    save_project(adjusted_project(project, case.block, sol), path, relative_images=False)
    return spec, sb, case, sol, load_project(path)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """1 µm of image noise, control at 2 mm: the statistics."""
    return calibrate(0.001, 0.002, tmp_path_factory.mktemp("lens"))


@pytest.fixture(scope="module")
def exact(tmp_path_factory):
    """0.01 µm of image noise, control at 0.01 mm: the chain bundle -> project file -> photo
    model, free of noise."""
    return calibrate(1e-5, 1e-5, tmp_path_factory.mktemp("lens_exact"))


def test_rendering_is_independent_of_the_toolbox_distortion(calibrated):
    """The block's noise-free image points equal collinearity + OpenCV's inverse (so the
    truth below does not rest on the camera code under test)."""
    spec, sb, case, sol, _ = calibrated
    for pid in list(sb.project.photos)[:3]:
        photo = sb.project.photos[pid]
        rows = [k for k, p in enumerate(sb.obs_photo) if p == pid]
        index = {p: k for k, p in enumerate(sb.point_ids)}
        ground = sb.points[[index[sb.obs_point[k]] for k in rows]]
        d = (ground - photo.exterior.centre) @ photo.exterior.rotation
        ideal = -spec.principal_distance_mm * d[:, :2] / d[:, 2:]
        np.testing.assert_allclose(sb.true_xy[rows], opencv_distort(ideal, TRUE), atol=1e-7)


def test_bundle_recovers_k1_k3_p1_p2_within_their_sigma(calibrated):
    _, _, _, sol, _ = calibrated
    names = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2")
    truth = {"c": 153.0} | TRUE
    for name in FREE:
        i = names.index(name)
        value, std = sol.calibration[0, i], sol.calibration_std[0, i]
        assert abs(value - truth[name]) < 4 * std, (name, value, std)
        if name != "c":  # determined, not merely consistent
            assert std < 0.3 * abs(truth[name]), (name, std)
    assert 0.85 < sol.sigma0 < 1.15


def test_adjusted_project_read_back_projects_every_point_to_its_true_image_position(exact):
    """Bundle (its own correction-form model) -> project YAML -> the photo's compiled
    ground -> image kernel: the true ground points, check points included, land on their
    rendered image positions within 0.01 px (a convention that differed anywhere, e.g. p1
    and p2 swapped, would leave microns)."""
    spec, sb, case, sol, back = exact
    cam = back.cameras["film"]
    d = cam.distortion
    names = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2")
    stored = (cam.c, *cam.principal_point_mm, d.k1, d.k2, d.k3, d.p1, d.p2)
    np.testing.assert_allclose(stored, [sol.calibration[0, names.index(n)] for n in names],
                               rtol=1e-12, atol=1e-30)
    checks = set(case.info["checks"])
    assert len(checks) == 2
    index = {p: k for k, p in enumerate(sb.point_ids)}
    errors, on_checks = np.empty(len(sb.obs_point)), []
    for k, (pid, phid) in enumerate(zip(sb.obs_point, sb.obs_photo)):
        mm = back.photos[phid].ground_to_image(sb.points[index[pid]][None])
        errors[k] = np.hypot(*(mm[0] - sb.true_xy[k]))
        if pid in checks:
            on_checks.append(k)
    assert len(on_checks) >= 4
    assert errors.max() < 0.01 * PIXEL_MM, errors.max()
    # the distortion matters here: the true camera without it is more than a pixel off
    k = int(np.argmax(np.hypot(*sb.true_xy.T)))
    start = sb.project.photos[sb.obs_photo[k]]
    plain = replace(start, camera=replace(start.camera, distortion=None))
    mm = plain.ground_to_image(sb.points[index[sb.obs_point[k]]][None])
    assert np.hypot(*(mm[0] - sb.true_xy[k])) > PIXEL_MM


def test_decentring_of_a_camera_with_a_distortion_table_is_refused():
    """A table is applied to the measurements as it is; estimating p1 (or k1-k3) on top of it
    would write a polynomial the table cannot hold: a one-line parameter error."""
    from toolbox.errors import ParameterError
    from toolbox.photogrammetry.camera import RadialDistortion

    spec = SyntheticBlockSpec(digital=False, seed=5)
    truth = make_block(spec).project
    table = replace(truth.cameras["film"],
                    distortion=RadialDistortion.from_table([50.0, 100.0, 150.0], [1.0, 2.0, 0.0]))
    project = Project(truth.crs, {"film": table},
                      {k: replace(p, camera=table) for k, p in truth.photos.items()})
    with pytest.raises(ParameterError, match=r"SELF_CALIBRATION.*'film' has a distortion table; "
                                             r"k1-k3, p1, p2 can be estimated only for a "
                                             r"polynomial"):
        build_case(spec, n_control=5, project=project, self_calibration="c, p1")
