"""ortho:batch on Orthority's NGI test data (4 real aerial frames, Orthority's interior YAML and
exterior GeoJSON read directly, images matched in IMAGES, 24 m DEM with EGM2008 heights) at 5 m,
checked against an independent projection written here: the textbook omega-phi-kappa
collinearity through OpenCV's ``projectPoints``, the DEM interpolated by scipy, the photo sampled
by scipy. Each ortho cell must hold the photo's value where that projection puts its ground
point (within uint8 rounding); a tenth of a pixel off, the same comparison fails."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio

import toolbox

CELL = 5.0


@pytest.fixture(scope="module")
def ngi_orthos(orthority_data, tmp_path_factory):
    folder = tmp_path_factory.mktemp("ngi")
    out = toolbox.run("ortho:batch", {
        "PROJECT": orthority_data / "io" / "ngi_ext_param.geojson",
        "IMAGES": str(orthority_data / "ngi"), "DEM": orthority_data / "ngi" / "dem.tif",
        "CELL_SIZE": CELL, "RESAMPLING": "bilinear", "OVERVIEWS": False,
        "PHOTOS": "3324c_2015_1004_05_0182_RGB,3324c_2015_1004_06_0253_RGB",
        "FOLDER": str(folder / "orthos"), "OUTPUT": folder / "orthos.json"})
    return orthority_data, out


def dem_heights(dem_path, x, y):
    """Bilinear heights between the DEM's cell centres (scipy), NaN outside."""
    from scipy.ndimage import map_coordinates

    with rasterio.open(dem_path) as src:
        z = src.read(1).astype(float)
        col, row = ~src.transform * (x, y)
    return map_coordinates(z, [row - 0.5, col - 0.5], order=1, cval=np.nan)


def opencv_pixels(camera: dict, xyz_c: np.ndarray, opk: np.ndarray, xyz: np.ndarray):
    """Textbook collinearity: R = Rx(ω)·Ry(φ)·Rz(κ) turns the camera frame (x right, y up,
    z back) into the world; OpenCV's camera frame is (x right, y down, z forward). Pixel
    centres at integers (OpenCV), principal point at the image centre."""
    import cv2

    om, ph, ka = opk
    rx = np.array([[1, 0, 0], [0, np.cos(om), -np.sin(om)], [0, np.sin(om), np.cos(om)]])
    ry = np.array([[np.cos(ph), 0, np.sin(ph)], [0, 1, 0], [-np.sin(ph), 0, np.cos(ph)]])
    rz = np.array([[np.cos(ka), -np.sin(ka), 0], [np.sin(ka), np.cos(ka), 0], [0, 0, 1]])
    r_cw = np.diag([1.0, -1.0, -1.0]) @ (rx @ ry @ rz).T  # world -> OpenCV camera
    w, h = camera["im_size"]
    fx = camera["focal_len"] * w / camera["sensor_size"][0]
    fy = camera["focal_len"] * h / camera["sensor_size"][1]
    k = np.array([[fx, 0, (w - 1) / 2], [0, fy, (h - 1) / 2], [0, 0, 1]])
    local = xyz - xyz_c  # a local origin: projected coordinates are large
    uv, _ = cv2.projectPoints(local.reshape(-1, 1, 3), cv2.Rodrigues(r_cw)[0], np.zeros(3), k,
                              None)
    return uv.reshape(-1, 2)


def sampled(photo: np.ndarray, uv: np.ndarray, offset: float) -> np.ndarray:
    """(bands, n) bilinear values of ``photo`` at pixels ``uv`` + ``offset`` (scipy; integer
    pixel centres as OpenCV's)."""
    from scipy.ndimage import map_coordinates

    return np.stack([map_coordinates(band, [uv[:, 1] + offset, uv[:, 0] + offset], order=1)
                     for band in photo])


def test_ngi_orthos_match_an_independent_projection(ngi_orthos):
    import yaml

    data, out = ngi_orthos
    assert out["STATISTICS"]["done"] == 2 and out["STATISTICS"]["failed"] == 0
    camera = next(iter(yaml.safe_load((data / "io" / "ngi_int_param.yaml").read_text())
                       .values()))
    exterior = {f["properties"]["filename"]: f["properties"] for f in json.loads(
        (data / "io" / "ngi_ext_param.geojson").read_text())["features"]}
    rng = np.random.default_rng(4)
    for path in json.loads(Path(out["OUTPUT"]).read_text())["orthos"]:
        with rasterio.open(path) as src:
            ortho = src.read()
            transform = src.transform
        assert ortho.shape[0] == 4 and transform.a == CELL and transform.c % CELL == 0
        rows, cols = np.nonzero(ortho[3] == 255)
        pick = rng.choice(len(rows), 400, replace=False)
        r, c = rows[pick], cols[pick]
        x, y = transform * (c + 0.5, r + 0.5)
        z = dem_heights(data / "ngi" / "dem.tif", x, y)
        ok = np.isfinite(z)
        assert ok.mean() > 0.95
        props = exterior[Path(path).stem]
        uv = opencv_pixels(camera, np.array(props["xyz"]), np.array(props["opk"]),
                           np.column_stack([x, y, z])[ok])
        with rasterio.open(data / "ngi" / f"{props['filename']}.tif") as src:
            photo = src.read().astype(float)
        w, h = camera["im_size"]
        inside = (uv[:, 0] > 1) & (uv[:, 0] < w - 2) & (uv[:, 1] > 1) & (uv[:, 1] < h - 2)
        assert inside.mean() > 0.95  # the ortho's valid cells are where the photo is

        ours = ortho[:3, r[ok][inside], c[ok][inside]].astype(float)
        diff = np.abs(ours - sampled(photo, uv[inside], 0.0))
        # uint8 rounding alone makes a mean of 0.25 (OpenCV's remap on a 1/32 px grid)
        assert diff.mean() < 0.35, diff.mean()
        assert np.percentile(diff, 99) <= 1.0
        # the check resolves a tenth of a pixel: 0.1 px off makes about 1.2 DN (measured)
        assert np.abs(ours - sampled(photo, uv[inside], 0.1)).mean() > 3 * diff.mean()


def test_images_folder_without_the_photos_is_one_line_error(orthority_data, tmp_path):
    """A foreign orientation file with IMAGES naming a folder without image files: exit 2, one
    line naming IMAGES, nothing written."""
    import subprocess
    import sys

    (tmp_path / "empty").mkdir()
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "toolbox.cli", "run", "ortho:batch",
         "--PROJECT", str(orthority_data / "io" / "ngi_ext_param.geojson"),
         "--IMAGES", str(tmp_path / "empty"), "--DEM", str(orthority_data / "ngi" / "dem.tif"),
         "--FOLDER", str(out), "--OUTPUT", str(tmp_path / "o.json")],
        capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "IMAGES" in lines[0] and "Traceback" not in proc.stderr
    assert not out.exists() and not (tmp_path / "o.json").exists()
