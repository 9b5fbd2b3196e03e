"""A DEM tagged with a vertical CRS (EGM96 height: its PROJ grid egm96_15.gtx is on this machine)
under photos whose heights are ellipsoidal: the DEM's heights are converted once, against pyproj's
own Transformer evaluated at every DEM cell (the oracle) and the system's gdaltransform at
49 cells (a second one, with the system's PROJ); the ortho equals the one made on the
oracle's ellipsoidal DEM, and differs (by ~48 m of heights) from the one that uses the EGM96
heights as they are. Same datum: no conversion. A grid missing (EGM2008 here): a one-line refusal
naming the grid, nothing written."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from pyproj import CRS, Transformer
from pyproj.transformer import TransformerGroup

import toolbox
from toolbox.errors import InputDataError
from toolbox.io.raster import open_raster_info
from toolbox.ortho.vertical import ELLIPSOIDAL, dem_for_photos, parse_heights, use_system_grids
from toolbox.photogrammetry.synthetic import (
    frame_photo,
    hills_dem,
    render_photo,
    wave_texture,
    write_photo,
)
from toolbox.raster.writer import write_raster

UTM = "EPSG:32632"  # WGS 84 / UTM 32N, near Siena
EGM96 = "EPSG:32632+5773"
BOUNDS = (686000.0, 4795000.0, 689200.0, 4798200.0)
CENTRE = (687600.0, 4796600.0, 1800.0)
ANGLES = (0.02, -0.015, 0.4)


def egm96_available() -> bool:
    use_system_grids()
    return TransformerGroup(CRS(EGM96), CRS(UTM).to_3d(), always_xy=True).best_available


pytestmark = pytest.mark.skipif(not egm96_available(),
                                reason="the EGM96 geoid grid (egm96_15.gtx) is not installed")


def oracle_ellipsoidal(z: np.ndarray, transform) -> np.ndarray:
    """Every DEM cell's EGM96 height -> ellipsoidal, pyproj point by point."""
    rows, cols = np.indices(z.shape)
    x, y = transform * (cols + 0.5, rows + 0.5)
    tr = Transformer.from_crs(CRS(EGM96), CRS(UTM).to_3d(), always_xy=True)
    _, _, h = tr.transform(x.ravel(), y.ravel(), z.astype("float64").ravel())
    return np.asarray(h).reshape(z.shape)


def vertical_scene(folder, size: int = 600, relief: float = 200.0,
                   dem_name: str = "dem_egm96.tif", bounds=BOUNDS, centre=CENTRE):
    """A ``size`` px photo ``p1.tif`` rendered with ellipsoidal heights and its
    ``project.yaml``; its DEM ``dem_name`` stored in EGM96 heights (tagged EPSG:32632+5773,
    values = ellipsoidal - N from pyproj). Returns the EGM96 heights and the DEM's transform."""
    z_ell, transform = hills_dem(bounds, cell=10.0, relief=relief, base=250.0, seed=3)
    to_egm = Transformer.from_crs(CRS(UTM).to_3d(), CRS(EGM96), always_xy=True)
    rows, cols = np.indices(z_ell.shape)
    x, y = transform * (cols + 0.5, rows + 0.5)
    _, _, z_egm = to_egm.transform(x.ravel(), y.ravel(), z_ell.astype("float64").ravel())
    z_egm = np.asarray(z_egm, dtype="float32").reshape(z_ell.shape)
    write_raster(folder / dem_name, z_egm, transform, CRS(EGM96), nodata=-9999.0)
    photo = frame_photo(centre, ANGLES, width=size, height=size, crs=UTM)
    texture = wave_texture(seed=7, wavelength=(40.0, 120.0))
    write_photo(folder / "p1.tif", render_photo(photo, z_ell, transform, texture, dtype="uint8"))
    camera = {"name": "synthetic", "principal_distance_mm": 153.0, "image_size_px": [size, size],
              "pixel_size_mm": 230.0 / size, "frame_size_mm": [230.0, 230.0]}
    doc = {"crs": UTM, "angle_unit": "rad", "cameras": [camera],
           "photos": [{"id": "p1", "camera": "synthetic", "image": "p1.tif",
                       "exterior": dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                                            [*centre, *ANGLES], strict=True))}]}
    (folder / "project.yaml").write_text(yaml.safe_dump(doc))
    return z_egm, transform


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """:func:`vertical_scene`, and the oracle's ellipsoidal DEM."""
    folder = tmp_path_factory.mktemp("vertical")
    z_egm, transform = vertical_scene(folder)
    write_raster(folder / "dem_ellipsoidal.tif", oracle_ellipsoidal(z_egm, transform)
                 .astype("float32"), transform, CRS(UTM), nodata=-9999.0)
    return folder, z_egm, transform


