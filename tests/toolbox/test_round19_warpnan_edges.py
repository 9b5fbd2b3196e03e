"""Round 19, warp NaN edges: the photo warp (toolbox.raster.warp: rectify, ortho, epipolar).

1. A float photo (no nodata: NaN marks the outside) rectified with cubic lost 753 of its 24580
   footprint cells (NaN, so no data) up to several cells inside the footprint edge, exit 0;
   gdalwarp on the same georeferenced photo gives all of them a value. The packed path gave
   OpenCV the fill (NaN) as its border value, and OpenCV's cubic starts a sample that has a
   kernel tap off its buffer from the border value, deciding that for groups of cells: NaN
   spread to cells whose kernel lies on the photo. ortho:photo (the planned-map path) the same.
2. A photo with a nodata value (-9999) inside it: cubic and lanczos samples next to its nodata
   pixels took -9999 with the kernel's outer weights (1196 off on a photo of 30..250) and
   stayed valid (only the bilinear taps were checked, on a uint8 mask that rounds small
   weights away: bilinear ortho cells 19 off). Truth: the same photo with NaN on those pixels
   (OpenCV carries a NaN tap into the cell: the cells whose kernel touches one), and gdalwarp's
   values where both have one.

The photo is georeferenced for gdalwarp by the exact similarity the rectification recovers
(as in test_round18_warpnodata)."""

from __future__ import annotations

import shutil
import subprocess
import warnings

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from tests.toolbox.warp_scene import GEO, H, W, estimate_homography, write_photo

pytestmark = pytest.mark.skipif(shutil.which("gdalwarp") is None, reason="needs gdalwarp")



def texture() -> np.ndarray:
    """A smooth gradient with texture, 30..250, float32 (1, H, W)."""
    yy, xx = np.mgrid[0:H, 0:W]
    return (50 + xx * 1.3 + yy * 0.7 + 20 * np.sin(xx / 3.0) * np.cos(yy / 4.0))[None].astype(
        "float32")


@pytest.fixture(scope="module")
def transform(tmp_path_factory):
    return estimate_homography(tmp_path_factory.mktemp("warpnan"))


def rectify(photo, transform, out, resampling, **params):
    toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 0.5,
                                  "RESAMPLING": resampling, "COG": False, "OVERVIEWS": False,
                                  "OUTPUT": out, **params})
    with rasterio.open(out) as ds:
        return ds.read(1), ds.dataset_mask() > 0, ds.bounds, ds.shape


def gdalwarp(photo, out, resampling, bounds, shape):
    subprocess.run(["gdalwarp", "-q", "-r", resampling, "-dstnodata", "nan",
                    "-te", *map(str, bounds), "-ts", str(shape[1]), str(shape[0]),
                    str(photo), str(out)], check=True, capture_output=True)
    with rasterio.open(out) as ds:
        return ds.read(1), ds.dataset_mask() > 0


# OpenCV's cubic is Keys' a = -0.75, GDAL's a = -0.5; lanczos 4 lobes against 3; at the photo's
# edge OpenCV extends the edge pixels, GDAL renormalises the kernel: at most 0.92 on this texture
TOLERANCE = {"bilinear": 1e-3, "cubic": 1.5, "lanczos": 1.5}


@pytest.mark.parametrize("outside", ["alpha", "nodata"])
def test_float_photo_cubic_keeps_its_footprint(tmp_path, transform, outside):
    data = texture()
    photo = write_photo(tmp_path / "p.tif", data)
    out, valid, bounds, shape = rectify(photo, transform, tmp_path / "o.tif", "cubic",
                                        OUTSIDE=outside)
    ref, ref_valid = gdalwarp(write_photo(tmp_path / "pg.tif", data, georeferenced=True),
                              tmp_path / "g.tif", "cubic", bounds, shape)
    assert ref_valid.sum() == 24580
    assert (valid == ref_valid).all(), (ref_valid & ~valid).sum()  # 753 cells were NaN
    assert np.abs(out[valid] - ref[valid]).max() < TOLERANCE["cubic"]


