"""Readers: the Z-Map logs of the thesis, the native CSV, the omega-phi-kappa exports (fixtures
written here in the documented Pix4D / Metashape layouts) and the project file."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from toolbox.errors import InputDataError, ParameterError
from toolbox.photogrammetry.project import load_project
from toolbox.photogrammetry.readers import read_exterior_orientations, read_zmap_log
from toolbox.photogrammetry.readers.text import photo_id, sniff_format
from toolbox.photogrammetry.rotation import rotation_matrix

SIENA = Path(__file__).resolve().parents[3] / "toolbox" / "demo" / "data" / "siena"
RUNS = {"strip1": "zmap_strip1.log", "strip2": "zmap_strip2.log", "block": "zmap_block.log"}


def csv_rows(name):
    with open(SIENA / name, newline="") as f:
        return list(csv.DictReader(f))


# -- Z-Map logs ---------------------------------------------------------------------------------
@pytest.mark.parametrize("run", RUNS)
def test_zmap_logs_exterior_orientations_match_the_extract(run):
    (log,) = read_zmap_log(SIENA / RUNS[run])
    rows = [r for r in csv_rows("exterior_orientation.csv") if r["run"] == run]
    assert len(log.photos) == len({r["photo"] for r in rows})
    for row in rows:
        record = log.photos[row["photo"]]
        eo = getattr(record, "final" if row["stage"] == "final" else "initial")
        assert record.camera_name == row["camera"]
        if row["X0_m"] == "":
            assert eo is None  # block / 2_7139: not printed
            continue
        assert (eo.x0, eo.y0, eo.z0) == (float(row["X0_m"]), float(row["Y0_m"]),
                                         float(row["Z0_m"]))
        assert eo.angles("rad") == pytest.approx(
            (float(row["omega"]), float(row["phi"]), float(row["kappa"])), abs=1e-15)


def test_zmap_log_headers_and_counts():
    strip1, strip2, block = (read_zmap_log(SIENA / RUNS[r])[0] for r in RUNS)
    assert (strip1.name, strip1.date, strip1.time) == ("str_1", "03/31/09", "11:45:10")
    assert (strip1.equations, strip1.unknowns) == (72, 45)
    assert (strip2.equations, strip2.unknowns) == (76, 45)
    assert (block.equations, block.unknowns, block.n_images) == (154, 93, 6)
    assert block.max_iterations == 100 and block.convergence == pytest.approx(0.001)
    assert block.missing("final") == ["2_7139"] and strip2.missing("final") == []
    assert len(block.control_points) == 8 and len(strip1.control_residuals) == 6
    assert strip1.control_residuals["ptc_008-2_7139"] == (0.257, -0.132, -0.947)
    cps = {r["id"]: (float(r["X"]), float(r["Y"]), float(r["Z"]))
           for r in csv_rows("control_points.csv") if r["record"] == "coordinates"
           and r["run"] == "block"}
    assert block.control_points == cps


@pytest.mark.parametrize("run", RUNS)
def test_zmap_log_interior_blocks_match_the_reports(run):
    (log,) = read_zmap_log(SIENA / RUNS[run])
    reports = {r["photo"]: r for r in csv_rows("interior_reports.csv")
               if r["source"] == f"log_{run}"}
    for pid, record in log.photos.items():
        report = reports[pid]
        printed = np.array([float(report[f"p2f_{i}{j}"]) for i in (1, 2, 3) for j in (1, 2, 3)])
        np.testing.assert_array_equal(record.pixel_to_fiducial.ravel(), printed)
        assert record.sigma_globale == float(report["sigma_globale"])
        assert len(record.distortion_table) == int(report["radial_distortion_entries"])
        assert record.counter_distortion == 0 and record.width_px == 16644
        refit = record.refit_interior()
        np.testing.assert_allclose(refit.pixel_to_fiducial.ravel(), printed, atol=1e-6)
    cameras = log.cameras()
    if "wild_rc30_152.94_sienamarco" in cameras:
        cam = cameras["wild_rc30_152.94_sienamarco"]
        assert cam.c == 303.55 and cam.fiducials_mm["1"] == (-106.005, 106.005)
        assert cam.distortion.delta_r(np.array([148.0]))[0] == pytest.approx(-1.4e-3)


def test_zmap_log_run_selection_and_errors(tmp_path):
    both = tmp_path / "two_runs.log"
    both.write_text((SIENA / RUNS["strip1"]).read_text() + "\n" + (SIENA / RUNS["block"])
                    .read_text())
    assert len(read_zmap_log(both)) == 2
    table = read_exterior_orientations(both, run="str_1")
    assert set(table.orientations) == {"1_7150", "1_7151", "1_7152"}
    assert table.orientations["1_7150"].x0 == 1688135.071
    assert read_exterior_orientations(both).orientations["1_7150"].x0 == 1688134.973  # last run
    with pytest.raises(ParameterError, match="RUN 'nope' is not a run"):
        read_exterior_orientations(both, run="nope")
    bad = tmp_path / "bad.log"
    bad.write_text("nothing here\n")
    with pytest.raises(InputDataError, match="not a Z-Map adjustment log"):
        read_zmap_log(bad)
    broken = tmp_path / "broken.log"
    broken.write_text("%% COMPENSAZIONE A STELLE PROIETTIVE %%\n----- FOTOGRAMMA c:\\a\\x1.tif -----\n"
                      "Focale = 150.0\nNome file camera - cam\n"
                      "---Orientamento esterno - valori approssimati iniziali\n"
                      "Omega 0.1, Phi 0.2, Kappa 0.3\n")
    with pytest.raises(InputDataError, match="line 6: Omega/Phi/Kappa without the Nx/Ny/Nz"):
        read_zmap_log(broken)


# -- native CSV -------------------------------------------------------------------------------
def test_native_csv_with_row_filters():
    table = read_exterior_orientations(SIENA / "exterior_orientation.csv",
                                       where={"run": "strip2", "stage": "final"})
    assert table.format == "native" and list(table.orientations) == ["2_7138", "2_7139", "2_7140"]
    assert table.orientations["2_7139"].kappa == 3.122
    assert table.attributes["2_7139"]["camera"] == "wild_rc30_152.94_sienamarco"
    with pytest.raises(InputDataError, match="line 24: photo '2_7139' has no valid X0_m"):
        read_exterior_orientations(SIENA / "exterior_orientation.csv",
                                   where={"run": "block", "stage": "final"})
    with pytest.raises(InputDataError, match="appears twice"):
        read_exterior_orientations(SIENA / "exterior_orientation.csv", where={"run": "block"})
    with pytest.raises(ParameterError, match="WHERE names column 'flight'"):
        read_exterior_orientations(SIENA / "exterior_orientation.csv", where={"flight": "1"})


def test_native_csv_needs_a_unit(tmp_path):
    path = tmp_path / "eo.csv"
    path.write_text("# my block\nphoto,X0,Y0,Z0,omega,phi,kappa\nA,1000,2000,1500,1,2,100\n")
    with pytest.raises(ParameterError, match="ANGLE_UNIT is required"):
        read_exterior_orientations(path)
    eo = read_exterior_orientations(path, angle_unit="gon").orientations["A"]
    assert eo.kappa == pytest.approx(math.pi / 2) and eo.source_unit == "gon"
    path.write_text("photo,X0,Y0,Z0,omega,phi,kappa,angle_unit\nA,1000,2000,1500,1,2,100,mil\n")
    with pytest.raises(ParameterError, match="angle_unit must be one of rad, deg, gon"):
        read_exterior_orientations(path)


# -- omega-phi-kappa exports ----------------------------------------------------------------------
def metashape_text(transpose=False, corrupt=False):
    """The Metashape "Omega Phi Kappa" layout: two comment lines, then tab-separated rows with
    the nine r values (written by this test from R(omega, phi, kappa) in degrees)."""
    lines = ["# Cameras (2)",
             "# PhotoID, X, Y, Z, Omega, Phi, Kappa, r11, r12, r13, r21, r22, r23, r31, r32, r33"]
    for name, xyz, opk in (("DSC_0001.JPG", (500000.1, 4800000.2, 620.3), (1.5, -2.0, 91.0)),
                           ("DSC_0002.JPG", (500080.4, 4800001.0, 621.0), (-0.5, 0.8, 89.5))):
        r = rotation_matrix(*np.radians(opk))
        r = r.T if transpose else r
        if corrupt:
            r = r @ rotation_matrix(0.0, 0.0, 0.01)
        lines.append("\t".join([name, *(f"{v:.6f}" for v in xyz), *(f"{v:.6f}" for v in opk),
                                *(f"{v:.10f}" for v in r.ravel())]))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("transpose, convention", [(False, "R (image -> ground)"),
                                                    (True, "R transposed (ground -> image)")])
def test_metashape_export(tmp_path, transpose, convention):
    path = tmp_path / "cameras.txt"
    path.write_text(metashape_text(transpose))
    table = read_exterior_orientations(path)
    assert table.format == "metashape" and list(table.orientations) == ["DSC_0001", "DSC_0002"]
    eo = table.orientations["DSC_0001"]
    assert eo.angles("deg") == pytest.approx((1.5, -2.0, 91.0)) and eo.z0 == 620.3
    assert any(convention in note for note in table.notes)


def test_metashape_matrix_inconsistent_with_angles_refused(tmp_path):
    path = tmp_path / "cameras.txt"
    path.write_text(metashape_text(corrupt=True))
    with pytest.raises(InputDataError, match="line 3: photo 'DSC_0001': the r11..r33 values do "
                                             "not match"):
        read_exterior_orientations(path)


def test_pix4d_external_parameters(tmp_path):
    path = tmp_path / "project_calibrated_external_camera_parameters.txt"
    path.write_text("imageName X Y Z Omega Phi Kappa\n"
                    "IMG_0101.tif 688001.5 4799321.25 1460.125 0.802141 -0.057296 2.864789\n"
                    "IMG_0102.tif 688190.0 4799322.75 1461.000 -0.5 0.25 3.0\n")
    assert sniff_format(path.read_text()) == "pix4d"
    table = read_exterior_orientations(path)
    eo = table.orientations["IMG_0101"]
    assert eo.omega == pytest.approx(math.radians(0.802141)) and eo.x0 == 688001.5


def test_generic_opk_text_with_and_without_header(tmp_path):
    headed = tmp_path / "eo.txt"
    headed.write_text("Name;Easting;Northing;Height;Omega;Phi;Kappa;Quality\n"
                      "7150;1688134.973;4799812.289;1463.236;0.014;-0.001;0.050;good\n")
    with pytest.raises(ParameterError, match="ANGLE_UNIT is required"):
        read_exterior_orientations(headed)
    eo = read_exterior_orientations(headed, angle_unit="rad").orientations["7150"]
    assert (eo.x0, eo.kappa) == (1688134.973, 0.05)
    bare = tmp_path / "bare.txt"
    bare.write_text("a 10 20 1000 0 0 90\nb 30 20 1000 0 0 90 extra\n")
    table = read_exterior_orientations(bare, angle_unit="deg")
    assert table.format == "opk" and table.orientations["b"].kappa == pytest.approx(math.pi / 2)
    short = tmp_path / "short.txt"
    short.write_text("a 10 20 1000 0 0\n")
    with pytest.raises(InputDataError, match="line 1: expected id X Y Z omega phi kappa"):
        read_exterior_orientations(short, angle_unit="deg")
    with pytest.raises(ParameterError, match="FORMAT must be one of"):
        read_exterior_orientations(bare, fmt="bingo")


def test_photo_ids_lose_folders_and_image_extensions():
    assert photo_id(r"d:\francesco\menci\siena\fotogrammi\1_7150.tif") == "1_7150"
    assert photo_id("DSC.0001.JPG") == "DSC.0001" and photo_id("strip.2") == "strip.2"


# -- project file -----------------------------------------------------------------------------
def test_siena_project_loads_with_its_crs_and_log_orientations():
    project = load_project(SIENA / "siena_project.yaml")
    assert project.crs.to_epsg() == 3003
    assert list(project.photos) == ["1_7150", "1_7151", "1_7152", "2_7138", "2_7139", "2_7140"]
    assert project.photos["2_7139"].exterior.x0 == 1688391.734  # strip-2 log (block has none)
    assert project.photos["1_7152"].exterior.x0 == 1688511.923  # block log
    assert project.photos["1_7152"].interior.transformation == "homography"
    assert project.photos["2_7140"].camera.distortion is not None
    assert [(a.id, b.id) for a, b in project.consecutive_pairs()] == [
        ("1_7150", "1_7151"), ("1_7151", "1_7152"), ("2_7138", "2_7139"), ("2_7139", "2_7140")]
    assert project.photos["1_7150"].image.name == "1_7150.tif"


PROJECT = """\
version: 1
crs: EPSG:3003
angle_unit: deg
cameras:
  - {{name: cam, principal_distance_mm: 150.0, frame_size_mm: [230, 230]}}
