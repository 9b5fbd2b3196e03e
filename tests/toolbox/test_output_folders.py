"""Output folders (OutputFolder + Algorithm.planned_files) are protected like OUTPUT (issue 24 §1):
every planned file is checked against every input (path, sidecars, a project's photos, inode),
an existing one needs --overwrite, the files are staged and moved on success, and a failure at
any point (during the work or during the final moves) leaves the folder as it was."""

from __future__ import annotations

import errno
import hashlib
import os
import sys
from pathlib import Path

import pytest

import toolbox
from tests import helpers_cli
from tests.helpers_cli import one_error
from toolbox.errors import OutputExistsError, OutputWriteError

sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "attribution"))
from restitution_files import make_files  # noqa: E402


def cli(*args) -> tuple[int, str]:
    code, _, err = helpers_cli.cli(*args)
    return code, err



def hashes(folder: Path) -> dict[str, str]:
    """Every entry of ``folder`` (hidden ones too) -> content hash."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo's ortho project folder (3 photos named by their ids) and the demo DEM."""
    from toolbox.demo.samples import ortho, terrain
    from toolbox.raster.writer import write_raster

    root = tmp_path_factory.mktemp("ortho_demo")
    z, transform = terrain.terrain()
    write_raster(root / "dem.tif", z, transform, terrain.CRS, nodata=-9999.0)
    ortho.make(root, {})
    return root


@pytest.fixture
def block(demo, tmp_path):
    """A private copy of the project folder: ``x/`` with project.yaml and the photos."""
    import shutil

    shutil.copytree(demo / "siena_ortho", tmp_path / "x")
    return tmp_path / "x", demo / "dem.tif"


def batch_args(project: Path, dem: Path, folder: Path, out: Path, *extra, cell: float = 8) -> list:
    return ["run", "ortho:batch", "--PROJECT", project, "--DEM", dem, "--CELL_SIZE", cell,
            "--FOLDER", folder, "--OUTPUT", out, *extra]


def test_issue_recipe_folder_holding_the_photos_is_refused(block, tmp_path):
    """The issue's recipe: FOLDER is the project folder, whose photos are named <photo id>.tif:
    exit 2, one line, every input byte-identical, nothing written (also with --overwrite)."""
    x, dem = block
    before = hashes(x)
    for extra in ((), ("--overwrite",)):
        code, err = cli(*batch_args(x / "project.yaml", dem, x, tmp_path / "o.json", *extra))
        line = one_error(err)
        assert code == 2 and "FOLDER" in line and "1_7150.tif" in line and "input" in line
        assert hashes(x) == before
        assert not (tmp_path / "o.json").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x"]  # no staging folder left


def test_dem_named_like_a_photo_and_hard_link_are_refused(block, tmp_path):
    x, dem = block
    folder = tmp_path / "orthos"
    folder.mkdir()
    dem_copy = folder / "1_7151.tif"  # the DEM, named like a photo, in FOLDER
    dem_copy.write_bytes(dem.read_bytes())
    code, err = cli(*batch_args(x / "project.yaml", dem_copy, folder, tmp_path / "o.json",
                                "--overwrite"))
    assert code == 2 and "DEM" in one_error(err)
    dem_copy.unlink()
    os.link(x / "2_7139.tif", folder / "2_7139.tif")  # another name of an input photo
    before = hashes(x)
    code, err = cli(*batch_args(x / "project.yaml", dem, folder, tmp_path / "o.json",
                                "--overwrite"))
    assert code == 2 and "2_7139.tif" in one_error(err) and "input" in one_error(err)
    assert hashes(x) == before


def test_existing_files_need_overwrite_and_others_are_left_alone(block, tmp_path):
    x, dem = block
    folder = tmp_path / "orthos"
    folder.mkdir()
    (folder / "1_7150.tif").write_bytes(b"an older ortho")
    (folder / "notes.txt").write_text("mine")
    code, err = cli(*batch_args(x / "project.yaml", dem, folder, tmp_path / "o.json"))
    line = one_error(err)
    assert code == 2 and "1_7150.tif" in line and "--overwrite" in line
    assert (folder / "1_7150.tif").read_bytes() == b"an older ortho"
    assert sorted(p.name for p in folder.iterdir()) == ["1_7150.tif", "notes.txt"]
    code, err = cli(*batch_args(x / "project.yaml", dem, folder, tmp_path / "o.json",
                                "--overwrite"))
    assert code == 0, err
    assert sorted(p.name for p in folder.iterdir()) == ["1_7150.tif", "1_7151.tif",
                                                        "2_7139.tif", "notes.txt"]
    assert (folder / "1_7150.tif").read_bytes()[:2] in (b"II", b"MM")  # a TIFF now
    assert (folder / "notes.txt").read_text() == "mine"
    import json

    listed = json.loads((tmp_path / "o.json").read_text())["orthos"]
    assert listed == [str(folder / f"{p}.tif") for p in ("1_7150", "1_7151", "2_7139")]