def test_conversion_equals_pyproj_at_every_cell(scene, tmp_path):
    folder, z_egm, transform = scene
    dem, note = dem_for_photos(open_raster_info(folder / "dem_egm96.tif", "DEM"), ELLIPSOIDAL,
                               tmp_path)
    assert note.converted and "EGM96" in note.dem and note.photos == "ellipsoidal heights"
    with rasterio.open(dem.path) as src:
        converted = src.read(1).astype("float64")
    truth = oracle_ellipsoidal(z_egm, transform)
    assert np.abs(converted - truth).max() < 2e-3  # float32 of ~400 m is 3e-5 m
    shift = truth - z_egm
    assert 40 < shift.min() < shift.max() < 55  # the geoid near Siena: ~48 m
    assert note.shift_m[0] == pytest.approx(shift.min(), abs=2e-3)


def test_conversion_equals_the_system_gdaltransform(scene, tmp_path):
    """A second oracle, independent of the pyproj wheel: the system's GDAL and PROJ
    (``gdaltransform`` with /usr/share/proj's egm96_15.gtx), EGM96 height -> WGS 84
    ellipsoidal height (EPSG:4979) at cells spread over the DEM."""
    import shutil

    if shutil.which("gdaltransform") is None:
        pytest.skip("GDAL's command-line tools (gdal-bin) are not installed")
    folder, z_egm, transform = scene
    dem, _ = dem_for_photos(open_raster_info(folder / "dem_egm96.tif", "DEM"), ELLIPSOIDAL,
                            tmp_path)
    with rasterio.open(dem.path) as src:
        converted = src.read(1).astype("float64")
    rows, cols = np.meshgrid(np.linspace(0, z_egm.shape[0] - 1, 7).astype(int),
                             np.linspace(0, z_egm.shape[1] - 1, 7).astype(int), indexing="ij")
    x, y = transform * (cols.ravel() + 0.5, rows.ravel() + 0.5)
    z = z_egm[rows.ravel(), cols.ravel()].astype("float64")
    text = "\n".join(f"{float(a)!r} {float(b)!r} {float(c)!r}"
                     for a, b, c in zip(x, y, z, strict=True))
    run = subprocess.run(["gdaltransform", "-s_srs", EGM96, "-t_srs", "EPSG:4979"], input=text,
                         capture_output=True, text=True, env={"PROJ_NETWORK": "OFF",
                                                              "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stderr
    h = np.array([float(line.split()[2]) for line in run.stdout.split("\n") if line.strip()])
    if np.allclose(h, z):
        pytest.skip("the system PROJ has no EGM96 grid (gdaltransform left the heights)")
    assert np.abs(converted[rows.ravel(), cols.ravel()] - h).max() < 2e-3


def ortho(folder: Path, dem: str, out: Path, **extra) -> dict:
    params = {"INPUT": folder / "p1.tif", "PROJECT": folder / "project.yaml",
              "DEM": folder / dem, "CELL_SIZE": 6.0, "EXTENT": "686800,4795800,688400,4797400",
              "OUTPUT": out, **extra}
    return toolbox.run("ortho:photo", params)["STATISTICS"]


def test_ortho_on_an_egm96_dem_with_ellipsoidal_photos(scene, tmp_path):
    folder, _, _ = scene
    stats = ortho(folder, "dem_egm96.tif", tmp_path / "converted.tif", HEIGHTS="ellipsoidal")
    assert stats["heights"]["converted"] is True
    assert "converted once from EGM96 height" in stats["heights"]["note"]
    reference = ortho(folder, "dem_ellipsoidal.tif", tmp_path / "reference.tif")
    assert reference["heights"]["converted"] is False
    unconverted = ortho(folder, "dem_egm96.tif", tmp_path / "as_is.tif")
    assert "states none" in unconverted["heights"]["note"]
    read = {}
    for name in ("converted", "reference", "as_is"):
        with rasterio.open(tmp_path / f"{name}.tif") as src:
            read[name] = src.read().astype("float64")
            assert src.crs.to_epsg() == 32632
    ok = (read["converted"][-1] > 0) & (read["reference"][-1] > 0)
    assert ok.mean() > 0.5
    assert np.abs(read["converted"][0] - read["reference"][0])[ok].mean() < 0.2
    # 48 m of height error, ~5 m on the ground at this tilt: the images differ
    both = ok & (read["as_is"][-1] > 0)
    assert np.abs(read["as_is"][0] - read["reference"][0])[both].mean() > 5.0


def test_same_datum_is_used_as_is(scene, tmp_path):
    folder, _, _ = scene
    info = open_raster_info(folder / "dem_egm96.tif", "DEM")
    dem, note = dem_for_photos(info, parse_heights("EPSG:5773"), tmp_path)
    assert dem is info and not note.converted and "no conversion" in note.text
    assert not any(tmp_path.iterdir())
    # the project's compound CRS states the same datum: no conversion either
    doc = yaml.safe_load((folder / "project.yaml").read_text())
    doc["crs"] = EGM96
    (tmp_path / "p1.tif").symlink_to(folder / "p1.tif")
    (tmp_path / "project.yaml").write_text(yaml.safe_dump(doc))
    stats = toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif",
                                        "PROJECT": tmp_path / "project.yaml",
                                        "DEM": folder / "dem_egm96.tif", "CELL_SIZE": 16.0,
                                        "OUTPUT": tmp_path / "o.tif"})["STATISTICS"]
    assert stats["heights"]["converted"] is False
    assert "both in EGM96 height" in stats["heights"]["note"]


