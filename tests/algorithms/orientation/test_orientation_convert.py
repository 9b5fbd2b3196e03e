"""orientation:convert end to end: a synthetic reconstruction to Orthority and back, the Siena
project to Orthority, and bad inputs (exit 2, one line, nothing written)."""

import json
import subprocess
import sys

import numpy as np
import pytest

import toolbox
import toolbox.errors
from tests.toolbox.exchange import exchange_synthetic as syn
from toolbox.exchange import csvtable, formats, opensfm, orthority
from toolbox.photogrammetry.project import load_project

CLI = [sys.executable, "-m", "toolbox.cli", "run", "orientation:convert"]


def test_reconstruction_to_orthority_and_project(tmp_path):
    source = syn.reconstruction(tmp_path / "reconstruction.json")
    out = toolbox.run("orientation:convert", {
        "INPUT": str(source), "FORMAT_OUT": "orthority",
        "OUTPUT": str(tmp_path / "o" / "block_ext_param.geojson")})
    summary = out["SUMMARY"]
    assert summary["crs"] == "EPSG:32651" and summary["oriented"] == 3
    assert any("UTM zone" in n for n in summary["notes"])
    assert summary["written"] == ["block_ext_param.geojson", "block_int_param.yaml"]
    direct = opensfm.read_reconstruction(source)
    back = formats.merge([orthority.read_exterior(tmp_path / "o" / "block_ext_param.geojson"),
                          orthority.read_interior(tmp_path / "o" / "block_int_param.yaml")])
    for pid, p in direct.photos.items():
        assert np.allclose(p.xyz, back.photos[pid].xyz, atol=1e-9, rtol=0)
        assert np.allclose(p.opk, back.photos[pid].opk, atol=1e-12, rtol=0)
    assert back.cameras == direct.cameras
    # the project YAML loads in the product and keeps the model
    toolbox.run("orientation:convert", {"INPUT": str(tmp_path / "o"), "FORMAT_OUT": "project",
                                        "OUTPUT": str(tmp_path / "p.yaml")})
    project = load_project(tmp_path / "p.yaml")
    assert set(project.photos) == {"IMG_0", "IMG_1", "IMG_2"}
    from toolbox.exchange.project import model_cameras

    assert ("model:" in (tmp_path / "p.yaml").read_text()) == model_cameras()


def test_siena_project_to_orthority_csv(tmp_path):
    """The demo's Siena project converts (its film cameras as pinhole specs, said in the notes);
    positions and angles survive to the CSV's printed precision."""
    siena = "toolbox/demo/data/siena/siena_project.yaml"
    out = toolbox.run("orientation:convert", {"INPUT": siena, "FORMAT_OUT": "csv",
                                              "OUTPUT": str(tmp_path / "siena.csv")})
    assert any("not carried over" in n for n in out["SUMMARY"]["notes"])
    table = csvtable.read_csv(tmp_path / "siena.csv")
    project = load_project(siena)
    assert table.crs.equals(project.crs)
    for pid, photo in project.photos.items():
        eo = photo.exterior
        assert np.allclose(table.photos[pid].xyz, (eo.x0, eo.y0, eo.z0), atol=5e-5, rtol=0)
        assert np.allclose(table.photos[pid].opk, (eo.omega, eo.phi, eo.kappa), atol=1e-11,
                           rtol=0)


