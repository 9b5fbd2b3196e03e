"""Round 18, warp nodata: the photo warp (toolbox.raster.warp: rectify, ortho, epipolar) with
OUTSIDE=nodata wrote valid cells as the nodata value in silence (exit 0): cubic and lanczos
overshoot, a dark pixel (2) next to a bright one (250) interpolates below 0, OpenCV saturates
it to 0 for uint8, and 0 is the default nodata: a hole inside the footprint (6139 of 24580 cells
in the repro). A user's NODATA equal to an interpolated value did the same with bilinear.

Truth: the footprint is geometry (an exact similarity: the cells whose centre maps inside the
photo), and ``gdalwarp -r cubic -dstnodata 0`` on the same georeferenced photo leaves no valid
cell at 0: its warp kernel moves a value that lands on the nodata one step off it (GDAL 3.6
gives 1 for Byte nodata 0, 99 for nodata 100, 254 for 255, -32767 for Int16 -32768). The
values elsewhere are those of the OUTSIDE=alpha output (a path the fix does not touch)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from tests.toolbox.warp_scene import SCALE, THETA, X0, Y0, H, W, estimate_homography, write_photo


def stripes(bands: int) -> np.ndarray:
    data = np.full((bands, H, W), 2, "uint8")
    data[:, :, ::8] = 250
    data[:, :, 1::8] = 250
    data[:, ::10, :] = 250
    return data


@pytest.fixture(scope="module")
def transform(tmp_path_factory):
    return estimate_homography(tmp_path_factory.mktemp("warpnodata"))


def rectify(photo, transform, out, **params):
    toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 0.5,
                                  "COG": False, "OVERVIEWS": False, "OUTPUT": out, **params})
    with rasterio.open(out) as ds:
        return ds.read(), ds.dataset_mask() > 0, ds.nodata, ds.transform


def rectify_nodata_and_alpha(photo, transform, tmp_path, resampling, **params):
    """The photo rectified with OUTSIDE=nodata (``params`` added) and, as the reference, with
    OUTSIDE=alpha: ``((data, valid, nodata, transform), (data, valid, nodata, transform))``."""
    return (rectify(photo, transform, tmp_path / "n.tif", OUTSIDE="nodata",
                    RESAMPLING=resampling, **params),
            rectify(photo, transform, tmp_path / "a.tif", OUTSIDE="alpha",
                    RESAMPLING=resampling))


def footprint(t: Affine, shape) -> np.ndarray:
    """Cells whose centre maps inside the photo, by the inverse similarity."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]] + 0.5
    x, y = t * (cols, rows)
    dx, dy = (x - X0) / SCALE, (y - Y0) / SCALE
    c, s = np.cos(THETA), np.sin(THETA)
    col, row = c * dx + s * dy, s * dx - c * dy
    return (col > 0) & (col < W) & (row > 0) & (row < H)


@pytest.mark.parametrize("bands", [1, 3])
@pytest.mark.parametrize("resampling", ["cubic", "lanczos"])
def test_overshoot_to_nodata_stays_valid(tmp_path, transform, resampling, bands):
    photo = write_photo(tmp_path / "p.tif", stripes(bands))
    (data, valid, nodata, t), (ref, ref_valid, _, _) = rectify_nodata_and_alpha(
        photo, transform, tmp_path, resampling)
    assert nodata == 0
    inside = footprint(t, valid.shape)
    assert (valid == inside).all()  # was 18441 of 24580 with cubic: holes
    assert (ref_valid == inside).all()
    assert not (data[:, valid] == 0).all(axis=0).any()  # no valid cell at nodata
    dark = (ref[:bands] == 0).all(axis=0) & inside  # the undershoots
    assert dark.sum() > 1000
    assert (data[:, dark] == 1).all()  # one step off nodata, as gdalwarp
    np.testing.assert_array_equal(data[:, inside & ~dark], ref[:bands, inside & ~dark])


