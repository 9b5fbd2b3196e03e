"""A paletted photo (one band with a colour table) is warped as its colours: rectify:image and
ortho:photo give, cell for cell, what they give of the photo expanded by
``gdal_translate -expand rgb`` (``rgba`` when the table has transparency). They dropped the
table and interpolated the palette indices into a grey band, exit 0."""

from __future__ import annotations

import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.enums import ColorInterp

import toolbox

HERE = Path(__file__).parents[2] / "algorithms"
sys.path.insert(0, str(HERE / "rectify"))
sys.path.insert(0, str(HERE / "ortho"))
import ortho_scene  # noqa: E402
import rectify_scene  # noqa: E402

pytestmark = [pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning"),
              pytest.mark.skipif(shutil.which("gdal_translate") is None,
                                 reason="gdal_translate (the reference expansion) not found")]


def paletted(source, path, transparent=False):
    """``source``'s first band as palette indices of a table that is not a grey ramp (so
    interpolating indices is not interpolating colours); index 0 transparent if asked."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(source) as src:
            index = src.read(1).astype("uint8")
            profile = {"driver": "GTiff", "width": src.width, "height": src.height, "count": 1,
                       "dtype": "uint8", "photometric": "palette"}
        index[:40, :60] = 0
        table = {k: (k, (255 - 3 * k) % 256, (7 * k) % 256, 0 if transparent and k == 0 else 255)
                 for k in range(256)}
        with rasterio.open(path, "w", **profile) as dst:
            dst.write(index, 1)
            dst.write_colormap(1, table)
        with rasterio.open(path) as src:
            assert src.colorinterp == (ColorInterp.palette,)
    return path


def expanded(path, how):
    out = path.with_name(path.stem + f"_{how}.tif")
    subprocess.run(["gdal_translate", "-q", "-expand", how, str(path), str(out)], check=True)
    return out


def assert_same_raster(one, other, bands):
    with rasterio.open(one) as a, rasterio.open(other) as b:
        assert a.colorinterp == bands and b.colorinterp == bands
        assert a.transform == b.transform
        np.testing.assert_array_equal(a.read(), b.read())


@pytest.fixture(scope="module")
def rectify_files(tmp_path_factory):
    return rectify_scene.photo_and_transform(tmp_path_factory.mktemp("palette_rectify"), "uint8",
                                             "grey.tif")


RGBA = (ColorInterp.red, ColorInterp.green, ColorInterp.blue, ColorInterp.alpha)


@pytest.mark.parametrize("transparent, how", [(False, "rgb"), (True, "rgba")])
def test_rectify_warps_a_paletted_photo_as_its_colours(tmp_path, rectify_files, transparent,
                                                       how):
    grey, transform = rectify_files
    photo = paletted(grey, tmp_path / "pal.tif", transparent)
    reference = expanded(photo, how)
    for source, out in ((photo, "o_pal.tif"), (reference, "o_ref.tif")):
        toolbox.run("rectify:image", {"INPUT": source, "TRANSFORM": transform, "CELL_SIZE": 1.0,
                                      "OUTPUT": tmp_path / out})
    assert_same_raster(tmp_path / "o_pal.tif", tmp_path / "o_ref.tif", RGBA)


def test_ortho_warps_a_paletted_photo_as_its_colours(tmp_path):
    scene = ortho_scene.make_scene(tmp_path)
    photo = paletted(scene.photo_path, tmp_path / "pal.tif")
    reference = expanded(photo, "rgb")
    for source, out in ((photo, "o_pal.tif"), (reference, "o_ref.tif")):
        toolbox.run("ortho:photo", {"INPUT": source, "PROJECT": scene.project_path,
                                    "PHOTO": "p1", "DEM": scene.dem_path, "CELL_SIZE": 5.0,
                                    "OUTPUT": tmp_path / out})
    assert_same_raster(tmp_path / "o_pal.tif", tmp_path / "o_ref.tif", RGBA)


def test_a_paletted_photo_whose_path_holds_a_question_mark_is_refused(tmp_path, rectify_files):
    grey, transform = rectify_files  # GDAL's vrt:// expansion cannot name it
    photo = paletted(grey, tmp_path / "p?1.tif")
    with pytest.raises(toolbox.ToolboxError, match=r"paletted photo whose path holds a '\?': "
                                                   r"expand it first: gdal_translate -expand rgb"):
        toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 1.0,
                                      "OUTPUT": tmp_path / "o.tif"})
    assert not (tmp_path / "o.tif").exists()