@pytest.mark.parametrize("resampling", ["cubic", "lanczos"])
def test_nodata_pixels_stay_out_of_the_kernel(tmp_path, transform, resampling):
    data = texture()
    hole = np.zeros(data.shape, bool)
    hole[:, 30:45, 50:75] = True
    with_nodata, with_nan = np.where(hole, -9999, data), np.where(hole, np.nan, data)
    out, valid, bounds, shape = rectify(write_photo(tmp_path / "p.tif", with_nodata, -9999.0),
                                        transform, tmp_path / "o.tif", resampling)
    nan_out, nan_valid, _, _ = rectify(write_photo(tmp_path / "q.tif", with_nan), transform,
                                       tmp_path / "n.tif", resampling)
    assert (valid == nan_valid).all()  # the cells whose kernel touches no hole pixel
    assert 22000 < valid.sum() < 23500
    np.testing.assert_allclose(out[valid], nan_out[valid], atol=1e-4)  # was 1196 off
    ref, ref_valid = gdalwarp(write_photo(tmp_path / "pg.tif", with_nodata, -9999.0, True),
                              tmp_path / "g.tif", resampling, bounds, shape)
    assert not (valid & ~ref_valid).any()  # no value where gdalwarp has none
    assert np.abs(out[valid] - ref[valid]).max() < TOLERANCE[resampling]


def ortho(tmp_path, data, nodata, resampling, outside="alpha", cell=12.0, window=None,
          rgba=False):
    """ortho:photo of ``data`` (a nadir photo, kappa 0.4, flat DEM at 250 m: an exact
    similarity) on ``cell`` metres, over the photo window ``window`` (col0, row0, col1, row1)
    when given, and gdalwarp's of the photo georeferenced by that similarity."""
    import yaml
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    n = data.shape[-1]
    pixel, focal, z0, ground, kappa = 230.0 / n, 153.0, 1700.0, 250.0, 0.4
    x0, y0 = 1688600.0, 4799600.0
    k = (z0 - ground) / focal * pixel  # metres per photo pixel
    a, b = k * np.cos(kappa), k * np.sin(kappa)  # x = (col - n/2) pixel, y = -(row - n/2) pixel
    geo = Affine(a, b, x0 - (a + b) * n / 2, b, -a, y0 - (b - a) * n / 2)
    profile = {"driver": "GTiff", "width": n, "height": n, "count": len(data),
               "dtype": data.dtype.name, "nodata": nodata}
    if rgba:
        profile.update(photometric="RGB", alpha="YES")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(tmp_path / "p1.tif", "w", **profile) as dst:
            dst.write(data)
    with rasterio.open(tmp_path / "pg.tif", "w", transform=geo, crs="EPSG:3003",
                       **profile) as dst:
        dst.write(data)
    write_raster(tmp_path / "dem.tif", np.full((40, 40), ground, "float32"),
                 from_origin(1686600.0, 4801600.0, 100.0, 100.0), "EPSG:3003", nodata=-9999.0)
    camera = {"name": "c", "principal_distance_mm": focal, "image_size_px": [n, n],
              "pixel_size_mm": pixel, "frame_size_mm": [230.0, 230.0]}
    exterior = dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                        (x0, y0, z0, 0.0, 0.0, kappa), strict=True))
    (tmp_path / "project.yaml").write_text(yaml.safe_dump({
        "format": "orientation-project", "version": 1, "crs": "EPSG:3003", "angle_unit": "rad",
        "cameras": [camera], "photos": [{"id": "p1", "camera": "c", "image": "p1.tif",
                                         "exterior": exterior}]}, sort_keys=False))
    out = tmp_path / "o.tif"
    extent = {}
    if window is not None:
        xs, ys = geo * (np.array(window)[[0, 2, 2, 0]], np.array(window)[[1, 1, 3, 3]])
        extent = {"EXTENT": f"{xs.min()},{ys.min()},{xs.max()},{ys.max()}"}
    toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "DEM": tmp_path / "dem.tif",
                                "PROJECT": tmp_path / "project.yaml", "CELL_SIZE": cell,
                                "RESAMPLING": resampling, "OUTSIDE": outside, "OUTPUT": out,
                                "OVERVIEWS": False, **extent})
    with rasterio.open(out) as ds:
        values, valid, bounds, shape = ds.read(1), ds.dataset_mask() > 0, ds.bounds, ds.shape
    if rgba:  # the whole output and gdalwarp's (bilinear: GDAL has no quadratic), alpha last
        subprocess.run(["gdalwarp", "-q", "-r", "bilinear", "-dstalpha", "-te", *map(str, bounds),
                        "-ts", str(shape[1]), str(shape[0]), str(tmp_path / "pg.tif"),
                        str(tmp_path / "g.tif")], check=True, capture_output=True)
        with rasterio.open(out) as ds, rasterio.open(tmp_path / "g.tif") as ref:
            return ds.read(), ref.read()
    return values, valid, gdalwarp(tmp_path / "pg.tif", tmp_path / "g.tif", resampling,
                                   bounds, shape)


