"""Round fifteen, camera models and orientation conventions (sweep_cameras): a photo's raster
against its camera's size and interior orientation."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml

import toolbox
from toolbox.errors import InputDataError

sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
import ortho_scene  # noqa: E402

BROWN = {"type": "brown", "im_size": [64, 48], "focal_len": 0.75, "k1": -0.1}
MARKS = {"1": [-110.0, 110.0], "2": [110.0, 110.0], "3": [110.0, -110.0], "4": [-110.0, -110.0]}


def _grey(path: Path, width: int, height: int) -> Path:
    data = (np.random.default_rng(1).random((1, height, width)) * 255).astype("uint8")
    with rasterio.open(path, "w", driver="GTiff", width=width, height=height, count=1,
                       dtype="uint8") as dst:
        dst.write(data)
    return path


def _brown_block(folder: Path, width: int, height: int) -> Path:
    for k in (1, 2):
        _grey(folder / f"p{k}.tif", width, height)
    doc = {"crs": "EPSG:3003", "angle_unit": "rad",
           "cameras": [{"name": "lens", "model": BROWN}],
           "photos": [{"id": f"p{k}", "camera": "lens", "image": f"p{k}.tif",
                       "exterior": {"X0": 1688000.0 + 300 * k, "Y0": 4799000.0, "Z0": 1000.0,
                                    "omega": 0.0, "phi": 0.0, "kappa": 0.0}}
                      for k in (1, 2)]}
    (folder / "block.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return folder / "block.yaml"


@pytest.mark.parametrize("size, hint", [((32, 24), "scaled by 0.5"),
                                        ((48, 64), "turned 90 degrees"),
                                        ((60, 40), "a crop")])
def test_tiepoints_refuse_a_raster_of_another_size_than_the_camera(tmp_path, size, hint):
    """The tie points are written in the raster's pixels and read back (orientation:bundle) in
    the camera's: a preview (half size) gave 470 observations at half their coordinates, exit 0
    (median reprojection 173 px on the 640 x 480 Brown block)."""
    project = _brown_block(tmp_path, *size)
    with pytest.raises(InputDataError, match=f"{size[0]} x {size[1]} px but the camera 'lens' "
                                             f"says 64 x 48.*{hint}"):
        toolbox.run("orientation:tiepoints", {"PROJECT": project, "TERRAIN_HEIGHT": 0.0,
                                              "OUTPUT": tmp_path / "tie.csv"})
    assert not (tmp_path / "tie.csv").exists()


@pytest.fixture(scope="module")
def film(tmp_path_factory):
    """The ortho scene's photo described as a scan with a fiducial fit and no image_size_px."""
    scene = ortho_scene.make_scene(tmp_path_factory.mktemp("film_scene"))
    doc = yaml.safe_load(scene.project_path.read_text())
    cam = doc["cameras"][0]
    pixel = cam.pop("pixel_size_mm")
    half = cam.pop("image_size_px")[0] / 2
    cam["fiducials_mm"] = MARKS
    doc["photos"][0]["interior"] = {
        "transformation": "affine",
        "fiducials_px": {k: [half + x / pixel, half - y / pixel] for k, (x, y) in MARKS.items()}}
    (scene.folder / "fiducials.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return scene


@pytest.mark.parametrize("algorithm", ["ortho:photo", "ortho:batch"])
def test_film_camera_without_image_size_takes_the_rasters(film, tmp_path, algorithm):
    """image_size_px is optional for a film camera (scans differ in size): ortho:photo and
    ortho:batch stopped with exit 3 (TypeError in the ground sample distance). The ortho is the
    one of the same scan described by its pixel size and image size."""
    fid = film.folder / "fiducials.yaml"
    out = tmp_path / "fid.tif"
    if algorithm == "ortho:photo":
        toolbox.run(algorithm, {"PROJECT": fid, "INPUT": film.photo_path, "DEM": film.dem_path,
                                "CELL_SIZE": 10.0, "OUTPUT": out})
    else:
        toolbox.run(algorithm, {"PROJECT": fid, "DEM": film.dem_path, "CELL_SIZE": 10.0,
                                "FOLDER": tmp_path / "orthos", "OUTPUT": tmp_path / "b.json"})
        out = tmp_path / "orthos" / "p1.tif"
    toolbox.run("ortho:photo", {"PROJECT": film.project_path, "INPUT": film.photo_path,
                                "DEM": film.dem_path, "CELL_SIZE": 10.0,
                                "OUTPUT": tmp_path / "ref.tif"})
    with rasterio.open(out) as a, rasterio.open(tmp_path / "ref.tif") as b:
        assert a.bounds == b.bounds
        assert np.abs(a.read().astype(int) - b.read().astype(int)).max() <= 1


def test_fiducials_measured_on_another_scan_are_refused(film, tmp_path):
    """A half-size copy of the scan with the full scan's fiducial fit: fiducial '2' lands at
    (782.6, 17.4) px of a 400 x 400 raster."""
    with rasterio.open(film.photo_path) as src:
        data = src.read(out_shape=(src.count, src.height // 2, src.width // 2))
        profile = src.profile | {"width": src.width // 2, "height": src.height // 2}
    half = tmp_path / "p1.tif"
    with rasterio.open(half, "w", **profile) as dst:
        dst.write(data)
    with pytest.raises(InputDataError, match=r"fiducial '2' at \(782\.6, 17\.4\) px, off the "
                                             r"raster .*\(400 x 400 px\)"):
        toolbox.run("ortho:photo", {"PROJECT": film.folder / "fiducials.yaml", "INPUT": half,
                                    "DEM": film.dem_path, "CELL_SIZE": 10.0,
                                    "OUTPUT": tmp_path / "o.tif"})


@pytest.mark.parametrize("col, row", [(30.0, 60.0), (-5.0, 20.0), (70.0, 47.0)])
def test_pixels_off_the_image_are_refused_or_flagged(tmp_path, col, row):
    """A measured pixel off the camera's 64 x 48 image (row 60, col -5, col 70) cannot have been
    measured on the photo (a turned or scaled copy was): orientation:monoplot gave an 'ok' ground
    point for it, exit 0, and intersect used its ray. Monoplot now flags it (outside_image, no
    geometry); intersect refuses it naming INPUT. The image's edge is on the image."""
    import geopandas as gpd

    project = _brown_block(tmp_path, 64, 48)
    table = tmp_path / "m.csv"
    table.write_text(f"point_id,photo,col_px,row_px\nedge,p1,64,0\nbad,p1,{col},{row}\n"
                     f"bad,p2,30,20\nedge,p2,0,48\n")
    with pytest.raises(InputDataError, match=f"INPUT: point 'bad' of photo 'p1' is measured at "
                                             rf"\({col:g}, {row:g}\) px, off the 64 x 48 px"):
        toolbox.run("orientation:intersect", {"PROJECT": project, "INPUT": table,
                                              "OUTPUT": tmp_path / "i.gpkg"})
    out = toolbox.run("orientation:monoplot", {"PROJECT": project, "INPUT": table,
                                               "HEIGHT": 0.0, "OUTPUT": tmp_path / "m.gpkg"})
    assert out["STATISTICS"]["status"] == {"ok": 3, "outside_image": 1}
    points = gpd.read_file(tmp_path / "m.gpkg", layer="points")
    assert points["status"].tolist() == ["ok", "outside_image", "ok", "ok"]
    assert points.geometry[1] is None and points.geometry[0] is not None


def test_metashape_p3_p4_are_not_dropped(tmp_path):
    """Metashape's tangential terms carry a radial factor (P1(r² + 2x²) + 2P2xy)(1 + P3r² +
    P4r⁴) (manual, appendix C): P3 = 8 with P1 = 0.004, P2 = -0.003 moves the corner of the
    1000 x 800 px, f = 900 px sensor by 11 px (the formula below), and was dropped in silence.
    Without tangential terms P3 changes nothing and the sensor is read."""
    from tests.toolbox.exchange.test_exchange_formats import TM, F, H, W, metashape_xml
    from toolbox.exchange import metashape

    p1, p2, p3 = 0.004, -0.003, 8.0
    x, y = W / 2 / F, H / 2 / F
    r2 = x * x + y * y
    assert abs((p1 * (r2 + 2 * x * x) + 2 * p2 * x * y) * p3 * r2 * F) > 10
    metashape_xml(tmp_path / "a.xml", f"<p1>{p1}</p1><p2>{p2}</p2><p3>{p3}</p3>")
    with pytest.raises(InputDataError, match="p3 = 8.0"):
        metashape.read_xml(tmp_path / "a.xml", crs=TM)
    metashape_xml(tmp_path / "b.xml", f"<k1>-0.08</k1><p3>{p3}</p3><p4>1.0</p4>")
    assert metashape.read_xml(tmp_path / "b.xml", crs=TM).cameras["test sensor"]["k1"] == -0.08


def test_bundle_reference_of_a_film_block_without_image_size(tmp_path):
    """orientation:bundle REFERENCE compared the orientations on the points each reference photo
    images, from its camera's image_size_px: a film camera without one (optional; here the demo
    block's 19167 px frame of 0.012 mm pixels given as a pixel -> fiducial matrix per photo)
    stopped with exit 3 (TypeError). Its frame outline (frame_size_mm) now bounds the image:
    the same points per photo as the camera with image_size_px."""
    from toolbox.demo.samples import bundle_block

    paths = bundle_block.make(tmp_path, {})
    doc = yaml.safe_load(paths["bundle_project"].read_text())
    cam = doc["cameras"][0]
    (w, h), s = cam.pop("image_size_px"), cam.pop("pixel_size_mm")
    matrix = [[s, 0.0, -w / 2 * s], [0.0, -s, h / 2 * s], [0.0, 0.0, 1.0]]
    for photo in doc["photos"]:
        photo["interior"] = {"transformation": "affine", "pixel_to_fiducial": matrix}
    (tmp_path / "fid.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    common = {"INPUT": paths["bundle_measurements"], "CONTROL": paths["bundle_control"],
              "PROJECT": tmp_path / "fid.yaml"}
    toolbox.run("orientation:bundle", {**common, "OUTPUT": tmp_path / "adjusted.yaml"})
    out = toolbox.run("orientation:bundle", {
        **common, "OUTPUT": tmp_path / "again.yaml", "REFERENCE": tmp_path / "adjusted.yaml",
        "REPORT": tmp_path / "again.json"})
    assert out["STATISTICS"]["reference"]["points"] == 6
    report = yaml.safe_load((tmp_path / "again.json").read_text())
    # the points per photo of the same block with image_size_px [19167, 19167] (as measured)
    assert [p["points"] for p in report["reference"]["photos"]] == [1, 3, 3, 1, 1, 2, 2, 1]


def test_rectify_refuses_a_raster_other_than_the_one_measured(tmp_path):
    """rectify:image of a half-size copy of the photo whose 12 GCPs rectify:estimate fitted:
    the full-size pixel transform warped the preview onto a quarter of the photo's ground, exit
    0. The control points lie off the 200 x 150 px copy (G01 at (246.3, 83.8) px): refused
    naming INPUT and TRANSFORM. The photo itself is still rectified."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "rectify"))
    import rectify_scene

    photo, transform = rectify_scene.photo_and_transform(tmp_path, "uint8")
    with rasterio.open(photo) as src:
        data = src.read(out_shape=(1, src.height // 2, src.width // 2))
        profile = src.profile | {"width": src.width // 2, "height": src.height // 2}
    with rasterio.open(tmp_path / "half.tif", "w", **profile) as dst:
        dst.write(data)
    from toolbox.errors import ParameterError

    for mode in ("warp", "gcps"):
        with pytest.raises(ParameterError, match=r"INPUT .* is 200 x 150 px but control point "
                                                 r"'G01' of TRANSFORM .* \(246\.\d+, 83\.\d+\) px"):
            toolbox.run("rectify:image", {"INPUT": tmp_path / "half.tif", "TRANSFORM": transform,
                                          "MODE": mode, "OUTPUT": tmp_path / f"h_{mode}.tif"})
    toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                  "OUTPUT": tmp_path / "full.tif"})


def test_dji_calibration_of_a_resized_copy_with_rewritten_exif_is_refused(tmp_path, orthority_data):
    """Orthority's ODM frames are 1368 x 912 copies of 5472 x 3648 DJI photos; their XMP
    calibration is in the original's pixels (CalibratedFocalLength 3666.67, optical centre
    2736, 1824) and EXIF PixelXDimension still says 5472: focal_len 0.670 (OpenSfM's 0.666 for
    these photos). A copy whose EXIF gives its own size (1368) was read unscaled, exit 0: focal
    2.68 and the optical centre 1.5 image widths off the centre. Refused naming the tags."""
    import subprocess

    from toolbox.exchange import exif

    source = orthority_data / "odm" / "images" / "100_0005_0018.tif"
    spec = next(iter(exif.read_images([source]).cameras.values()))
    assert spec["focal_len"] == pytest.approx(3666.666504 / 5472) and spec["cx"] == 0.0
    copy = tmp_path / "100_0005_0018.tif"
    subprocess.run(["gdal_translate", "-q", "-mo", "EXIF_PixelXDimension=1368", "-mo",
                    "EXIF_PixelYDimension=912", str(source), str(copy)], check=True)
    with pytest.raises(InputDataError, match=r"CalibratedOpticalCenterX/Y \(2736\.000000, "
                                             r"1824\.000000\) px, read against EXIF "
                                             r"PixelXDimension 1368"):
        exif.read_images([copy])


def test_control_predictions_refuse_a_preview(tmp_path):
    """orientation:control predicted the control points in the camera's pixels and cut the
    chips from the raster at those pixels: on half-size previews the chips showed other ground
    (exit 0). Refused naming both sizes; the full-size photos are predicted at the camera's
    pixel (the nadir point of p1 at the image centre (32, 24))."""
    (tmp_path / "c.csv").write_text("id,X,Y,Z\nA,1688300,4799000,0\n")
    project = _brown_block(tmp_path, 32, 24)
    with pytest.raises(InputDataError, match="32 x 24 px but the camera 'lens' says 64 x 48"):
        toolbox.run("orientation:control", {"PROJECT": project, "CONTROL": tmp_path / "c.csv",
                                            "OUTPUT": tmp_path / "p.csv"})
    project = _brown_block(tmp_path, 64, 48)
    toolbox.run("orientation:control", {"PROJECT": project, "CONTROL": tmp_path / "c.csv",
                                        "OUTPUT": tmp_path / "q.csv"})
    rows = (tmp_path / "q.csv").read_text().splitlines()
    assert rows[1].startswith("A,p1,32.0,24.0,predicted")


@pytest.mark.parametrize("cx, cy", [(7.68, -3.84), (0.0, 0.6), (-0.51, 0.0)])
def test_principal_point_off_the_image_is_refused(cx, cy):
    """cx, cy are offsets from the image centre normalised by max(w, h): written in pixels
    (7.68 for a 7.68 px offset) the principal point lay 4900 px off a 640 x 480 image and
    orientation:footprints drew the photos' footprints far away, exit 0. The image's own
    range (|cx| <= 0.5, |cy| <= 0.375 here) is accepted, its edge included."""
    from toolbox.cameras import create_intrinsics

    with pytest.raises(InputDataError, match=rf"principal point .* lies off the 640 x 480 px "
                                             rf"image \(cx = {cx!r}, cy = {cy!r}\)"):
        create_intrinsics({"type": "pinhole", "im_size": [640, 480], "focal_len": 0.75,
                           "cx": cx, "cy": cy})
    model = create_intrinsics({"type": "pinhole", "im_size": [640, 480], "focal_len": 0.75,
                               "cx": 0.5, "cy": -0.375})
    assert model.principal_point_px == (640.0, 0.0)