def test_masked_source_keeps_its_valid_cells(tmp_path, transform):
    """A photo with a nodata value (the source-mask path): its nodata pixels stay no data,
    its valid ones that cubic takes to 0 stay valid."""
    data = stripes(1)
    data[:, 30:50, 40:70] = 0  # the photo's no data
    photo = write_photo(tmp_path / "p.tif", data, nodata=0)
    (out, valid, nodata, _), (ref, ref_valid, _, _) = rectify_nodata_and_alpha(
        photo, transform, tmp_path, "cubic")
    assert nodata == 0
    assert (valid == ref_valid).all()  # the alpha output's validity: same geometry and mask
    assert ref_valid.sum() > 15000 and not (out[0][valid] == 0).any()
    dark = (ref[0] == 0) & ref_valid
    assert dark.sum() > 1000 and (out[0][dark] == 1).all()
    np.testing.assert_array_equal(out[0][valid & ~dark], ref[0][valid & ~dark])


def test_user_nodata_equal_to_an_interpolated_value(tmp_path, transform):
    """Bilinear between 2 and 250 passes through 126: with NODATA=126 those cells were no data;
    now 125 (GDAL's nodata - 1)."""
    photo = write_photo(tmp_path / "p.tif", stripes(1))
    (out, valid, nodata, t), (ref, _, _, _) = rectify_nodata_and_alpha(
        photo, transform, tmp_path, "bilinear", NODATA=126)
    inside = footprint(t, valid.shape)
    assert nodata == 126 and (valid == inside).all()
    hit = (ref[0] == 126) & inside
    assert hit.sum() > 10 and (out[0][hit] == 125).all()
    np.testing.assert_array_equal(out[0][inside & ~hit], ref[0][inside & ~hit])


def test_remap_path_without_fast(tmp_path):
    """The generic coordinate-array path (cv2.remap, not the packed warpPerspective one)."""
    from toolbox.io.grid import GridSpec
    from toolbox.raster.homography import HomographyMap
    from toolbox.raster.warp import warp_to_geotiff

    photo = write_photo(tmp_path / "p.tif", stripes(3))
    c, s = np.cos(THETA), np.sin(THETA)
    p2g = np.array([[SCALE * c, SCALE * s, X0], [SCALE * s, -SCALE * c, Y0], [0, 0, 1]])
    grid = GridSpec(Affine(0.5, 0, X0 - 30, 0, -0.5, Y0 + 70), 320, 320, "EPSG:3003")
    for fast in (False, True):
        out = tmp_path / f"o_{fast}.tif"
        warp_to_geotiff(photo, HomographyMap(np.linalg.inv(p2g), grid.transform), grid, out,
                        resampling="cubic", outside="nodata", overviews=False, fast=fast)
        with rasterio.open(out) as ds:
            data, valid = ds.read(), ds.dataset_mask() > 0
        inside = footprint(grid.transform, valid.shape)
        assert (valid == inside).all(), fast
        assert not (data[:, valid] == 0).all(axis=0).any()


def test_keep_off_nodata_steps_as_gdal():
    from toolbox.raster.writer import keep_off_nodata

    one = np.ones((1, 1), bool)
    assert keep_off_nodata(np.array([[[100]]], "uint8"), one, 100).item() == 99
    assert keep_off_nodata(np.array([[[0]]], "uint8"), one, 0).item() == 1
    assert keep_off_nodata(np.array([[[255]]], "uint8"), one, 255).item() == 254
    assert keep_off_nodata(np.array([[[-32768]]], "int16"), one, -32768).item() == -32767
    assert keep_off_nodata(np.array([[[5]]], "int16"), one, 5).item() == 4