@pytest.mark.parametrize("outside", ["alpha", "nodata"])
def test_ortho_float_photo_cubic_keeps_its_footprint(tmp_path, outside):
    """The planned-map path (ortho:photo, mosaic's ortho chips): 3769 of 131981 cells lost."""
    yy, xx = np.mgrid[0:80, 0:80]
    data = (60 + xx * 2 + 20 * np.sin(xx / 3.0) * np.cos(yy / 4.0))[None].astype("float32")
    out, valid, (ref, ref_valid) = ortho(tmp_path, data, None, "cubic", outside)
    assert ref_valid.sum() > 25000
    assert (valid == ref_valid).all(), (ref_valid & ~valid).sum()
    assert np.abs(out[valid] - ref[valid]).max() < TOLERANCE["cubic"]


def test_ortho_bilinear_next_to_nodata_pixels(tmp_path):
    """Bilinear with small weights on a nodata pixel (upsampled 2.3 times): the uint8 mask
    rounded them away and the cell kept a share of -9999 (14 off); now it is no data, as the
    same photo with NaN gives."""
    yy, xx = np.mgrid[0:80, 0:80]
    data = (60 + xx * 2 + 20 * np.sin(xx / 3.0) * np.cos(yy / 4.0))[None].astype("float32")
    data[:, 30:45, 35:55] = -9999
    around = (25, 20, 65, 55)
    out, valid, (ref, ref_valid) = ortho(tmp_path, data, -9999.0, "bilinear", cell=6.0,
                                         window=around)
    (tmp_path / "nan").mkdir()
    _, nan_valid, _ = ortho(tmp_path / "nan", np.where(data == -9999, np.nan, data), None,
                            "bilinear", cell=6.0, window=around)
    assert 5000 < valid.sum() < ref_valid.sum()
    assert (valid == nan_valid).all()
    assert not (valid & ~ref_valid).any()
    np.testing.assert_allclose(out[valid], ref[valid], atol=1e-3)


def test_alpha_photo_with_outside_nodata_is_a_parameter_error(tmp_path, transform):
    """A photo with an alpha band keeps it as the output's alpha; OUTSIDE=nodata asked for a
    nodata value too, which the writer refused after the work: exit 3, 'internal error'. Now
    exit 2 naming OUTSIDE, no output."""
    from toolbox.errors import ParameterError

    gray = np.full((2, H, W), 200, "uint8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(tmp_path / "ga.tif", "w", driver="GTiff", width=W, height=H,
                           count=2, dtype="uint8", alpha="YES") as dst:
            dst.write(gray)
    with pytest.raises(ParameterError) as err:  # (the CLI's exit 2)
        toolbox.run("rectify:image", {"INPUT": tmp_path / "ga.tif", "TRANSFORM": transform,
                                      "OUTSIDE": "nodata", "OUTPUT": tmp_path / "o.tif"})
    assert err.value.name == "OUTSIDE"
    assert "nodata does not apply to a photo with an alpha band (band 2" in str(err.value)
    assert not (tmp_path / "o.tif").exists()