def test_failure_midway_leaves_nothing(block, tmp_path, monkeypatch):
    """A full disk at the second photo: no ortho in FOLDER (the first was complete), no
    staging folder, and the message says nothing was written."""
    from toolbox.ortho import block as ortho_block

    x, dem = block
    real, calls = ortho_block.run_task, []

    def failing(task):
        calls.append(task)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(task)

    monkeypatch.setattr(ortho_block, "run_task", failing)
    folder = tmp_path / "orthos"
    params = {"PROJECT": x / "project.yaml", "DEM": dem, "CELL_SIZE": 8, "WORKERS": 1,
              "FOLDER": folder, "OUTPUT": tmp_path / "o.json"}
    with pytest.raises(OutputWriteError, match="nothing was written"):
        toolbox.run("ortho:batch", params)
    assert len(calls) >= 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x"]  # no FOLDER, no staging


def test_failed_commit_restores_the_replaced_files(block, tmp_path, monkeypatch):
    """--overwrite over three older orthos, the last move fails: the two moved already are
    undone (the older files are back), nothing new is left."""
    from toolbox.io import staging

    x, dem = block
    folder = tmp_path / "orthos"
    folder.mkdir()
    for pid in ("1_7150", "1_7151", "2_7139"):
        (folder / f"{pid}.tif").write_text(f"old {pid}")
    before = hashes(folder)
    real, moves = os.replace, []

    def failing_replace(src, dst):
        if Path(dst).parent == folder and Path(dst).suffix == ".tif":
            moves.append(dst)
            if len(moves) == 3:
                raise OSError(errno.EIO, "Input/output error")
        return real(src, dst)

    monkeypatch.setattr(staging.os, "replace", failing_replace)
    params = {"PROJECT": x / "project.yaml", "DEM": dem, "CELL_SIZE": 8,
              "FOLDER": folder, "OUTPUT": tmp_path / "o.json"}
    with pytest.raises(OutputWriteError):
        toolbox.run("ortho:batch", params, overwrite=True)
    assert len(moves) >= 3  # the third failed; the undo restores the first two
    assert hashes(folder) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["orthos", "x"]


def test_style_sidecars_need_overwrite(tmp_path):
    files = make_files(tmp_path)
    out = tmp_path / "coded.gpkg"
    sidecar = tmp_path / "coded.gpkg.FAB01002.qml"
    sidecar.write_text("<qgis>my own style</qgis>")
    args = ["run", "attribution:apply", "--INPUT", files["export"], "--CODES", files["codes"],
            "--PARAMETERS", files["params"], "--CRS", "EPSG:3003", "--STYLE_FILES", "true",
            "--OUTPUT", out]
    code, err = cli(*args)
    line = one_error(err)
    assert code == 2 and "OUTPUT" in line and sidecar.name in line and "--overwrite" in line
    assert sidecar.read_text() == "<qgis>my own style</qgis>" and not out.exists()
    code, err = cli(*args, "--overwrite")
    assert code == 0, err
    assert "my own style" not in sidecar.read_text()
    # a sidecar pattern never lands on an input either
    victim = tmp_path / "x.gpkg.codes.qml"
    victim.write_text("input")
    code, err = cli("run", "attribution:apply", "--INPUT", files["export"], "--CODES", victim,
                    "--PARAMETERS", files["params"], "--CRS", "EPSG:3003", "--STYLE_FILES",
                    "true", "--OUTPUT", tmp_path / "x.gpkg", "--overwrite")
    assert code == 2 and "would write" in one_error(err) and "input CODES" in one_error(err)
    assert victim.read_text() == "input"


def test_mosaic_cut_sheet_equal_to_an_input_is_refused(tmp_path):
    """A sheet file named like the input raster, in the input's folder: refused even with
    --overwrite (the old OutputFolder refused only a folder holding an input)."""
    import numpy as np
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    raster = tmp_path / "1688_5998.tif"  # the name of the sheet holding it at 1:2000
    write_raster(raster, np.ones((10, 10), "float32"), from_origin(1688000, 4799010, 1, 1),
                 "EPSG:3003", nodata=-9999.0)
    before = raster.read_bytes()
    with pytest.raises(toolbox.ParameterError, match="input"):
        toolbox.run("mosaic:cut", {"INPUT": raster, "SCALE": 2000, "OUTPUT": tmp_path},
                    overwrite=True)
    assert raster.read_bytes() == before
    out = toolbox.run("mosaic:cut", {"INPUT": raster, "SCALE": 2000,
                                     "OUTPUT": tmp_path / "s"})["OUTPUT"]
    assert sorted(p.name for p in Path(out).iterdir()) == ["1688_5998.tif", "sheets.gpkg"]
    with pytest.raises(OutputExistsError, match="1688_5998.tif"):
        toolbox.run("mosaic:cut", {"INPUT": raster, "SCALE": 2000, "OUTPUT": tmp_path / "s"})


