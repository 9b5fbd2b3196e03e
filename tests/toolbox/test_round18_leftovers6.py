"""Round 18, masks:

- mosaic:cut took a sheet's valid cells from band 1's mask: a valid dark-blue pixel (0, 0, 255)
  of an RGB with nodata 0 was blanked, and a sheet holding only such pixels was dropped
  (gdal_translate of the same window keeps them), exit 0; now GDAL's dataset mask;
- a raster whose bands have different nodata values (a VRT's) was cut, and a photo of that kind
  warped (rectify:image, ortho:photo, ortho:batch), under band 1's mask alone, exit 0; now
  refused naming INPUT (exit 2), since the output holds one mask for all the bands (gdalwarp
  fills each band's nodata cells with 0 under one alpha: no mask says which values are empty).
"""

from __future__ import annotations

import shutil
import subprocess
import warnings

import numpy as np
import pytest
import rasterio
import shapely
from rasterio.transform import from_origin

import toolbox
from toolbox.errors import ParameterError
from toolbox.mosaic.sheets import clip_raster

X0, Y0 = 500000.0, 5000000.0


def _rgb(path, data, nodata=0):
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                       count=data.shape[0], dtype="uint8", nodata=nodata, crs="EPSG:32632",
                       transform=from_origin(X0, Y0 + data.shape[1], 1, 1)) as dst:
        dst.write(data)
    return path


def _per_band_vrt(tif, vrt, band, nodata):
    """A VRT of ``tif`` whose band ``band`` alone gets ``nodata`` (the others none)."""
    subprocess.run(["gdal_translate", "-q", "-of", "VRT", "-a_nodata", "none", str(tif),
                    str(vrt)], check=True)
    parts = vrt.read_text().split("<VRTRasterBand")
    head, tail = parts[band].split(">", 1)
    parts[band] = f"{head}>\n    <NoDataValue>{nodata}</NoDataValue>{tail}"
    vrt.write_text("<VRTRasterBand".join(parts))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(vrt) as src:
            assert src.nodatavals[band - 1] == nodata and src.nodatavals[0 if band > 1 else 1] \
                is None
    return vrt


needs_gdal = pytest.mark.skipif(shutil.which("gdal_translate") is None,
                                reason="gdal_translate not found")


def test_cut_keeps_cells_valid_in_any_band(tmp_path):
    data = np.zeros((3, 20, 20), np.uint8)
    data[:, 10:, :] = 100  # grey south half
    data[2, 2:5, 2:5] = 255  # north half: only dark-blue pixels (band 1 = 0), valid
    data[:, 12, 3] = (0, 200, 0)  # a valid green pixel in the grey half
    src = _rgb(tmp_path / "rgb.tif", data)
    north = shapely.box(X0, Y0 + 10, X0 + 20, Y0 + 20)
    assert clip_raster(src, north, tmp_path / "north.tif")  # was dropped: no valid cell
    with rasterio.open(tmp_path / "north.tif") as out:
        np.testing.assert_array_equal(out.read(), data[:, :10])
        assert (out.dataset_mask() > 0).sum() == 9
    assert clip_raster(src, shapely.box(X0, Y0, X0 + 20, Y0 + 10), tmp_path / "south.tif")
    with rasterio.open(tmp_path / "south.tif") as out:
        np.testing.assert_array_equal(out.read()[:, 2, 3], (0, 200, 0))  # was (0, 0, 0)


@needs_gdal
def test_cut_matches_gdal_translate_of_the_window(tmp_path):
    data = np.zeros((3, 20, 20), np.uint8)
    data[2, 2:5, 2:5] = 255
    data[1, 6, 8] = 7
    src = _rgb(tmp_path / "rgb.tif", data)
    assert clip_raster(src, shapely.box(X0, Y0 + 10, X0 + 10, Y0 + 20), tmp_path / "t.tif")
    subprocess.run(["gdal_translate", "-q", "-projwin", str(X0), str(Y0 + 20), str(X0 + 10),
                    str(Y0 + 10), str(src), str(tmp_path / "g.tif")], check=True)
    with rasterio.open(tmp_path / "t.tif") as t, rasterio.open(tmp_path / "g.tif") as g:
        np.testing.assert_array_equal(t.read(), g.read())
        np.testing.assert_array_equal(t.dataset_mask(), g.dataset_mask())


@needs_gdal
def test_cut_refuses_a_nodata_per_band(tmp_path):
    data = np.full((3, 20, 20), 50, np.uint8)
    vrt = _per_band_vrt(_rgb(tmp_path / "rgb.tif", data, None), tmp_path / "pb.vrt", 2, 50)
    with pytest.raises(ParameterError, match=r"INPUT.*band 1: none, band 2: 50, band 3: none"):
        toolbox.run("mosaic:cut", {"INPUT": vrt, "SCALE": 1000, "SHEET_WIDTH": 1,
                                   "SHEET_HEIGHT": 1, "OUTPUT": tmp_path / "out"})


@needs_gdal
def test_rectify_refuses_a_photo_with_nodata_on_one_band(tmp_path):
    photo = np.full((3, 30, 40), 60, np.uint8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(tmp_path / "p.tif", "w", driver="GTiff", width=40, height=30,
                           count=3, dtype="uint8") as dst:
            dst.write(photo)
    vrt = _per_band_vrt(tmp_path / "p.tif", tmp_path / "p.vrt", 2, 77)
    gcps = tmp_path / "g.csv"
    gcps.write_text("id,col,row,X,Y\n" + "".join(
        f"P{k},{c},{r},{1000 + c},{2000 - r}\n"
        for k, (c, r) in enumerate([(0, 0), (40, 0), (0, 30), (40, 30), (20, 15)])))
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "MODEL": "affine",
                                     "ROBUST": "none", "OUTPUT": tmp_path / "t.json"})
    with pytest.raises(ParameterError, match=r"INPUT.*nodata value per band \(band 1: none, "
                                             r"band 2: 77, band 3: none\)"):
        toolbox.run("rectify:image", {"INPUT": vrt, "TRANSFORM": tmp_path / "t.json",
                                      "CELL_SIZE": 1.0, "OUTPUT": tmp_path / "r.tif"})