def test_ortho_photo_planned_path(tmp_path):
    """ortho:photo (the planned-map packed path) on a flat DEM: the nodata output's valid cells
    are the alpha output's (the footprint; 25 % of them were holes with cubic), none at 0."""
    import yaml
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    n, pixel = 200, 230.0 / 200
    img = np.full((3, n, n), 2, "uint8")
    img[:, :, ::7] = 250
    img[:, ::9, :] = 250
    profile = {"driver": "GTiff", "width": n, "height": n, "count": 3, "dtype": "uint8"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(tmp_path / "p1.tif", "w", **profile) as dst:
            dst.write(img)
    write_raster(tmp_path / "dem.tif", np.full((40, 40), 250.0, "float32"),
                 from_origin(1686600.0, 4801600.0, 100.0, 100.0), "EPSG:3003", nodata=-9999.0)
    camera = {"name": "c", "principal_distance_mm": 153.0, "image_size_px": [n, n],
              "pixel_size_mm": pixel, "frame_size_mm": [230.0, 230.0]}
    exterior = dict(zip(("X0", "Y0", "Z0", "omega", "phi", "kappa"),
                        (1688600.0, 4799600.0, 1700.0, 0.0, 0.0, 0.4), strict=True))
    (tmp_path / "project.yaml").write_text(yaml.safe_dump({
        "format": "orientation-project", "version": 1, "crs": "EPSG:3003", "angle_unit": "rad",
        "cameras": [camera], "photos": [{"id": "p1", "camera": "c", "image": "p1.tif",
                                         "exterior": exterior}]}, sort_keys=False))
    runs = {}
    for outside in ("alpha", "nodata"):
        out = tmp_path / f"o_{outside}.tif"
        toolbox.run("ortho:photo", {"INPUT": tmp_path / "p1.tif", "DEM": tmp_path / "dem.tif",
                                    "PROJECT": tmp_path / "project.yaml", "CELL_SIZE": 10.0,
                                    "RESAMPLING": "cubic", "OUTSIDE": outside, "OUTPUT": out,
                                    "OVERVIEWS": False})
        with rasterio.open(out) as ds:
            runs[outside] = (ds.read(), ds.dataset_mask() > 0, ds.nodata)
    (ref, ref_valid, _), (data, valid, nodata) = runs["alpha"], runs["nodata"]
    assert nodata == 0 and ref_valid.sum() > 5000
    assert (valid == ref_valid).all()
    assert not (data[:, valid] == 0).all(axis=0).any()
    dark = (ref[:3] == 0).all(axis=0) & ref_valid
    assert dark.sum() > 500 and (data[:, dark] == 1).all()
    np.testing.assert_array_equal(data[:, valid & ~dark], ref[:3, valid & ~dark])


@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("nodata", [-9999.0, 2.0, 0.0, 1000.0])
def test_keep_off_nodata_float_step_is_valid_for_gdal(tmp_path, dtype, nodata):
    """A float one ulp off nodata is still no data for GDAL's mask (it reads values within about
    4 float ulps as nodata): the moved value and the cells near nodata must be read as valid by
    GDAL itself (rasterio's dataset_mask of a written GeoTIFF)."""
    from toolbox.raster.writer import keep_off_nodata

    nd = np.dtype(dtype).type(nodata)
    near = [nd, np.nextafter(nd, np.inf), np.nextafter(np.nextafter(nd, -np.inf), -np.inf), 7.5]
    data = np.array([[near]], dtype)
    out = keep_off_nodata(data.copy(), np.ones((1, 4), bool), nodata)
    assert out[0, 0, 3] == 7.5 and np.abs(out[0, 0, :3] - nd).max() < 1e-2 + 1e-6 * abs(nd)
    path = tmp_path / "f.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=4, height=1, count=1, dtype=dtype,
                           nodata=nodata) as dst:
            dst.write(out)
        with rasterio.open(path) as src:
            assert (src.dataset_mask() == 255).all()


def test_float_photo_with_nodata_at_its_dark_value(tmp_path, transform):
    """A float32 photo, NODATA=2 (its dark value): cubic gives 2.0 and values a few ulps off
    it, which GDAL's mask reads as no data too (5900 of 24580 cells were holes)."""
    photo = write_photo(tmp_path / "p.tif", stripes(1).astype("float32"))
    (out, valid, nodata, t), (ref, _, _, _) = rectify_nodata_and_alpha(
        photo, transform, tmp_path, "cubic", NODATA=2)
    inside = footprint(t, valid.shape)
    assert nodata == 2 and (valid == inside).all()
    same = inside & ~np.isnan(ref[0])  # (the NaN-nodata run loses edge cells: see report)
    assert same.sum() > 20000 and np.abs(out[0][same] - ref[0][same]).max() < 1e-5