def test_overwrite_removes_the_stale_aux_xml_of_a_replaced_raster(block, tmp_path):
    """--overwrite of a GeoTIFF: the old .aux.xml (statistics QGIS would show) goes with the
    old file; without --overwrite nothing is touched."""
    _, dem = block
    out = tmp_path / "hs.tif"
    toolbox.run("dem:hillshade", {"INPUT": dem, "OUTPUT": out})
    aux = tmp_path / "hs.tif.aux.xml"
    aux.write_text("<PAMDataset><Metadata><MDI key='STATISTICS_MAXIMUM'>1e9</MDI></Metadata>"
                   "</PAMDataset>")
    with pytest.raises(OutputExistsError):
        toolbox.run("dem:hillshade", {"INPUT": dem, "OUTPUT": out})
    assert aux.exists()
    toolbox.run("dem:hillshade", {"INPUT": dem, "OUTPUT": out}, overwrite=True)
    assert not aux.exists() and out.exists()


def test_folder_holding_the_images_of_images_is_refused(block, tmp_path):
    """IMAGES names a folder (not files): its photos are inputs too."""
    import shutil

    x, dem = block
    images = tmp_path / "scans"
    images.mkdir()
    for pid in ("1_7150", "1_7151", "2_7139"):
        shutil.copy(x / f"{pid}.tif", images / f"{pid}.tif")
    before = hashes(images)
    code, err = cli(*batch_args(x / "project.yaml", dem, images, tmp_path / "o.json",
                                "--IMAGES", images, "--overwrite"))
    line = one_error(err)
    assert code == 2 and "FOLDER" in line and "IMAGES" in line
    assert hashes(images) == before


@pytest.mark.parametrize("fmt, name", [("orthority", "ext.geojson"), ("csv", "ext.csv"),
                                       ("patb", "ext.ori")])
def test_photos_another_programs_project_finds_by_stem_are_inputs(block, tmp_path, fmt, name):
    """Found by the I/O sweep: with an Orthority GeoJSON or CSV (or PAT-B) project, whose photos
    are found by file stem in its folder, ortho:batch FOLDER and ortho:photo OUTPUT replaced
    the photos with --overwrite (with the YAML project they were refused). Refused in one line
    naming the parameter, PROJECT and the photo; every file byte-identical, nothing written."""
    import yaml

    x, dem = block
    project = x / name
    toolbox.run("orientation:convert", {"INPUT": str(x / "project.yaml"), "FORMAT_OUT": fmt,
                                        "OUTPUT": project})
    if fmt != "orthority":  # the cameras beside it (PAT-B names none: the first for all)
        toolbox.run("orientation:convert", {"INPUT": str(x / "project.yaml"), "FORMAT_OUT":
                                            "orthority", "OUTPUT": tmp_path / "c.geojson"})
        cameras = yaml.safe_load((tmp_path / "c_int_param.yaml").read_text(encoding="utf-8"))
        if fmt == "patb":
            cameras = dict([next(iter(cameras.items()))])
        (x / "cam_int_param.yaml").write_text(yaml.safe_dump(cameras), encoding="utf-8")
    before = hashes(x)
    code, err = cli(*batch_args(project, dem, x, tmp_path / "o.json", "--overwrite"))
    line = one_error(err)
    assert code == 2 and f"FOLDER would write '{x / '1_7150.tif'}', which is the input " \
        "PROJECT" in line, line
    code, err = cli("run", "ortho:photo", "--INPUT", x / "1_7151.tif", "--PROJECT", project,
                    "--PHOTO", "1_7151", "--DEM", dem, "--CELL_SIZE", 8, "--OUTPUT",
                    x / "2_7139.tif", "--overwrite")
    line = one_error(err)
    assert code == 2 and f"OUTPUT '{x / '2_7139.tif'}' is the input PROJECT" in line, line
    assert hashes(x) == before and not (tmp_path / "o.json").exists()


def test_sigterm_after_the_first_ortho_leaves_the_folder_as_it_was(block, tmp_path):
    """A real SIGTERM once the first ortho is complete in the staged folder: exit 143, the
    message says nothing was written, and it is true (FOLDER holds only what it held)."""
    import signal
    import subprocess
    import time

    x, dem = block
    folder = tmp_path / "orthos"
    folder.mkdir()
    (folder / "notes.txt").write_text("mine")
    # 0.5 m cells: about 0.2 s an ortho, so that the run is still going when the first one is
    # seen (at 8 m the two others and the commit took less than the 0.05 s between looks, and
    # the run had finished: exit 0 before the signal)
    proc = subprocess.Popen(
        [sys.executable, "-m", "toolbox.cli", *map(str, batch_args(
            x / "project.yaml", dem, folder, tmp_path / "o.json", "--WORKERS", 1, cell=0.5))],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if list(tmp_path.glob(".orthos.*.part/orthos/1_7150.tif")):
            break
        time.sleep(0.05)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and "no output was written" in err, err
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["orthos", "x"]
