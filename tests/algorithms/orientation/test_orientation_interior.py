"""Interior orientation from fiducial marks: the Siena reports reproduced; bad marks refused;
the orientation:interior algorithm end to end."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import siena_interior_cases

import toolbox
from toolbox.errors import InputDataError
from toolbox.photogrammetry.fiducials import InteriorOrientation

SIENA = Path(__file__).resolve().parents[3] / "toolbox" / "demo" / "data" / "siena"
NOMINAL = {"01": (-106.0, 106.0), "02": (106.0, 106.0), "03": (106.0, -106.0),
           "04": (-106.0, -106.0)}


@pytest.mark.parametrize("key, rows, report", siena_interior_cases(), ids=lambda v: "_".join(v)
                         if isinstance(v, tuple) else "")
def test_siena_reports_reproduced(key, rows, report):
    """What this proves, honestly: the 18 (photo, source) reports hold only 8 distinct mark
    sets (the logs reprint the same measurements); 6 of the 18 (2 distinct) are homographies
    fitted on exactly 4 marks, where zero residuals are a tautology of an exact fit (only the
    matrices are checked there). The affine cases have redundancy 2 and check the residuals and
    sigma. Over-determined fits with known noise are tested in test_io_overdetermined_recovers_known_noise."""
    calibrated = {r["mark_id"]: (float(r["x_mm"]), float(r["y_mm"])) for r in rows}
    measured = {r["mark_id"]: (float(r["col_px"]), float(r["row_px"])) for r in rows}
    io = InteriorOrientation.fit(calibrated, measured, rows[0]["transformation"], key[0])
    p2f = np.array([float(report[f"p2f_{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)])
    f2p = np.array([float(report[f"f2p_{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)])
    np.testing.assert_allclose(io.pixel_to_fiducial.ravel(), p2f, atol=1e-6)
    # the printed Fiducial->Pixel is the plain inverse (2_7138 prints 3_3 = 1.000058)
    np.testing.assert_allclose(np.linalg.inv(io.pixel_to_fiducial).ravel(), f2p, atol=1.5e-6)
    residuals = np.array([[float(r["res_x_mm"]), float(r["res_y_mm"])] for r in rows])
    np.testing.assert_allclose(io.residuals_mm, residuals, atol=1e-6)
    if report["p2f_transformation"] == "AFFINE":
        assert io.transformation == "affine" and io.redundancy == 2
        assert io.variance_mm2 == pytest.approx(float(report["sigma_globale"]), abs=5e-7)
    else:
        assert io.transformation == "homography" and io.redundancy == 0
        assert io.sigma0_mm is None and np.abs(io.residuals_mm).max() < 1e-9


def test_photo_1_7150_affine_values_printed_in_the_thesis():
    measured = {"01": (815.770348, 622.505490), "02": (15958.353063, 649.370400),
                "03": (15930.745824, 15791.048428), "04": (788.705455, 15763.965936)}
    io = InteriorOrientation.fit(NOMINAL, measured, "AFFINE", "1_7150")
    np.testing.assert_allclose(np.abs(io.residuals_mm), [[0.001897, 0.000765]] * 4, atol=5e-7)
    np.testing.assert_allclose(np.sign(io.residuals_mm[:, 0]), [-1, 1, -1, 1])
    assert round(io.variance_mm2, 6) == 0.000008  # "Sigma globale = 0.000008"
    assert io.pixel_size_mm == pytest.approx(0.014, abs=2e-6)
    # pixel <-> image round trip; rows grow downward (y = +106 at the top marks)
    px = np.array(list(measured.values()))
    np.testing.assert_allclose(io.image_to_pixel(io.pixel_to_image(px)), px, atol=1e-9)
    assert io.pixel_to_image(px)[0, 1] > 0 > io.pixel_to_image(px)[3, 1]


def test_too_few_and_collinear_marks_refused():
    measured = {"01": (815.8, 622.5), "02": (15958.4, 649.4)}
    with pytest.raises(InputDataError, match="photo 'p': a affine interior orientation needs "
                                             "at least 3 fiducial marks, got 2"):
        InteriorOrientation.fit(NOMINAL, measured, "affine", "p")
    three = {"01": (815.8, 622.5), "02": (15958.4, 649.4), "03": (15930.7, 15791.0)}
    with pytest.raises(InputDataError, match="at least 4"):
        InteriorOrientation.fit(NOMINAL, three, "omografica", "p")
    collinear = {"01": (0.0, 0.0), "02": (100.0, 100.0), "03": (200.0, 200.0),
                 "04": (300.0, 300.0)}
    with pytest.raises(InputDataError, match="photo 'p': fiducial marks: .*collinear"):
        InteriorOrientation.fit(NOMINAL, collinear, "affine", "p")
    with pytest.raises(InputDataError, match="'9' are not in the camera"):
        InteriorOrientation.fit(NOMINAL, {**three, "9": (1.0, 2.0)}, "affine", "p")
    with pytest.raises(InputDataError, match="affine, homography"):
        InteriorOrientation.fit(NOMINAL, three, "polynomial", "p")


def test_digital_camera_pixel_size_transform():
    io = InteriorOrientation.from_pixel_size(6000, 4000, 0.004)
    np.testing.assert_allclose(io.pixel_to_image(np.array([[3000.0, 2000.0], [0.0, 0.0]])),
                               [[0.0, 0.0], [-12.0, 8.0]])


def test_algorithm_on_the_bundled_fiducials(tmp_path):
    out = toolbox.run("orientation:interior", {
        "INPUT": SIENA / "fiducials.csv", "TRANSFORMATION": "from_input", "SOURCE": "log_block",
        "OUTPUT": tmp_path / "io.json", "RESIDUALS": tmp_path / "res.csv"})
    report = json.loads(Path(out["OUTPUT"]).read_text())
    photos = {p["photo"]: p for p in report["photos"]}
    assert set(photos) == {"1_7150", "1_7151", "1_7152", "2_7138", "2_7139", "2_7140"}
    first = photos["1_7150"]
    assert first["transformation"] == "affine" and round(first["variance_mm2"], 6) == 0.000008
    assert first["residuals"][0]["res_x_mm"] == pytest.approx(-0.001897, abs=5e-7)
    assert photos["1_7152"]["transformation"] == "homography"
    assert photos["1_7152"]["variance_mm2"] is None
    with open(out["RESIDUALS"]) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 24 and float(rows[0]["res_y_mm"]) == pytest.approx(-0.000765, abs=5e-7)
    assert out["STATISTICS"]["photos"] == 6


def test_algorithm_takes_marks_from_a_project_and_reports_bad_input(tmp_path):
    table = tmp_path / "marks.csv"
    table.write_text("photo;mark_id;col_px;row_px\n"
                     "1_7150;01;815.770348;622.505490\n1_7150;02;15958.353063;649.370400\n"
                     "1_7150;03;15930.745824;15791.048428\n1_7150;04;788.705455;15763.965936\n")
    out = toolbox.run("orientation:interior", {
        "INPUT": table, "PROJECT": SIENA / "siena_project.yaml", "OUTPUT": tmp_path / "a.json"})
    assert out["STATISTICS"]["max_residual_mm"] == pytest.approx(0.0020453, abs=1e-6)
    with pytest.raises(InputDataError, match="give PROJECT"):
        toolbox.run("orientation:interior", {"INPUT": table, "OUTPUT": tmp_path / "b.json"})
    with pytest.raises(InputDataError, match="from_input but photo '1_7150'"):
        toolbox.run("orientation:interior", {"INPUT": table, "OUTPUT": tmp_path / "c.json",
                                             "PROJECT": SIENA / "siena_project.yaml",
                                             "TRANSFORMATION": "from_input"})
    assert not (tmp_path / "b.json").exists() and not (tmp_path / "c.json").exists()


def test_siena_cases_are_what_the_docstring_says():
    cases = siena_interior_cases()
    assert len(cases) == 18
    distinct = {tuple((r["mark_id"], r["x_mm"], r["y_mm"], r["col_px"], r["row_px"]) for r in rows)
                for _, rows, _ in cases}
    assert len(distinct) == 8
    exact = [k for k, rows, rep in cases if rep["p2f_transformation"] != "AFFINE" and len(rows) == 4]
    assert len(exact) == 6 and len({k[0] for k in exact}) == 2


@pytest.mark.parametrize("transformation, redundancy", [("affine", 10), ("homography", 8)])
def test_io_overdetermined_recovers_known_noise(transformation, redundancy):
    """8 marks (corners and mid-sides), a known affine scan geometry, 2 µm noise per coordinate:
    sigma0 estimates the noise and the residuals are computed minus observed."""
    rng = np.random.default_rng(8)
    marks = {f"{k:02d}": xy for k, xy in enumerate(
        [(-106, 106), (106, 106), (106, -106), (-106, -106), (0, 110), (110, 0), (0, -110),
         (-110, 0)], start=1)}
    f2p = np.array([[71.43, 0.05, 8322.0], [0.04, -71.42, 8322.0]])  # fiducial mm -> pixel
    measured = {}
    for k, (x, y) in marks.items():
        noisy = np.array([x, y]) + rng.normal(0, 0.002, 2)
        measured[k] = tuple(f2p @ [noisy[0], noisy[1], 1.0])
    io = InteriorOrientation.fit(marks, measured, transformation, "synthetic")
    assert io.redundancy == redundancy
    assert 0.0008 < io.sigma0_mm < 0.0035
    fitted = io.pixel_to_image(np.array(list(measured.values())))
    np.testing.assert_allclose(io.residuals_mm, fitted - np.array(list(marks.values())), atol=1e-9)
