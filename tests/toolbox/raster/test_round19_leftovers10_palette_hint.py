"""OUTSIDE=nodata is refused for a paletted photo with transparency (it is read as RGBA, whose
alpha the output keeps); the refusal's hint said ``gdal_translate -b 1 -b 2 -b 3``, which does
not apply to a one-band paletted file (GDAL: "Band 2 requested, but only bands 1 to 1
available"). It now says ``gdal_translate -expand rgb``, and that hint works: the expanded file
is accepted with OUTSIDE=nodata."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.enums import ColorInterp

import toolbox

sys.path.insert(0, str(Path(__file__).parent))
from test_palette_photos import rectify_scene  # noqa: E402

pytestmark = [pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning"),
              pytest.mark.filterwarnings("ignore::UserWarning"),
              pytest.mark.skipif(shutil.which("gdal_translate") is None,
                                 reason="gdal_translate not found")]


def transparent_paletted(source, path):
    """``source``'s first band as palette indices, index 0 transparent, as a PNG (a TIFF
    palette holds no alpha: GDAL reads its entries back opaque)."""
    with rasterio.open(source) as src:
        index = src.read(1).astype("uint8")
    index[:40, :60] = 0
    with rasterio.open(path, "w", driver="PNG", width=index.shape[1], height=index.shape[0],
                       count=1, dtype="uint8") as dst:
        dst.write(index, 1)
        dst.write_colormap(1, {k: (k, 255 - k, 0, 0 if k == 0 else 255) for k in range(256)})
    with rasterio.open(path) as src:
        assert src.colorinterp == (ColorInterp.palette,) and src.colormap(1)[0][3] == 0
    return path


def test_nodata_refusal_for_a_transparent_paletted_photo_hints_expand_rgb(tmp_path):
    grey, transform = rectify_scene.photo_and_transform(tmp_path, "uint8", "grey.tif")
    photo = transparent_paletted(grey, tmp_path / "photo.png")
    params = {"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 1.0, "OUTSIDE": "nodata",
              "OUTPUT": tmp_path / "o.tif"}
    with pytest.raises(toolbox.ToolboxError, match="OUTSIDE") as refused:
        toolbox.run("rectify:image", params)
    assert not (tmp_path / "o.tif").exists()
    hint = re.search(r"\((gdal_translate [^)]*)\)", str(refused.value))
    assert hint and "-expand rgb " in hint.group(1) and " -b " not in hint.group(1), \
        str(refused.value)
    # the hint, run as given (on this photo), gives a photo the warp takes with OUTSIDE=nodata
    args = shlex.split(hint.group(1))
    assert args[-2] == str(photo)
    subprocess.run(args, check=True, capture_output=True, cwd=tmp_path)
    toolbox.run("rectify:image", {**params, "INPUT": tmp_path / "photo_rgb.tif"})
    with rasterio.open(tmp_path / "o.tif") as out:
        assert out.count == 3 and out.nodata == 0
        assert np.any(out.read(1) > 0)