@pytest.mark.parametrize("case, expected", [
    ("no_reference", "no reference_lla"),
    ("projection", "projection_type 'spherical'"),
    ("mixed_units", "mixed angle units"),
])
def test_bad_input_exits_2(tmp_path, case, expected):
    if case == "no_reference":
        source = syn.reconstruction(tmp_path / "r.json", reference=False)
    elif case == "projection":
        source = syn.reconstruction(tmp_path / "r.json", projection_type="spherical")
    else:
        source = tmp_path / "m.csv"
        source.write_text("filename,x,y,z,omega_deg,phi_gon,kappa_deg\na,1,2,3,0,0,0\n")
    output = tmp_path / "out.yaml"
    extra = ["--CRS", "EPSG:32632"] if case == "mixed_units" else []
    run = subprocess.run(CLI + ["--INPUT", str(source), *extra, "--OUTPUT", str(output)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert expected in run.stderr and "Traceback" not in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1
    assert not output.exists()


def test_summary_printed(tmp_path):
    source = syn.reconstruction(tmp_path / "reconstruction.json")
    run = subprocess.run(CLI + ["--INPUT", str(source), "--FORMAT_OUT", "csv", "--OUTPUT",
                                str(tmp_path / "x.csv")], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)["SUMMARY"]
    assert summary["written"] == ["x.csv", "x.prj"] and (tmp_path / "x.prj").exists()


def test_folder_input_and_inputs_never_overwritten(tmp_path):
    """A folder reads its recognised orientation files (a stray file is left out and said); an
    output whose sidecar would land on an input is refused before anything is written."""
    folder = tmp_path / "ortho"
    folder.mkdir()
    source = syn.reconstruction(tmp_path / "reconstruction.json")
    formats.write_orientations(opensfm.read_reconstruction(source), "orthority",
                               folder / "b_ext_param.geojson")
    (folder / "notes.txt").write_text("flown on a windy day\n")
    out = toolbox.run("orientation:convert", {"INPUT": str(folder), "FORMAT_OUT": "csv",
                                              "OUTPUT": str(tmp_path / "b.csv")})
    assert out["SUMMARY"]["oriented"] == 3 and out["SUMMARY"]["cameras"]
    assert any("notes.txt" in n for n in out["SUMMARY"]["notes"])
    before = (folder / "b_int_param.yaml").read_bytes()
    with pytest.raises(toolbox.errors.ParameterError, match="is an input"):
        toolbox.run("orientation:convert", {"INPUT": str(folder), "FORMAT_OUT": "orthority",
                                            "OUTPUT": str(folder / "b.geojson")})
    assert (folder / "b_int_param.yaml").read_bytes() == before
    assert not (folder / "b.geojson").exists()


def test_photo_algorithm_takes_an_orientation_file(tmp_path):
    """orientation:footprints given an Orthority GeoJSON as PROJECT (its interior YAML found
    beside it): one footprint per photo; the nadir camera's is 150 x 100 m and its centre lies
    where the principal point offset (12 px right, 24 px up at 120 m / 960 px: 1.5 m east,
    3 m south in the topocentric frame) turned by the meridian convergence puts it."""
    import geopandas

    source = syn.reconstruction(tmp_path / "reconstruction.json")
    formats.write_orientations(opensfm.read_reconstruction(source), "orthority",
                               tmp_path / "b_ext_param.geojson")
    toolbox.run("orientation:footprints", {"PROJECT": str(tmp_path / "b_ext_param.geojson"),
                                           "MEAN_HEIGHT": 30.0,
                                           "OUTPUT": str(tmp_path / "f.gpkg")})
    feet = geopandas.read_file(tmp_path / "f.gpkg", layer="footprints")
    assert sorted(feet["photo"]) == ["IMG_0", "IMG_1", "IMG_2"]
    nadir = feet[feet["photo"] == "IMG_0"].geometry.iloc[0]
    centre = opensfm.read_reconstruction(source).photos["IMG_0"].xyz
    assert nadir.area == pytest.approx(150.0 * 100.0, rel=1e-3)
    from pyproj import Proj

    gamma = np.radians(Proj("EPSG:32651").get_factors(syn.LON, syn.LAT).meridian_convergence)
    turn = np.array([[np.cos(gamma), -np.sin(gamma)], [np.sin(gamma), np.cos(gamma)]])
    offset = np.array([nadir.centroid.x - centre[0], nadir.centroid.y - centre[1]])
    assert offset == pytest.approx(turn @ [-1.5, -3.0], abs=0.01)


def test_a_film_camera_distortion_that_the_output_cannot_hold_is_a_warning(tmp_path):
    """A project camera with k3 and decentring converts to Orthority as a pinhole spec: the
    warning names every term left behind."""
    import yaml

    from toolbox.feedback import Feedback

    warnings = []

    class Collect(Feedback):
        def push_warning(self, message, *args, **kwargs):
            warnings.append(message)

    doc = {"version": 1, "crs": "EPSG:3003", "angle_unit": "rad",
           "cameras": [{"name": "rc", "principal_distance_mm": 153.0,
                        "image_size_px": [2000, 2000], "pixel_size_mm": 0.1,
                        "distortion": {"polynomial": {"k1": 2e-8, "k3": 1e-17, "p1": 2e-7,
                                                      "p2": -1e-7}}}],
           "photos": [{"id": "a", "camera": "rc", "exterior": {
               "X0": 1688000.0, "Y0": 4799500.0, "Z0": 1800.0, "omega": 0.01, "phi": 0.0,
               "kappa": 0.2}}]}
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(doc))
    toolbox.run("orientation:convert", {"INPUT": str(tmp_path / "p.yaml"),
                                        "FORMAT_OUT": "csv", "OUTPUT": str(tmp_path / "o.csv")},
                feedback=Collect())
    (warning,) = [w for w in warnings if "distortion" in w]
    assert "camera 'rc'" in warning and "not carried over" in warning
    assert all(term in warning for term in ("k1", "k2", "k3", "p1", "p2"))
