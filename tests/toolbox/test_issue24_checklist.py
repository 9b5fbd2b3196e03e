"""Issue 24, round four: the gaps the audit of the newer algorithms found, each with the test that
fails without its guard. Size guards of orientation:design (a block past the precision analysis
ran for minutes and took 14 GB) and dem:ground (MAX_WINDOW 1e9: MemoryError, exit 3); the CRS of
orientation:models (a string: EPSG:4326 accepted) and the area-of-use check of control points in
models / absolute / bundle; PIXEL_SIZE_MM named by stereo:epipolar and dem:match; SIGTERM during
dem:match (staged LAZ half-written: nothing left, the message says so)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import toolbox
from toolbox.cli import main
from toolbox.errors import InputDataError, ParameterError

sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "stereo"))
import stereo_scene as sc  # noqa: E402

E0, N0 = 1688000.0, 4799000.0


def never(*args, **kwargs):
    raise AssertionError("the heavy step ran before the size guard")


def one_error(stderr: str) -> str:
    lines = [ln for ln in stderr.strip().splitlines() if not ln.startswith("WARNING:")]
    assert len(lines) == 1 and lines[0].startswith("toolbox: error: "), stderr
    assert "Traceback" not in stderr
    return lines[0]


# -- size guards ----------------------------------------------------------------------------------
@pytest.mark.parametrize("changes, parameter, words", [
    ({"PHOTO_SCALE": 1}, "PHOTO_SCALE", "14,493 strips"),  # 0.23 m photos over 4 x 2.5 km
    ({"MAP_SCALE": 1000, "EXTENT": "0,0,1e7,1e7 [EPSG:3003]"}, "MAP_SCALE", "10,540 strips"),
    ({"PHOTO_SCALE": 1, "EXTENT": "0,0,1e7,1e7 [EPSG:3003]"}, "PHOTO_SCALE",
     "more than 714 stereo models"),  # 5e7 strips: refused before they are laid out
])
def test_design_refuses_a_block_too_large_before_laying_it_out(tmp_path, monkeypatch, changes,
                                                                parameter, words):
    from toolbox.triangulation import prediction

    monkeypatch.setattr(prediction, "predict", never)
    monkeypatch.setattr(prediction, "block_points", never)
    params = {"EXTENT": f"{E0 - 500},{N0 - 1000},{E0 + 3500},{N0 + 1500} [EPSG:3003]",
              "TERRAIN_HEIGHT": 300, "OUTPUT": tmp_path / "d.gpkg"} | changes
    started = time.perf_counter()
    with pytest.raises(ParameterError) as info:
        toolbox.run("orientation:design", params)
    text = str(info.value)
    assert info.value.name == parameter and text.startswith(parameter + " "), text
    assert words in text and "over the limit of 714" in text and "plan the block in parts" in text
    assert time.perf_counter() - started < 10
    assert list(tmp_path.iterdir()) == []
    # the same refusal in a pipeline's --validate, before any step runs
    pipe = tmp_path / "p.yaml"
    extent = params["EXTENT"]
    pipe.write_text("steps:\n  - algorithm: orientation:design\n    params: {EXTENT: '"
                    f"{extent}', {parameter}: {changes[parameter]}, OUTPUT: d.gpkg}}\n")
    result = CliRunner().invoke(main, ["batch", str(pipe), "--validate"])
    assert result.exit_code == 2 and parameter in one_error(result.stderr)


def test_design_of_an_ordinary_block_is_not_refused(tmp_path):
    out = toolbox.run("orientation:design", {
        "EXTENT": f"{E0},{N0},{E0 + 4000},{N0 + 2500} [EPSG:3003]", "MAP_SCALE": 5000,
        "TERRAIN_HEIGHT": 300, "OUTPUT": tmp_path / "d.gpkg"})
    assert 0 < out["STATISTICS"]["models"] <= 714


def test_ground_refuses_a_window_wider_than_the_data(tmp_path, monkeypatch):
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster
    from toolbox.terrain import ground_run

    z = 300.0 + np.add.outer(np.arange(30.0), np.arange(40.0)) * 0.1
    write_raster(tmp_path / "dsm.tif", z.astype("float32"), from_origin(E0, N0 + 120, 4, 4),
                 "EPSG:3003", nodata=-9999.0)
    params = {"DSM": tmp_path / "dsm.tif", "MAX_WINDOW": 1e9, "OUTPUT": tmp_path / "g.tif",
              "NONGROUND": tmp_path / "n.tif"}
    real = ground_run.smrf
    monkeypatch.setattr(ground_run, "smrf", never)
    with pytest.raises(ParameterError) as info:
        toolbox.run("dem:ground", params)
    text = str(info.value)
    assert info.value.name == "MAX_WINDOW" and "250,000,000 filter cells of 4" in text
    assert "wider than the data (39 x 29 cells)" in text  # cell centres 39 x 29 cells apart
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dsm.tif"]
    monkeypatch.setattr(ground_run, "smrf", real)
    toolbox.run("dem:ground", params | {"MAX_WINDOW": 40})  # 10 cells: filtered


def test_epipolar_pixel_size_is_named():
    """A PIXEL_SIZE_MM of 1 nm makes normalised images of 1e17 pixels: the parameter is named
    (it read 'the photos are too oblique to the base')."""
    from toolbox.stereo.epipolar import epipolar_geometry

    left, right = sc.photo("L"), sc.photo("R")
    with pytest.raises(ParameterError) as info:
        epipolar_geometry(left, right, pixel_mm=1e-6)
    assert info.value.name == "PIXEL_SIZE_MM" and "use a larger PIXEL_SIZE_MM" in str(info.value)
    geometry = epipolar_geometry(left, right, pixel_mm=0.383)
    assert 400 < geometry.height < 800


# -- CRS of the orientation tools ------------------------------------------------------------------
@pytest.fixture(scope="module")
def block(tmp_path_factory):
    from toolbox.demo.samples.bundle_block import make

    return make(tmp_path_factory.mktemp("bundle_block") / "data", {})


def test_models_crs_is_a_crs_in_metres_covering_the_control(block, tmp_path):
    base = {"INPUT": block["bundle_models"], "CONTROL": block["bundle_control"],
            "OUTPUT": tmp_path / "m.gpkg"}
    with pytest.raises(ParameterError, match="^CRS .*'abc'"):
        toolbox.run("orientation:models", base | {"CRS": "abc"})
    with pytest.raises(ParameterError, match="^CRS is in the geographic CRS EPSG:4326"):
        toolbox.run("orientation:models", base | {"CRS": "EPSG:4326"})
    with pytest.raises(InputDataError, match="^CONTROL: coordinates .* outside the area of use "
                                             "of EPSG:32632"):
        toolbox.run("orientation:models", base | {"CRS": "EPSG:32632"})
    assert list(tmp_path.iterdir()) == []
    toolbox.run("orientation:models", base | {"CRS": "EPSG:3003"})
    import geopandas as gpd

    assert gpd.read_file(tmp_path / "m.gpkg").crs.to_epsg() == 3003


def test_absolute_and_bundle_check_control_against_the_crs_area(block, tmp_path):
    model = np.array([[0, 0, 0], [10, 0, 1], [0, 10, 2], [10, 10, 0], [5, 5, 3.0]])
    ground = model * 2 + [E0, N0, 300.0]
    for name, xyz in (("m.csv", model), ("c.csv", ground)):
        (tmp_path / name).write_text("id,X,Y,Z\n" + "".join(
            f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(xyz)))
    base = {"INPUT": tmp_path / "m.csv", "CONTROL": tmp_path / "c.csv",
            "REPORT": tmp_path / "a.json"}
    with pytest.raises(InputDataError, match="^CONTROL: .* area of use of EPSG:32633"):
        toolbox.run("orientation:absolute", base | {"CRS": "EPSG:32633"})
    assert not (tmp_path / "a.json").exists()
    toolbox.run("orientation:absolute", base | {"CRS": "EPSG:3003"})
    # the bundle: the project's CRS is EPSG:3003, control moved to local coordinates
    lines = Path(block["bundle_control"]).read_text().splitlines()
    header = lines[0].split(",")
    ix, iy = header.index("X"), header.index("Y")
    local = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        for i, shift in ((ix, 1687000.0), (iy, 4796000.0)):
            if cells[i].strip():
                cells[i] = f"{float(cells[i]) - shift:.3f}"
        local.append(",".join(cells))
    (tmp_path / "local.csv").write_text("\n".join(local) + "\n")
    with pytest.raises(InputDataError, match="^CONTROL: coordinates .* outside the area of use"):
        toolbox.run("orientation:bundle", {"PROJECT": block["bundle_project"],
                                           "INPUT": block["bundle_measurements"],
                                           "CONTROL": tmp_path / "local.csv",
                                           "OUTPUT": tmp_path / "b.yaml"})
    assert not (tmp_path / "b.yaml").exists()


# -- SIGTERM during dem:match -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    from toolbox.photogrammetry.synthetic import hills_dem, wave_texture

    z, transform = hills_dem((sc.X0 - 300, sc.Y0 - 100, sc.X0 + 1300, sc.Y0 + 1100), cell=2.0,
                             relief=40.0, base=300.0, seed=5)
    texture = wave_texture(seed=2, wavelength=(8.0, 40.0), waves=40)
    return sc.make_pair(tmp_path_factory.mktemp("pair"), z, transform, texture,
                        names=("L", "R"), supersample=1)


def test_sigterm_during_dem_match_leaves_nothing(pair, tmp_path):
    """SIGTERM once the pair is being matched (the staged LAZ begun, the epipolar images in a
    temporary folder): exit 143, one line saying nothing was written, and nothing is: no
    output, no staging folder, no temporary folder."""
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    out.mkdir()
    tmp.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-m", "toolbox.cli", "run", "dem:match", "--PROJECT", str(pair.project),
         "--MIN_HEIGHT", "280", "--MAX_HEIGHT", "370", "--CELL_SIZE", "4", "--OUTPUT",
         str(out / "dsm.tif"), "--COUNT", str(out / "count.tif"), "--SPREAD",
         str(out / "spread.tif"), "--POINTS", str(out / "points.laz"), "--progress", "json"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
        env={**__import__("os").environ, "TMPDIR": str(tmp)})
    lines = []
    deadline = time.monotonic() + 180
    for line in proc.stderr:  # the progress lines: signal once the matching has begun
        lines.append(line)
        if '"percent": 6' in line or time.monotonic() > deadline:
            break
    staged = list(out.glob(".points.laz.*.part/points.laz"))
    assert staged, lines  # the LAZ begun
    assert list(tmp.glob("dem_match_*")), lines  # the epipolar images' folder
    assert proc.poll() is None, lines
    proc.send_signal(signal.SIGTERM)
    rest = proc.stderr.read()
    proc.wait(timeout=60)
    errors = [ln for ln in rest.splitlines() if not ln.startswith("{")]
    assert proc.returncode == 143, rest
    assert len(errors) == 1 and "terminated by SIGTERM; no output was written" in errors[0], rest
    assert list(out.iterdir()) == [] and list(tmp.iterdir()) == []


# -- batch --validate: a step without its required input ------------------------------------------
def test_validate_refuses_a_step_without_its_required_input(tmp_path):
    """The first of the issue's 8 pipelines (the others: test_batch_validate_gaps.py and
    test_error_contract.py::test_batch_validate_checks_values)."""
    pipe = tmp_path / "p.yaml"
    pipe.write_text("steps:\n  - name: shade\n    algorithm: dem:hillshade\n"
                    "    params: {OUTPUT: a.tif}\n")
    for extra in (["--validate"], []):
        result = CliRunner().invoke(main, ["batch", str(pipe), *extra])
        line = one_error(result.stderr)
        assert result.exit_code == 2 and "step 1 of 1 (dem:hillshade 'shade'): INPUT is required" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml"]


def test_overwrite_of_an_output_folder_removes_stale_sidecars_of_replaced_files(tmp_path):
    """--overwrite of mosaic:cut's sheets: a sheet's old .aux.xml (statistics QGIS would show)
    goes with the replaced sheet; a file the run does not plan is left alone."""
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    raster = tmp_path / "r.tif"
    write_raster(raster, np.ones((10, 10), "float32"), from_origin(E0, N0 + 10, 1, 1),
                 "EPSG:3003", nodata=-9999.0)
    folder = tmp_path / "cut"
    toolbox.run("mosaic:cut", {"INPUT": raster, "SCALE": 2000, "OUTPUT": folder})
    sheet = next(folder.glob("*.tif"))
    stale = folder / f"{sheet.name}.aux.xml"
    stale.write_text("<PAMDataset><Metadata><MDI key='STATISTICS_MAXIMUM'>1e9</MDI></Metadata>"
                     "</PAMDataset>")
    (folder / "notes.txt").write_text("mine")
    toolbox.run("mosaic:cut", {"INPUT": raster, "SCALE": 2000, "OUTPUT": folder}, overwrite=True)
    assert sheet.exists() and not stale.exists()
    assert (folder / "notes.txt").read_text() == "mine"


def test_convert_never_writes_over_a_file_of_an_input_folder(tmp_path):
    """orientation:convert with INPUT a folder and OUTPUT one of its files, --overwrite: the
    file was replaced by its conversion (exit 0); now refused, the file intact."""
    from toolbox.photogrammetry.synthetic import frame_photo

    photo = frame_photo((E0, N0, 1500.0), (0.01, -0.02, 0.3), width=100, height=100,
                        principal_distance_mm=150.0, crs="EPSG:3003", photo_id="p1")
    rot = photo.exterior.rotation
    folder = tmp_path / "orientations"
    folder.mkdir()
    patb = folder / "block.ori"
    values = [f"{v:.12f}" for v in rot.ravel()]  # PAT-B: id X0 Y0 Z0, then R in 5 + 4
    patb.write_text(f"p1 {E0:.3f} {N0:.3f} 1500.000\n{' '.join(values[:5])}\n"
                    f"{' '.join(values[5:])}\n")
    before = patb.read_bytes()
    params = {"INPUT": str(folder), "FORMAT": "patb", "CRS": "EPSG:3003", "FORMAT_OUT": "patb",
              "OUTPUT": patb}
    with pytest.raises(ParameterError, match=r"^OUTPUT '.*block\.ori' is the input INPUT"):
        toolbox.run("orientation:convert", params, overwrite=True)
    assert patb.read_bytes() == before and sorted(folder.iterdir()) == [patb]
    other = tmp_path / "other.ori"  # INPUT a comma-separated list: each of its files too
    other.write_bytes(before)
    with pytest.raises(ParameterError, match=r"^OUTPUT '.*other\.ori' is the input INPUT"):
        toolbox.run("orientation:convert", params | {"INPUT": f"{patb},{other}",
                                                     "OUTPUT": other}, overwrite=True)
    assert other.read_bytes() == before and patb.read_bytes() == before
    out = toolbox.run("orientation:convert", params | {"OUTPUT": tmp_path / "copy.ori"})
    assert out["SUMMARY"]["photos"] == 1


def test_relative_orientation_of_a_single_photo_names_input(block, tmp_path):
    """Measurements on one photo only: the message read "PHOTO2 photo None has no
    measurements"; it names INPUT and what it holds."""
    lines = Path(block["bundle_measurements"]).read_text().splitlines()
    header = lines[0].split(",")
    photo = header.index("photo")
    first = lines[1].split(",")[photo]
    (tmp_path / "one.csv").write_text("\n".join(
        [lines[0]] + [ln for ln in lines[1:] if ln.split(",")[photo] == first]) + "\n")
    result = CliRunner().invoke(main, ["run", "orientation:relative", "--PROJECT",
                                       str(block["bundle_project"]), "--INPUT",
                                       str(tmp_path / "one.csv"), "--OUTPUT",
                                       str(tmp_path / "r.csv")])
    line = one_error(result.stderr)
    assert result.exit_code == 2 and "INPUT measures 1 photo(s)" in line and first in line
    assert "None" not in line and not (tmp_path / "r.csv").exists()


