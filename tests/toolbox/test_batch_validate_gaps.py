"""``toolbox batch --validate`` runs every check the run makes before it writes (issue 24 §4):
OVERWRITE values, truncated rasters, the grid size guard, output folders landing on inputs,
size guards of the algorithms' check(); and pipeline variables expand recursively."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
from click.testing import CliRunner
from shapely.geometry import Point

from tests.helpers_cli import one_error
from toolbox.cli import main

sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
import ortho_scene as scene  # noqa: E402

E0, N0 = 1688000.0, 4799000.0


def batch(pipe: Path, *extra) -> tuple[int, str]:
    result = CliRunner().invoke(main, ["batch", str(pipe), *extra])
    assert "Traceback" not in result.stderr, result.stderr
    return result.exit_code, result.stderr



@pytest.fixture
def folder(tmp_path):
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    z = 300.0 + np.add.outer(np.arange(40.0), np.arange(50.0))
    write_raster(tmp_path / "dem.tif", z.astype("float32"), from_origin(E0, N0 + 400, 10, 10),
                 "EPSG:3003", nodata=-9999.0)
    data = (tmp_path / "dem.tif").read_bytes()
    (tmp_path / "cut.tif").write_bytes(data[: len(data) * 2 // 3])  # a copy cut short
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 400, (50, 2)) + [E0, N0]
    gpd.GeoDataFrame({"z": rng.uniform(100, 200, 50)},
                     geometry=[Point(x, y) for x, y in xy], crs="EPSG:3003"
                     ).to_file(tmp_path / "pts.gpkg")
    return tmp_path


def hillshade(params: str) -> str:
    return f"  - algorithm: dem:hillshade\n    params: {{{params}}}\n"


@pytest.mark.parametrize("label, steps, words", [
    ("overwrite maybe", hillshade("INPUT: dem.tif, OUTPUT: a.tif, OVERWRITE: maybe"),
     "OVERWRITE must be true or false, got 'maybe'"),
    ("truncated raster", hillshade("INPUT: cut.tif, OUTPUT: a.tif"),
     "INPUT '", ),
    ("grid size guard", "  - algorithm: dem:idw\n    params: {INPUT: pts.gpkg, CELL_SIZE: "
     "0.0001, OUTPUT: b.tif}\n", "CELL_SIZE 0.0001 gives a"),
    ("size guard of check()", "  - algorithm: mosaic:cut\n    params: {INPUT: dem.tif, SCALE: "
     "2000, SHEET_WIDTH: 0.001, OUTPUT: cut}\n", "SHEET_WIDTH"),
])
def test_validate_refuses_what_the_run_refuses(folder, label, steps, words):
    pipe = folder / "p.yaml"
    pipe.write_text("steps:\n" + steps)
    before = sorted(p.name for p in folder.iterdir())
    for extra in (["--validate"], []):
        code, err = batch(pipe, *extra)
        line = one_error(err)
        assert code == 2 and words in line, (label, line)
    if label == "truncated raster":
        assert "truncated" in line
    assert sorted(p.name for p in folder.iterdir()) == before


def test_validate_refuses_an_output_folder_over_the_photos(tmp_path):
    sc = scene.make_scene(tmp_path)
    pipe = tmp_path / "p.yaml"
    pipe.write_text("steps:\n  - algorithm: ortho:batch\n    params: {PROJECT: "
                    f"{sc.project_path.name}, DEM: {sc.dem_path.name}, FOLDER: ., "
                    "OUTPUT: o.json}\n")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    code, err = batch(pipe, "--validate", "--overwrite")
    line = one_error(err)
    assert code == 2 and sc.photo_path.name in line and "input" in line
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before


def test_variables_expand_recursively(folder):
    pipe = folder / "p.yaml"
    pipe.write_text('variables: {run: r1, out: "${run}/out", shade: "${out}/a.tif"}\n'
                    "steps:\n" + hillshade("INPUT: dem.tif, OUTPUT: '${shade}'"))
    code, err = batch(pipe, "--validate")
    assert code == 0, err
    code, err = batch(pipe)
    assert code == 0, err
    assert (folder / "r1" / "out" / "a.tif").exists()
    assert not any("$" in p.name for p in folder.rglob("*"))
    for variables, words in (('{a: "${b}", b: "${a}"}', "refers to itself through a -> b -> a"),
                             ('{a: "${nope}/x"}', "uses ${nope} but no such variable")):
        pipe.write_text(f"variables: {variables}\nsteps:\n"
                        + hillshade("INPUT: dem.tif, OUTPUT: '${a}/a.tif'"))
        code, err = batch(pipe, "--validate")
        assert code == 2 and words in one_error(err)


@pytest.mark.parametrize("first, second, words", [
    ("tin", "cv", "RESIDUALS '{out}/t_edges.shp' is also written by tin.OUTPUT"),
    ("cv", "tin", "OUTPUT '{out}/t.shp' (its layer file '{out}/t_edges.shp') is also written "
                  "by cv.RESIDUALS"),
])
def test_validate_refuses_two_steps_writing_one_layer_file(folder, first, second, words):
    """A Shapefile output writes its other layers beside it (t.shp's edges in t_edges.shp):
    another step writing that file is two steps writing one file, refused before any run."""
    steps = {
        "tin": "  - name: tin\n    algorithm: tin:delaunay\n    params: {INPUT: pts.gpkg, "
               "Z_FIELD: z, OUTPUT: out/t.shp}\n",
        "cv": "  - name: cv\n    algorithm: dem:cross_validate\n    params: {INPUT: pts.gpkg, "
              "Z_FIELD: z, METHODS: idw, OUTPUT: out/cv.json, RESIDUALS: out/t_edges.shp}\n"}
    pipe = folder / "p.yaml"
    pipe.write_text("steps:\n" + steps[first] + steps[second])
    for extra in (["--validate"], ["--overwrite"]):
        code, err = batch(pipe, *extra)
        assert code == 2 and words.format(out=folder / "out") in one_error(err), err
    assert not (folder / "out").exists()


def test_validate_sees_what_a_vrt_reads_and_takes_feet_where_the_run_does(folder):
    """A later step writing the file an earlier step's VRT input reads (the DEM under dem.vrt)
    passed --validate (the run itself refuses it); and --validate refused a CRS in feet for the
    gridding, which the run accepts."""
    import subprocess

    if shutil.which("gdal_translate") is None:
        pytest.skip("gdal_translate not installed")
    subprocess.run(["gdal_translate", "-q", "-of", "VRT", str(folder / "dem.tif"),
                    str(folder / "dem.vrt")], check=True)
    pipe = folder / "p.yaml"
    pipe.write_text("steps:\n" + hillshade("INPUT: dem.vrt, OUTPUT: shade.tif")
                    + "  - algorithm: dem:idw\n    params: {INPUT: pts.gpkg, Z_FIELD: z, "
                      "CELL_SIZE: 20, OUTPUT: dem.tif}\n")
    before = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    code, err = batch(pipe, "--validate", "--overwrite")
    line = one_error(err)
    assert code == 2 and "dem.tif" in line and "an input is never overwritten" in line, line
    assert {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()} == before
    feet = gpd.read_file(folder / "pts.gpkg").translate(1_000_000 - E0, 200_000 - N0)
    gpd.GeoDataFrame({"z": gpd.read_file(folder / "pts.gpkg")["z"]}, geometry=feet.values,
                     crs=None).set_crs("EPSG:2263", allow_override=True).to_file(
        folder / "ft.gpkg")
    pipe.write_text("steps:\n  - algorithm: dem:idw\n    params: {INPUT: ft.gpkg, Z_FIELD: z, "
                    "CELL_SIZE: 20, OUTPUT: ft.tif}\n")
    code, err = batch(pipe, "--validate")
    assert code == 0, err
