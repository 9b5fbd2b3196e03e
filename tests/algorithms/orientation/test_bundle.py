"""orientation:bundle end to end on the sample block (2 strips x 4 digital photos, one blunder)
and its bad-input contract (one-line errors, exit 2, nothing written)."""

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

import toolbox
from tests.helpers_cli import assert_refused
from toolbox.demo.samples.bundle_block import BLUNDER_POINT, make
from toolbox.errors import ToolboxError
from toolbox.photogrammetry.project import load_project
from toolbox.triangulation.synthetic import SyntheticBlockSpec, make_block


def declared_layer_problems(alg_id: str, name: str, path, params) -> list[str]:
    """tests/toolbox/test_specs.py's check of written against declared layers (that test covers
    only algorithms with a demo step)."""
    import importlib.util
    from pathlib import Path

    from toolbox.registry import get

    spec = importlib.util.spec_from_file_location(
        "_specs", Path(__file__).resolve().parents[2] / "toolbox" / "test_specs.py")
    specs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(specs)
    dest = next(d for d in get(alg_id).destinations() if d.name == name)
    return specs.check_layers(str(path), dest.layers, {k: str(v) for k, v in params.items()})


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    return make(tmp_path_factory.mktemp("bundle_sample"), {})


def _params(sample, tmp_path, **over):
    return {"PROJECT": sample["bundle_project"], "INPUT": sample["bundle_measurements"],
            "CONTROL": sample["bundle_control"], "SIGMA_PX": 0.3,
            "OUTPUT": tmp_path / "adjusted.yaml", "POINTS": tmp_path / "bundle.gpkg",
            "REPORT": tmp_path / "bundle.json"} | over


def test_sample_block_is_oriented_blunder_rejected_outputs_readable(sample, tmp_path):
    import geopandas as gpd

    params = _params(sample, tmp_path)
    out = toolbox.run("orientation:bundle", params)
    assert not declared_layer_problems("orientation:bundle", "POINTS", out["POINTS"], params)
    stats = out["STATISTICS"]
    assert 0.8 < stats["sigma0"] < 1.2 and stats["photos"] == 8
    report = json.loads((tmp_path / "bundle.json").read_text())
    rejected = report["rejected_observations"]
    obs = report["image_observations"]
    assert len(obs) == report["summary"]["image_observations"]
    assert sum(o["rejected"] for o in obs) >= 1
    assert any(r["point_id"] == BLUNDER_POINT and r["photo"] == "1_01" and abs(r["w"]) > 10
               for r in rejected)
    # orientations against the truth the sample was made from, within 4 sigma
    truth = make_block(SyntheticBlockSpec(digital=True, seed=7)).project
    adjusted = load_project(out["OUTPUT"])  # what ortho:batch reads
    assert len(adjusted.oriented()) == 8
    for row in report["photos"]:
        t = truth.photos[row["photo"]].exterior
        e = adjusted.photos[row["photo"]].exterior
        for name, a, b in (("X0", e.x0, t.x0), ("Y0", e.y0, t.y0), ("Z0", e.z0, t.z0)):
            assert abs(a - b) < 4 * row[f"std_{name}"], (row["photo"], name, a - b)
    checks = [g for g in report["control_and_check"] if g["role"] == "check"]
    assert len(checks) == 2
    for g in checks:
        for a in "xyz":
            assert abs(g[f"d{a}_m"]) < 4 * g[f"sigma_{a}_m"]
    layers = {n: gpd.read_file(out["POINTS"], layer=n) for n in
              ("projection_centres", "points", "image_residuals", "ground_residuals")}
    assert len(layers["projection_centres"]) == 8
    assert set(layers["points"]["role"]) == {"tie", "control", "check"}
    assert layers["image_residuals"]["rejected"].sum() >= 1
    res = layers["image_residuals"]
    flagged = res[~res["rejected"] & (res["res_px"] > 1.0)]
    assert res["flagged"].sum() == len(flagged) == report["summary"]["flagged"]
    assert (layers["points"]["sigma_z_m"] > 0).all()
    pts = layers["points"]
    # the error ellipse holds the XY variances: a² + b² = σx² + σy², b <= σx, σy <= a
    assert np.allclose(pts["ellipse_a_m"] ** 2 + pts["ellipse_b_m"] ** 2,
                       pts["sigma_x_m"] ** 2 + pts["sigma_y_m"] ** 2, rtol=1e-9)
    assert (pts["ellipse_b_m"] <= pts[["sigma_x_m", "sigma_y_m"]].min(axis=1) + 1e-12).all()


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


def _write(path, rows):
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return path


def _bad(sample, tmp_path, match, **over):
    params = _params(sample, tmp_path, **over)
    with pytest.raises(ToolboxError, match=match) as info:
        toolbox.run("orientation:bundle", params)
    assert "\n" not in str(info.value)
    assert not any(p.exists() for p in (params["OUTPUT"], params["POINTS"], params["REPORT"]))


def test_measurements_of_unknown_photos_are_refused(sample, tmp_path):
    rows = _rows(sample["bundle_measurements"])
    rows[1][1] = "9_99"
    _bad(sample, tmp_path, "9_99", INPUT=_write(tmp_path / "m.csv", rows))