@needs_gdal
def test_photo_images_with_a_nodata_per_band_are_refused(tmp_path):
    from toolbox.io.raster import open_raster_info

    data = np.full((3, 20, 20), 50, np.uint8)
    vrt = _per_band_vrt(_rgb(tmp_path / "rgb.tif", data, None), tmp_path / "pb.vrt", 3, 0)
    with pytest.raises(ParameterError, match=r"IMAGES.*band 3: 0"):  # ortho:batch's photos
        open_raster_info(vrt, "IMAGES")
    assert open_raster_info(tmp_path / "rgb.tif", "IMAGES").count == 3  # one nodata: fine


def test_mosaic_of_orthos_with_different_nodata_keeps_their_valid_values(tmp_path):
    """mosaic:build wrote the first input's nodata (0): the other ortho's valid black pixels
    (its nodata is 255) became no data, exit 0; now an alpha band."""
    paths = []
    for name, x0, nodata, value in (("a", 0, 0, 100), ("b", 30, 255, 0)):
        paths.append(tmp_path / f"{name}.tif")
        with rasterio.open(paths[-1], "w", driver="GTiff", width=20, height=20, count=1,
                           dtype="uint8", nodata=nodata, crs="EPSG:32633",
                           transform=from_origin(X0 + x0, Y0 + 20, 1, 1)) as dst:
            dst.write(np.full((1, 20, 20), value, np.uint8))
    toolbox.run("mosaic:build", {"INPUT": paths, "BLEND": "none", "OUTPUT": tmp_path / "m.tif"})
    with rasterio.open(tmp_path / "m.tif") as out:
        valid = out.dataset_mask() > 0
        assert valid.sum() == 800  # was 400
        assert (out.read(1)[valid] == 0).sum() == 400  # b's black pixels, valid


def _blue_square(path):
    """100 x 100 grey (120) RGB, nodata 0, a valid pure-blue (0, 0, 255) square at rows and
    columns 40..59 and a true no-data strip (0, 0, 0) on rows 0..9."""
    data = np.full((3, 100, 100), 120, np.uint8)
    data[:, 40:60, 40:60] = np.array([0, 0, 255])[:, None, None]
    data[:, :10] = 0
    with rasterio.open(path, "w", driver="GTiff", width=100, height=100, count=3, dtype="uint8",
                       nodata=0, crs="EPSG:32632", transform=from_origin(X0, Y0 + 100, 1, 1)
                       ) as dst:
        dst.write(data)
    return path


def test_sheet_base_draws_a_pixel_with_a_zero_band_in_its_colours(tmp_path):
    """carto:sheet's base masked each band by its own nodata: the blue square was drawn white
    (255, 255, 255), a (0, 3, 8) shadow (255, 3, 8)."""
    from toolbox.cartography.sheet_io import read_base
    from toolbox.io.raster import open_raster_info

    info = open_raster_info(_blue_square(tmp_path / "rgb.tif"), "BASE", "map")
    image, _ = read_base(info, (X0, Y0, X0 + 100, Y0 + 100), 500, dpi=254)  # 1 m cells
    assert image.shape == (100, 100, 3)
    np.testing.assert_array_equal(image[50, 50], (0, 0, 255))  # was (255, 255, 255)
    np.testing.assert_array_equal(image[80, 5], (120, 120, 120))
    np.testing.assert_array_equal(image[5, 50], (255, 255, 255))  # no data: paper


def test_ortho_samples_of_a_pixel_with_a_zero_band_are_data(tmp_path):
    """orientation:control's ortho chips and the ortho check's patches called a pixel with one
    band at the nodata value no data (NaN): the blue square was a hole."""
    from toolbox.cartography.quality_ortho_job import _ortho_patch
    from toolbox.matching.ortho_match import OrthoReference

    path = _blue_square(tmp_path / "rgb.tif")
    ortho = OrthoReference.open(path)
    values = ortho.sample(np.array([X0 + 50.0, X0 + 20.0, X0 + 50.0]),
                          np.array([Y0 + 50.0, Y0 + 20.0, Y0 + 95.0]))
    np.testing.assert_allclose(values[:2], (85.0, 120.0))  # mean of (0, 0, 255): 85, was NaN
    assert np.isnan(values[2])
    with rasterio.open(path) as src:
        grey, _ = _ortho_patch(src, X0 + 50.0, Y0 + 50.0, 1.0, 3)
    assert np.isfinite(grey).all() and (grey == 85.0).all()


@needs_gdal
def test_mosaic_refuses_an_ortho_with_a_nodata_per_band(tmp_path):
    """Its cells where band 1 is valid were mosaicked with band 2's nodata value as data."""
    data = np.full((3, 20, 20), 50, np.uint8)
    vrt = _per_band_vrt(_rgb(tmp_path / "rgb.tif", data, None), tmp_path / "pb.vrt", 2, 50)
    with pytest.raises(ParameterError, match=r"INPUT.*band 1: none, band 2: 50, band 3: none"):
        toolbox.run("mosaic:build", {"INPUT": [vrt], "OUTPUT": tmp_path / "m.tif"})