def test_run_report_never_lands_on_a_file_of_an_input_folder(tmp_path):
    """report:quality reads the JSON run reports of REPORTS (a folder): --run-report pointed at
    one of them, with --overwrite, replaced it (exit 0); the files of an input folder are
    inputs too."""
    reports = tmp_path / "reports"
    reports.mkdir()
    victim = reports / "dem.json"
    victim.write_text('{"algorithm": "dem:idw", "parameters": {}, "outputs": {}}')
    before = victim.read_bytes()
    args = ["run", "report:quality", "--REPORTS", str(reports), "--OUTPUT",
            str(tmp_path / "q.html"), "--run-report", str(victim), "--overwrite"]
    result = CliRunner().invoke(main, args)
    line = one_error(result.stderr)
    assert result.exit_code == 2 and "--run-report" in line and "input REPORTS" in line
    assert victim.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_epipolar_refuses_an_image_of_another_size_than_the_camera(pair, tmp_path):
    """LEFT_IMAGE of another photo (1200 x 1200 px for a 600 x 600 px camera) was warped
    without a word (exit 0); ortho:photo already refused it."""
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    write_raster(tmp_path / "other.tif", np.full((1200, 1200), 90, "uint8"),
                 from_origin(0, 1200, 1, 1), None)
    with pytest.raises(InputDataError, match=r"^photo 'L': the raster .*other\.tif' is 1200 x "
                                             r"1200 px but the camera .* says 600 x 600"):
        toolbox.run("stereo:epipolar", {
            "PROJECT": pair.project, "LEFT": "L", "RIGHT": "R", "LEFT_IMAGE": tmp_path /
            "other.tif", "TERRAIN_HEIGHT": 320, "OUTPUT_LEFT": tmp_path / "l.tif",
            "OUTPUT_RIGHT": tmp_path / "r.tif", "TRANSFORM": tmp_path / "t.json"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.tif"]


def test_tin_to_raster_nodata_beyond_float32_is_refused(tmp_path, points_gpkg):
    """The sweep found NODATA 3.4028235677973366e+38 (just past float32's largest) crashing the
    GeoTIFF writer: refused before any work, naming NODATA and the float32 range; float64
    cells take it."""
    from tests.helpers_cli import assert_refused

    tin = tmp_path / "tin.gpkg"
    toolbox.run("tin:delaunay", {"INPUT": points_gpkg, "OUTPUT": tin})
    args = ["run", "tin:to_raster", "--TIN", str(tin), "--CELL_SIZE", "5", "--NODATA",
            "3.4028235677973366e+38", "--OUTPUT", str(tmp_path / "t.tif")]
    line = assert_refused(args, "NODATA 3.4028235677973366e+38 does not fit the float32",
                          (tmp_path / "t.tif",))
    assert "3.4028234663852886e+38" in line
    toolbox.run("tin:to_raster", {"TIN": tin, "CELL_SIZE": 5, "NODATA": 3.4028235677973366e+38,
                                  "DATA_TYPE": "float64", "OUTPUT": tmp_path / "t64.tif"})