def test_a_tie_point_seen_once_is_refused(sample, tmp_path):
    rows = _rows(sample["bundle_measurements"]) + [["lonely", "1_01", "100.0", "200.0"]]
    _bad(sample, tmp_path, "fewer than 2 photos.*lonely", INPUT=_write(tmp_path / "m.csv", rows))


def test_duplicate_measurements_are_refused(sample, tmp_path):
    rows = _rows(sample["bundle_measurements"])
    rows.append(list(rows[5]))
    _bad(sample, tmp_path, "duplicate", INPUT=_write(tmp_path / "m.csv", rows))


@pytest.mark.parametrize("value", ["0", "-0.5"])
def test_sigma_not_positive_is_refused(sample, tmp_path, value):
    rows = _rows(sample["bundle_measurements"])
    rows = [rows[0] + ["sigma_px"]] + [r + ["0.3"] for r in rows[1:]]
    rows[3][-1] = value
    _bad(sample, tmp_path, "sigma_px must be > 0", INPUT=_write(tmp_path / "m.csv", rows))


def test_datum_defect_names_what_is_missing(sample, tmp_path):
    rows = _rows(sample["bundle_control"])
    keep = [rows[0]] + [r for r in rows[1:] if r[4] == "check" or r[3] == ""][:3] + [rows[1]]
    _bad(sample, tmp_path, "datum defect.*planimetric.*add",
         CONTROL=_write(tmp_path / "c.csv", keep))


def test_disconnected_block_is_reported_by_component(sample, tmp_path):
    rows = _rows(sample["bundle_measurements"])
    renamed = [[r[0] + "_s2" if r[1].startswith("2_") else r[0], *r[1:]] for r in rows[1:]]
    seen = [r[0] for r in renamed]
    rows = [rows[0]] + [r for r in renamed if seen.count(r[0]) >= 2]
    _bad(sample, tmp_path, "not connected.*component 1.*component 2",
         INPUT=_write(tmp_path / "m.csv", rows))


def test_start_project_without_exteriors_is_refused(sample, tmp_path):
    _bad(sample, tmp_path, "START", START="project")


