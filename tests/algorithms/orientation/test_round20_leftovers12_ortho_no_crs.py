"""An orthophoto without a CRS: orientation:control refused it ("ORTHO ... must be a north-up
georeferenced raster (a CRS and ...)"), report:ortho_check took it to be in the project's CRS
in silence. Both now take it to be in the project's CRS with a warning when its grid holds one
of their points, and refuse it (exit 2, naming ORTHO) when it holds none (a grid in pixels or
in another CRS's numbers). Scene: the ortho tests' (a photo rendered through the collinearity
equations over analytic terrain); the orthophoto is the texture itself on a 2.5 m grid, so the
labelled and the unlabelled copy must give the same measurements."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from tests.helpers_cli import cli, one_error

sys.path.insert(0, str(Path(__file__).parents[1] / "ortho"))
import ortho_scene as scene  # noqa: E402

PIXELS = [(250.5, 250.5), (550.5, 260.5), (400.5, 400.5), (260.5, 560.5), (540.5, 540.5)]
CELL = 2.5
WARNED = "ORTHO has no CRS: taken to be in PROJECT's CRS (EPSG:3003)"


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    from toolbox.photogrammetry.surface import DemSurface

    folder = tmp_path_factory.mktemp("ortho_no_crs")
    sc = scene.make_scene(folder)
    surface = DemSurface.from_transform(np.asarray(sc.dem, "float64"), sc.transform)
    px = np.array(PIXELS)
    hit = sc.photo.monoplot_pixels((px[:, 0], px[:, 1]), surface)
    assert hit.ok.all()
    (folder / "points.csv").write_text("id,X,Y,Z\n" + "".join(
        f"k{i},{x},{y},{z}\n" for i, (x, y, z) in enumerate(hit.xyz)))
    (folder / "image.csv").write_text("point_id,photo,col_px,row_px\n" + "".join(
        f"k{i},p1,{c},{r}\n" for i, (c, r) in enumerate(px)))
    left, top, n = scene.CENTRE[0] - 1000.0, scene.CENTRE[1] + 1000.0, 800
    gx, gy = np.meshgrid(left + (np.arange(n) + 0.5) * CELL, top - (np.arange(n) + 0.5) * CELL)
    ortho = np.clip(sc.texture(gx, gy), 0, 255).astype("uint8")
    profile = {"driver": "GTiff", "width": n, "height": n, "count": 1, "dtype": "uint8",
               "transform": Affine(CELL, 0, left, 0, -CELL, top)}
    with rasterio.open(folder / "ortho.tif", "w", crs=scene.CRS, **profile) as dst:
        dst.write(ortho[None])
    with rasterio.open(folder / "bare.tif", "w", **profile) as dst:
        dst.write(ortho[None])
    with rasterio.open(folder / "pixels.tif", "w", **profile | {  # a grid in pixels
            "transform": Affine(1.0, 0, 0.0, 0, -1.0, float(n))}) as dst:
        dst.write(ortho[None])
    for name in ("bare.tif", "pixels.tif"):
        with rasterio.open(folder / name) as check:
            assert check.crs is None
    return folder, sc


def rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_control_takes_an_ortho_without_crs_in_the_project_crs(case, tmp_path):
    folder, sc = case
    warned = {}
    for name in ("ortho", "bare"):
        feedback = toolbox.Feedback()
        toolbox.run("orientation:control", {
            "PROJECT": sc.project_path, "CONTROL": folder / "points.csv",
            "ORTHO": folder / f"{name}.tif", "OUTPUT": tmp_path / f"{name}.csv"}, feedback=feedback)
        warned[name] = [w for w in feedback.warnings if "ORTHO has no CRS" in w]
    assert warned["ortho"] == []
    assert len(warned["bare"]) == 1 and warned["bare"][0].startswith(WARNED) and \
        f"{len(PIXELS)} of the {len(PIXELS)} CONTROL points" in warned["bare"][0], warned
    labelled = rows(tmp_path / "ortho.csv")
    assert sum(r["status"] == "matched" for r in labelled) >= 3, labelled  # measured on it
    assert rows(tmp_path / "bare.csv") == labelled


def test_control_refuses_an_ortho_without_crs_off_the_points(case, tmp_path):
    folder, sc = case
    code, _, err = cli("run", "orientation:control", "--PROJECT", sc.project_path,
                       "--CONTROL", folder / "points.csv", "--ORTHO", folder / "pixels.tif",
                       "--OUTPUT", tmp_path / "t.csv")
    assert code == 2, err
    line = one_error(err)
    assert "ORTHO has no CRS and its grid (0..800, 0..800) holds none of the 5 CONTROL" in line
    assert not (tmp_path / "t.csv").exists()


def check_run(case, ortho: str, out: Path, feedback=None):
    folder, sc = case
    return toolbox.run("report:ortho_check", {
        "ORTHO": folder / ortho, "PROJECT": sc.project_path,
        "CHECK_POINTS": folder / "points.csv", "MEASUREMENTS": folder / "image.csv",
        "OUTPUT": out}, feedback=feedback)["STATISTICS"]


def test_ortho_check_warns_of_an_ortho_without_crs(case, tmp_path):
    feedback = toolbox.Feedback()
    bare = check_run(case, "bare.tif", tmp_path / "bare.csv", feedback)
    labelled = check_run(case, "ortho.tif", tmp_path / "labelled.csv")
    warned = [w for w in feedback.warnings if "ORTHO has no CRS" in w]
    assert len(warned) == 1 and warned[0].startswith(WARNED) and \
        f"{len(PIXELS)} of the {len(PIXELS)} CHECK_POINTS" in warned[0], feedback.warnings
    assert labelled["matched"] == len(PIXELS) and labelled["rmse_planimetric_m"] < 0.25 * CELL
    assert bare == labelled | {"ortho": "bare.tif"}
    assert rows(tmp_path / "bare.csv") == rows(tmp_path / "labelled.csv")


def test_ortho_check_refuses_an_ortho_without_crs_off_the_points(case, tmp_path):
    folder, sc = case
    code, _, err = cli("run", "report:ortho_check", "--ORTHO", folder / "pixels.tif",
                       "--PROJECT", sc.project_path, "--CHECK_POINTS", folder / "points.csv",
                       "--MEASUREMENTS", folder / "image.csv", "--OUTPUT", tmp_path / "o.csv")
    assert code == 2, err
    assert "ORTHO has no CRS and its grid (0..800, 0..800) holds none of the 5 " \
        "CHECK_POINTS" in one_error(err)
    assert not (tmp_path / "o.csv").exists()
