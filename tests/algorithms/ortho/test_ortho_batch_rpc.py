"""ortho:batch of satellite images with RPCs (IMAGES without PROJECT), against GDAL's RPC
transformer (``gdalwarp -rpc -to RPC_DEM=... -et 0``) on each ortho's own grid, through ramp
images (rpc_scene: each output cell holds the image position it was mapped to)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import rasterio

import toolbox
from tests.helpers_cli import assert_refused
from toolbox.cameras import read_rpc
from toolbox.raster.writer import write_raster

sys.path.insert(0, str(Path(__file__).parent))
import rpc_scene as rs  # noqa: E402
from ortho_scene import assert_on_lattice  # noqa: E402

SIZE = (1200, 1000)


def batch(tmp_path: Path, images: str, dem: Path, **extra) -> tuple[dict, dict, list]:
    feedback = toolbox.Feedback()
    out = toolbox.run("ortho:batch", {"IMAGES": images, "DEM": dem, "OUTSIDE": "nodata",
                                      "NODATA": rs.NODATA, "OVERVIEWS": False,
                                      "FOLDER": str(tmp_path / "orthos"),
                                      "OUTPUT": tmp_path / "block.json", **extra},
                      feedback=feedback)
    return out["STATISTICS"], json.loads((tmp_path / "block.json").read_text()), \
        feedback.warnings


def read(path: Path) -> np.ndarray:
    with rasterio.open(path) as src:
        return src.read().astype("float64")


@rs.needs_gdalwarp
def test_folder_of_synthetic_rpc_images_equals_gdalwarp(tmp_path):
    """Two RPC images and a file without RPCs in a folder: the file is skipped with a warning,
    each ortho equals GDAL's RPC warp on its grid (< 0.05 px), and both lie on one lattice of
    the largest GSD (2 significant digits; the images' GSDs are alike: GDAL's bilinear kernel
    widens on a cell coarser than the image's pixel, another filter)."""
    images = tmp_path / "images"
    images.mkdir()
    dem = rs.write_synthetic_dem(tmp_path / "dem.tif")
    rs.write_ramp(images / "a.tif", rs.synthetic_rpc(), *SIZE)
    rs.write_ramp(images / "b.tif", rs.synthetic_rpc(dx=250.0, dy=-180.0), *SIZE)
    write_raster(images / "plain.tif", np.zeros((8, 8), "float32"), rasterio.Affine.identity(),
                 None)
    stats, listing, warnings = batch(tmp_path, str(images), dem)
    assert (stats["photos"], stats["done"], stats["failed"]) == (2, 2, 0)
    assert stats["skipped"] == ["plain.tif"] and any("plain.tif" in w for w in warnings)
    assert stats["camera"] == "rpc" and stats["crs"].endswith("32632")
    assert [Path(p).name for p in listing["orthos"]] == ["a.tif", "b.tif"]
    gsds = [r["photo_gsd_m"] for r in listing["photos"]]
    cell = stats["cell_size"]
    assert cell == float(f"{max(gsds):.2g}") and gsds[0] != gsds[1]
    for path in listing["orthos"]:
        assert_on_lattice(path, cell)
        ramp = images / Path(path).name
        worst, compared, only_one = rs.disagreement(
            read(Path(path)), rs.gdal_ortho(ramp, dem, Path(path), tmp_path / "gdal.tif"), SIZE)
        assert compared > 500_000 and worst < 0.05 and only_one < 0.002 * compared


@rs.needs_gdalwarp
def test_gcp_bias_per_image_and_an_image_without_gcps_fails(tmp_path):
    """GCPs measured on one of two images (its RPCs off by a shift): that image is refined and
    equals GDAL's ortho of the true RPCs; the other has no GCP: it fails alone (the table's
    points are never applied to an image they were not measured on)."""
    images = tmp_path / "images"
    images.mkdir()
    dem = rs.write_synthetic_dem(tmp_path / "dem.tif")
    rs.write_ramp(images / "a.tif", rs.synthetic_rpc(), *SIZE)
    rs.write_ramp(images / "b.tif", rs.synthetic_rpc(dx=250.0), *SIZE)
    true_ramp = rs.write_ramp(tmp_path / "true.tif", rs.synthetic_rpc(dx=3.7, dy=-2.2), *SIZE)
    control, measured = rs.write_gcps(tmp_path, read_rpc(true_ramp, "EPSG:32632"), "a.tif", 5,
                                   seed=3)
    stats, listing, warnings = batch(tmp_path, f"{images / 'a.tif'},{images / 'b.tif'}", dem,
                                     CONTROL=control, MEASUREMENTS=measured, BIAS="shift")
    assert (stats["done"], stats["failed"]) == (1, 1)
    assert listing["failed"][0]["photo"] == "b" and "no control point" in \
        listing["failed"][0]["error"]
    report = listing["photos"][0]
    assert report["bias"]["gcps"] == 5 and report["bias"]["rms_before_px"] > 4.0
    assert report["bias"]["rms_after_px"] < 1e-3
    ortho = Path(listing["orthos"][0])
    assert ortho.name == "a.tif" and not (tmp_path / "orthos" / "b.tif").exists()
    worst, compared, _ = rs.disagreement(read(ortho), rs.gdal_ortho(true_ramp, dem, ortho,
                                                              tmp_path / "gdal.tif"), SIZE)
    assert compared > 200_000 and worst < 0.05


@rs.needs_gdalwarp
def test_quickbird_list_equals_gdalwarp(orthority_data, tmp_path):
    """Orthority's QuickBird image and a ramp carrying its RPCs, listed, on the NGI DEM (its
    EGM2008 heights taken as they are, as GDAL does without the geoid grid): the ramp's ortho
    equals GDAL's on its grid; the real image's ortho is grey + alpha, mostly seen."""
    qb, dem = orthority_data / "rpc" / "qb2_basic1b.tif", orthority_data / "ngi" / "dem.tif"
    with rasterio.open(qb) as src:
        rpcs, size = src.rpcs, (src.width, src.height)
    ramp = rs.write_ramp(tmp_path / "qb_ramp.tif", rpcs, *size)
    stats, listing, _ = batch(tmp_path, f"{qb},{ramp}", dem, HEIGHTS="EPSG:3855",
                              OUTSIDE="alpha", NODATA=None)
    assert (stats["done"], stats["failed"]) == (2, 0) and stats["cell_size"] == 6.5
    assert stats["heights"]["converted"] is False
    real, ramp_ortho = (Path(p) for p in listing["orthos"])
    with rasterio.open(real) as src:
        assert src.count == 2 and (src.read(2) > 0).mean() > 0.5
    ours = read(ramp_ortho)
    assert ours.shape[0] == 2  # the float ramp: NaN nodata, not a float alpha GDAL would ignore
    ours[:, np.isnan(ours).any(axis=0)] = rs.NODATA
    worst, compared, only_one = rs.disagreement(ours, rs.gdal_ortho(ramp, dem, ramp_ortho,
                                                              tmp_path / "gdal.tif"), size)
    assert compared > 500_000 and worst < 0.05 and only_one < 0.002 * compared


def test_rpc_batch_bad_input_is_one_line(tmp_path):
    images = tmp_path / "images"
    images.mkdir()
    dem = rs.write_synthetic_dem(tmp_path / "dem.tif")
    ramp = rs.write_ramp(images / "a.tif", rs.synthetic_rpc(), *SIZE)
    plain = tmp_path / "plain" / "p.tif"
    plain.parent.mkdir()
    write_raster(plain, np.zeros((8, 8), "float32"), rasterio.Affine.identity(), None)
    control = tmp_path / "control.csv"
    control.write_text("id,X,Y,Z\ng1,657000,4984000,300\n")
    out, folder = tmp_path / "block.json", tmp_path / "orthos"
    cases = [
        (("--IMAGES", str(images)), "DEM"),  # RPC images without a DEM
        (("--IMAGES", f"{ramp},{plain}", "--DEM", str(dem)), "has no RPCs"),
        (("--IMAGES", str(plain.parent), "--DEM", str(dem)), "no image with RPCs"),
        (("--DEM", str(dem)), "PROJECT"),
        (("--IMAGES", str(images), "--DEM", str(dem), "--OCCLUSION"), "OCCLUSION"),
        (("--IMAGES", str(images), "--DEM", str(dem), "--CONTROL", str(control)),
         "MEASUREMENTS"),
        (("--IMAGES", str(images), "--DEM", str(dem), "--PHOTOS", "zz"), "zz"),
        (("--IMAGES", str(images), "--DEM", str(dem), "--CRS", "EPSG:4326"), "projected"),
    ]
    for extra, word in cases:
        assert_refused(["run", "ortho:batch", *extra, "--FOLDER", folder, "--OUTPUT", out], word,
                       (out, folder))
    # FOLDER holding the images: a.tif's ortho would replace the image a.tif
    assert_refused(["run", "ortho:batch", "--IMAGES", images, "--DEM", dem, "--FOLDER", images,
                    "--OUTPUT", out, "--overwrite"], "never overwritten", (out,))
    assert sorted(p.name for p in images.iterdir()) == ["a.tif"]
    assert read_rpc(ramp).image_size == SIZE  # the input untouched


def test_a_project_camera_of_type_rpc_points_to_images(tmp_path):
    """A project YAML camera ``model: {type: rpc}``: one line saying how RPC images are given."""
    project = tmp_path / "p.yaml"
    project.write_text("cameras:\n  - {name: qb, model: {type: rpc}}\nphotos: []\n")
    dem = rs.write_synthetic_dem(tmp_path / "dem.tif")
    line = assert_refused(["run", "ortho:batch", "--PROJECT", project, "--DEM", dem, "--FOLDER",
                           tmp_path / "o", "--OUTPUT", tmp_path / "o.json"], "without PROJECT")
    assert "IMAGES" in line