def test_missing_grid_is_a_one_line_refusal_naming_it(scene, tmp_path):
    use_system_grids()
    with warnings.catch_warnings():  # "best transformation is not available": what is tested
        warnings.simplefilter("ignore", UserWarning)
        group = TransformerGroup(CRS(EGM96), CRS("EPSG:32632+3855"), always_xy=True)
    if group.best_available:
        pytest.skip("the EGM2008 grid is installed here")
    folder, _, _ = scene
    with pytest.raises(InputDataError, match="needs the PROJ grid us_nga_egm08_25.tif"):
        dem_for_photos(open_raster_info(folder / "dem_egm96.tif", "DEM"),
                       parse_heights("EPSG:3855"), tmp_path)
    out = tmp_path / "o.tif"
    run = subprocess.run([sys.executable, "-m", "toolbox", "run", "ortho:photo", "--INPUT",
                          str(folder / "p1.tif"), "--PROJECT", str(folder / "project.yaml"),
                          "--DEM", str(folder / "dem_egm96.tif"), "--HEIGHTS", "EPSG:3855",
                          "--OUTPUT", str(out)], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "us_nga_egm08_25.tif" in lines[0] and "EGM96" in lines[0]
    assert not out.exists() and not list(tmp_path.glob(".*"))


def test_heights_parameter_errors(scene, tmp_path):
    folder, _, _ = scene
    run = subprocess.run([sys.executable, "-m", "toolbox", "run", "ortho:photo", "--INPUT",
                          str(folder / "p1.tif"), "--PROJECT", str(folder / "project.yaml"),
                          "--DEM", str(folder / "dem_egm96.tif"), "--HEIGHTS", "EPSG:32632",
                          "--OUTPUT", str(tmp_path / "o.tif")], capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and "HEIGHTS" in run.stderr
    assert "not a vertical CRS" in run.stderr


def test_ortho_batch_converts_once_and_states_it(scene, tmp_path):
    folder, _, _ = scene
    stats = toolbox.run("ortho:batch", {"PROJECT": folder / "project.yaml",
                                        "DEM": folder / "dem_egm96.tif", "HEIGHTS": "ellipsoidal",
                                        "CELL_SIZE": 12.0, "FOLDER": tmp_path / "orthos",
                                        "OUTPUT": tmp_path / "orthos.json"})["STATISTICS"]
    assert stats["done"] == 1 and stats["heights"]["converted"] is True
    reference = toolbox.run("ortho:batch", {"PROJECT": folder / "project.yaml",
                                            "DEM": folder / "dem_ellipsoidal.tif",
                                            "CELL_SIZE": 12.0, "FOLDER": tmp_path / "reference",
                                            "OUTPUT": tmp_path / "reference.json"})["STATISTICS"]
    assert reference["heights"]["converted"] is False
    with rasterio.open(tmp_path / "orthos" / "p1.tif") as a, \
            rasterio.open(tmp_path / "reference" / "p1.tif") as b:
        assert a.bounds == b.bounds
        x, y = a.read().astype("float64"), b.read().astype("float64")
    ok = (x[-1] > 0) & (y[-1] > 0)
    assert ok.mean() > 0.5 and np.abs(x[0] - y[0])[ok].mean() < 0.2
    assert sorted(p.name for p in (tmp_path / "orthos").iterdir()) == ["p1.tif"]


def test_datum_note_never_compares_a_crs_with_a_string(monkeypatch):
    """The heights note of a DEM with a vertical CRS (the NGI DEM's EGM2008) asks 'ellipsoidal?'
    with a type test: pyproj compares a CRS with a string by parsing the string as a CRS (a PROJ
    database search, 0.2-0.4 s CPU in every ortho run)."""
    from toolbox.ortho.vertical import datum_label, is_ellipsoidal, vertical_part

    egm2008 = vertical_part(CRS.from_user_input("EPSG:32735+3855"))
    parsed: list[str] = []
    original = CRS.from_user_input

    def counting(value, **kwargs):
        if isinstance(value, str):
            parsed.append(value)
        return original(value, **kwargs)

    monkeypatch.setattr(CRS, "from_user_input", staticmethod(counting))
    assert datum_label(egm2008) == "EGM2008 height (EPSG:3855)"
    assert not is_ellipsoidal(egm2008) and is_ellipsoidal(ELLIPSOIDAL)
    assert datum_label(ELLIPSOIDAL) == "ellipsoidal heights"
    assert "ellipsoidal" not in parsed
    assert not (egm2008 == ELLIPSOIDAL) and "ellipsoidal" in parsed  # what the old test did