photos:
  - {{id: 1_7150, camera: {camera}, exterior: {{X0: 1, Y0: 2, Z0: 1000, omega: 0, phi: 0,
      kappa: 90}}}}
{extra}"""


def write_project(tmp_path, camera="cam", extra=""):
    path = tmp_path / "p.yaml"
    path.write_text(PROJECT.format(camera=camera, extra=extra))
    return path


def test_project_reads_ids_as_text_and_units(tmp_path):
    project = load_project(write_project(tmp_path))
    assert list(project.photos) == ["1_7150"]  # not the YAML 1.1 integer 17150
    assert project.photos["1_7150"].exterior.kappa == pytest.approx(math.pi / 2)


def test_project_errors_name_the_problem(tmp_path):
    with pytest.raises(InputDataError, match="photo '1_7150' names camera 'other', which the "
                                             "project does not define"):
        load_project(write_project(tmp_path, camera="other"))
    eo_file = tmp_path / "eo.csv"
    eo_file.write_text("photo,X0,Y0,Z0,omega,phi,kappa,angle_unit\n"
                       "1_7150,5,6,1000,0,0,0,rad\nX9,7,8,1000,0,0,0,rad\n")
    extra = "exterior_orientations:\n  - {path: eo.csv}\n"
    with pytest.raises(InputDataError, match="photo 'X9' in .*eo.csv has no camera"):
        load_project(write_project(tmp_path, extra=extra))
    project = load_project(write_project(
        tmp_path, extra="exterior_orientations:\n  - {path: eo.csv, default_camera: cam}\n"))
    assert project.photos["X9"].camera.name == "cam" and project.photos["1_7150"].exterior.x0 == 5
    path = tmp_path / "geo.yaml"
    path.write_text(PROJECT.format(camera="cam", extra="").replace("EPSG:3003", "EPSG:4326"))
    with pytest.raises(InputDataError, match="not a projected CRS"):
        load_project(path)
    path.write_text("cameras: [1, 2]\n")
    with pytest.raises(InputDataError, match="a camera needs at least 'name'"):
        load_project(path)


def test_project_save_and_reload_round_trip(tmp_path):
    from toolbox.photogrammetry.project import save_project

    project = load_project(SIENA / "siena_project.yaml")
    again = load_project(save_project(project, tmp_path / "copy.yaml", angle_unit="gon"))
    assert list(again.photos) == list(project.photos) and again.crs == project.crs
    for pid, photo in project.photos.items():
        copy = again.photos[pid]
        np.testing.assert_allclose(copy.exterior.angles(), photo.exterior.angles(), atol=1e-15)
        assert copy.exterior.centre.tolist() == photo.exterior.centre.tolist()
        np.testing.assert_allclose(copy.interior.pixel_to_fiducial, photo.interior.pixel_to_fiducial,
                                   rtol=0, atol=0)
        assert copy.camera.as_dict() == photo.camera.as_dict() and copy.strip == photo.strip
        assert copy.image.resolve() == photo.image.resolve()