@pytest.mark.parametrize(("resampling", "pattern", "cell"), [
    ("bilinear", "hole", 0.5), ("cubic", "hole", 0.5), ("bilinear", "checker", 0.25)])
def test_alpha_photo_colours_next_to_transparent_pixels(tmp_path, transform, resampling,
                                                        pattern, cell):
    """An RGBA photo whose transparent pixels hold black: the cells next to them mixed the
    black in (82 grey levels darker than gdalwarp's with bilinear, 83 with cubic: a dark
    fringe); GDAL weighs the colours by alpha, as the warp now does. (checker: most of the
    98000 cells are next to a transparent pixel, more than an OpenCV map's 32767 a side.)"""
    grey = np.clip(texture()[0], 0, 255).astype("uint8")
    hole = np.zeros((H, W), bool)
    if pattern == "hole":
        hole[30:45, 50:75] = True
    else:
        hole[::3, ::3] = True
    bands = np.stack([np.where(hole, 0, grey), np.where(hole, 0, 255 - grey),
                      np.where(hole, 0, grey // 2 + 60), np.where(hole, 0, 255)]).astype("uint8")
    for name, extra in (("p.tif", {}), ("pg.tif", {"transform": GEO, "crs": "EPSG:3003"})):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(tmp_path / name, "w", driver="GTiff", width=W, height=H, count=4,
                               dtype="uint8", photometric="RGB", alpha="YES", **extra) as dst:
                dst.write(bands)
    toolbox.run("rectify:image", {"INPUT": tmp_path / "p.tif", "TRANSFORM": transform,
                                  "CELL_SIZE": cell, "RESAMPLING": resampling, "COG": False,
                                  "OVERVIEWS": False, "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "o.tif") as ds:
        out, bounds, shape = ds.read(), ds.bounds, ds.shape
    subprocess.run(["gdalwarp", "-q", "-r", resampling, "-dstalpha", "-te", *map(str, bounds),
                    "-ts", str(shape[1]), str(shape[0]), str(tmp_path / "pg.tif"),
                    str(tmp_path / "g.tif")], check=True, capture_output=True)
    with rasterio.open(tmp_path / "g.tif") as ds:
        ref = ds.read()
    both = (out[3] > 0) & (ref[3] > 0)
    assert both.sum() > 20000
    assert (out[3][ref[3] > 0] > 0).all()
    diff = np.abs(out[:3, both].astype(int) - ref[:3, both]).max()
    assert diff <= 2, diff


def test_ortho_alpha_photo_colours_with_quadratic(tmp_path):
    """ortho:photo's quadratic (the toolbox's own kernel, not OpenCV's) on an RGBA photo with
    black under a transparent area: the colours next to it were darkened (as with bilinear and
    cubic); weighed by alpha they agree with gdalwarp's bilinear (GDAL has no quadratic) within
    the kernels' difference."""
    yy, xx = np.mgrid[0:80, 0:80]
    grey = (60 + xx * 2 + 20 * np.sin(xx / 3.0) * np.cos(yy / 4.0)).astype("uint8")
    hole = np.zeros((80, 80), bool)
    hole[30:45, 35:55] = True
    bands = np.stack([np.where(hole, 0, grey), np.where(hole, 0, 255 - grey),
                      np.where(hole, 0, grey // 2), np.where(hole, 0, 255)]).astype("uint8")
    out, ref = ortho(tmp_path, bands, None, "quadratic", cell=6.0, window=(25, 20, 65, 55),
                     rgba=True)
    both = (out[3] > 0) & (ref[3] > 0)
    assert both.sum() > 5000 and (out[3][ref[3] > 0] > 0).all()
    diff = np.abs(out[:3, both].astype(int) - ref[:3, both]).max()
    assert diff <= 3, diff
