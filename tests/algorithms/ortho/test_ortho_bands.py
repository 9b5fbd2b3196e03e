"""ortho:photo keeps a 1-4 band photo's bands, in order, with one alpha band: the last (a 4-band
photo used to come out with band 2 tagged alpha as well, and a 2-band one as red/green). Three
byte bands are written as RGB, as before."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.enums import ColorInterp

import toolbox

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402


@pytest.fixture(scope="module")
def grey(tmp_path_factory):
    return scene.make_scene(tmp_path_factory.mktemp("bands_scene"))


@pytest.mark.parametrize("bands, photometric", [(1, "MINISBLACK"), (2, "MINISBLACK"),
                                                (4, "MINISBLACK"), (3, "RGB")])
def test_bands_kept_in_order_with_the_last_band_alpha(grey, tmp_path, bands, photometric):
    with rasterio.open(grey.photo_path) as src:
        a = src.read(1).astype(np.int32)
        profile = src.profile
    # band k is a known affine function of band 1, so the order can be checked after resampling
    stack = np.stack([a if k % 2 == 0 else 255 - a for k in range(bands)]).astype("uint8")
    profile.update(count=bands, photometric=photometric)
    photo = tmp_path / "p1.tif"
    with rasterio.open(photo, "w", **profile) as dst:
        dst.write(stack)
    toolbox.run("ortho:photo", {"INPUT": photo, "PROJECT": grey.project_path, "DEM": grey.dem_path,
                                "CELL_SIZE": 10.0, "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "o.tif") as src:
        out = src.read().astype(np.int32)
        interp = list(src.colorinterp)
    assert out.shape[0] == bands + 1
    assert interp[-1] == ColorInterp.alpha and ColorInterp.alpha not in interp[:-1]
    if photometric == "RGB":
        assert interp[:3] == [ColorInterp.red, ColorInterp.green, ColorInterp.blue]
    else:
        assert ColorInterp.red not in interp
    valid = out[-1] == 255
    assert valid.mean() > 0.3
    for k in range(1, bands):
        expected = out[0] if k % 2 == 0 else 255 - out[0]
        assert np.abs(out[k][valid] - expected[valid]).max() <= 1