def test_command_line_error_is_one_line_exit_2(sample, tmp_path):
    rows = _rows(sample["bundle_measurements"])
    rows.append(list(rows[5]))
    bad = _write(tmp_path / "m.csv", rows)
    result = subprocess.run(
        [sys.executable, "-m", "toolbox.cli", "run", "orientation:bundle", "--PROJECT",
         str(sample["bundle_project"]), "--INPUT", str(bad), "--CONTROL",
         str(sample["bundle_control"]), "--OUTPUT", str(tmp_path / "o.yaml")],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and "duplicate" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o.yaml").exists()


def test_gnss_centres_fix_the_datum_without_control(sample, tmp_path):
    truth = make_block(SyntheticBlockSpec(digital=True, seed=7)).project
    rng = np.random.default_rng(5)
    rows = [["photo", "X", "Y", "Z"]]
    for pid, p in truth.photos.items():
        x, y, z = np.asarray(p.exterior.centre) + rng.normal(0, 0.05, 3)
        rows.append([pid, f"{x:.4f}", f"{y:.4f}", f"{z:.4f}"])
    gnss = _write(tmp_path / "gnss.csv", rows)
    control = _rows(sample["bundle_control"])
    only_checks = _write(tmp_path / "c.csv", [control[0]] + [r for r in control[1:]
                                                             if r[4] == "check"])
    out = toolbox.run("orientation:bundle", _params(
        sample, tmp_path, CONTROL=only_checks, GNSS=gnss, GNSS_SIGMA_XY=0.05,
        GNSS_SIGMA_Z=0.05))
    assert 0.8 < out["STATISTICS"]["sigma0"] < 1.2
    report = json.loads((tmp_path / "bundle.json").read_text())
    for g in report["control_and_check"]:
        for a in "xyz":
            assert abs(g[f"d{a}_m"]) < 4 * g[f"sigma_{a}_m"]


def test_control_points_never_measured_are_listed_not_used(sample, tmp_path):
    rows = _rows(sample["bundle_control"]) + [["ghost", "1689000.0", "4798000.0", "300.0",
                                               "control"]]
    params = _params(sample, tmp_path, CONTROL=_write(tmp_path / "c.csv", rows))
    toolbox.run("orientation:bundle", params)
    notes = json.loads((tmp_path / "bundle.json").read_text())["notes"]
    assert any("not measured in INPUT" in n and "ghost" in n for n in notes)


def test_bad_lever_arm_is_refused(sample, tmp_path):
    _bad(sample, tmp_path, "LEVER_ARM.*three numbers", LEVER_ARM="0.1, up")


def test_start_from_the_project_exteriors(sample, tmp_path):
    from dataclasses import replace

    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.project import Project, save_project

    truth = make_block(SyntheticBlockSpec(digital=True, seed=7)).project
    rng = np.random.default_rng(3)
    photos = {}
    for pid, p in truth.photos.items():  # a flight plan: 20 m and 20 mrad off
        e = p.exterior
        photos[pid] = replace(p, exterior=ExteriorOrientation(
            pid, e.x0 + rng.normal(0, 20), e.y0 + rng.normal(0, 20), e.z0 + rng.normal(0, 20),
            e.omega + rng.normal(0, 0.02), e.phi + rng.normal(0, 0.02),
            e.kappa + rng.normal(0, 0.02), crs=truth.crs))
    project = save_project(Project(truth.crs, truth.cameras, photos), tmp_path / "plan.yaml")
    out = toolbox.run("orientation:bundle", _params(sample, tmp_path, PROJECT=project,
                                                    START="project"))
    report = json.loads((tmp_path / "bundle.json").read_text())
    assert any("PROJECT's exterior" in n for n in report["notes"])
    adjusted = load_project(out["OUTPUT"])
    for row in report["photos"]:
        t, e = truth.photos[row["photo"]].exterior, adjusted.photos[row["photo"]].exterior
        assert abs(e.z0 - t.z0) < 4 * row["std_Z0"]


def test_tie_points_and_control_measurements_in_two_files(sample, tmp_path):
    rows = _rows(sample["bundle_measurements"])
    control_ids = {r[0] for r in _rows(sample["bundle_control"])[1:]}
    ties = _write(tmp_path / "ties.csv", [rows[0] + ["sigma_px"]] +
                  [r + ["0.3"] for r in rows[1:] if r[0] not in control_ids])
    ctrl = _write(tmp_path / "ctrl.csv", [rows[0]] + [r for r in rows[1:] if r[0] in control_ids])
    out = toolbox.run("orientation:bundle", _params(sample, tmp_path, INPUT=ties,
                                                    CONTROL_INPUT=ctrl))
    assert out["STATISTICS"]["photos"] == 8 and "check_rmse_m" in out["STATISTICS"]
    mm = _write(tmp_path / "mm.csv", [["point_id", "photo", "x_mm", "y_mm"],
                                      ["x", "1_01", "1.0", "2.0"]])
    bad = tmp_path / "bad"
    bad.mkdir()
    _bad(sample, bad, "CONTROL_INPUT.*image coordinates", INPUT=ties, CONTROL_INPUT=mm)


def test_control_in_another_crs_is_refused(sample, tmp_path):
    """Control labelled with another CRS (a .prj beside the CSV), or lon/lat numbers in a
    CSV for a projected PROJECT: one line naming CONTROL, nothing written."""
    from pyproj import CRS, Transformer

    rows = _rows(sample["bundle_control"])
    labelled = _write(tmp_path / "control_utm.csv", rows)
    labelled.with_suffix(".prj").write_text(CRS.from_epsg(32632).to_wkt())
    _bad(sample, tmp_path, "CONTROL.*EPSG:32632.*PROJECT.*EPSG:3003", CONTROL=labelled)
    to_lonlat = Transformer.from_crs("EPSG:3003", "EPSG:4326", always_xy=True)
    header = rows[0]
    ix, iy = header.index("X"), header.index("Y")
    for r in rows[1:]:
        if r[ix] != "":
            r[ix], r[iy] = map(str, to_lonlat.transform(float(r[ix]), float(r[iy])))
    _bad(sample, tmp_path, "CONTROL", CONTROL=_write(tmp_path / "control_ll.csv", rows))


def test_project_angles_in_the_wrong_unit_are_refused(sample, tmp_path):
    """A flight plan written in degrees but declared angle_unit rad: the vertical block's
    control points fall behind the cameras, the same numbers as degrees fit: one line naming
    PROJECT and the mix-up, nothing written. (Its kappas of 178 deg are beyond a full turn in
    rad: the project's reader refuses them first, naming the file's angle_unit and deg.)"""
    import yaml

    from toolbox.photogrammetry.project import Project, save_project

    truth = make_block(SyntheticBlockSpec(digital=True, seed=7)).project
    path = save_project(Project(truth.crs, truth.cameras, truth.photos), tmp_path / "plan.yaml",
                        angle_unit="deg")
    doc = yaml.safe_load(path.read_text())
    doc["angle_unit"] = "rad"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    _bad(sample, tmp_path, "(PROJECT.*written in deg, read as rad.*angle_unit)|(plan.yaml "
         "photo .* angle_unit is rad, but an angle of .* beyond a full turn .*in deg\\?)",
         PROJECT=path, START="project")


@pytest.mark.parametrize(("over", "text"), [
    ({"REFERENCE_TOLERANCE": "0.1, 0.1, 0.2"}, "REFERENCE_TOLERANCE must be four positive"),
    ({"REFERENCE_TOLERANCE": "0.1, 0.1, 0.2, 50"}, "REFERENCE_TOLERANCE needs REFERENCE")])
def test_bad_reference_tolerance_is_one_line_exit_2_nothing_written(sample, tmp_path, over, text):
    args = ["run", "orientation:bundle"]
    for key, value in _params(sample, tmp_path, **over).items():
        args += [f"--{key}", value]
    assert_refused(args, text, absent=(tmp_path / "adjusted.yaml", tmp_path / "bundle.json"))

