"""warp_to_geotiff opens its photo once (every ortho of ortho:photo and ortho:batch): it opened
it seven times (the paletted-photo check three times, a dataset each for the layout, the band
names and the size, then the tiles' own), each open parsing the file's header again. The
pixels are the photo's, checked against NumPy slicing."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

from toolbox.executor import Executor
from toolbox.io.grid import GridSpec
from toolbox.raster.homography import HomographyMap
from toolbox.raster.warp import warp_to_geotiff

pytestmark = pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")


def test_the_photo_is_opened_once_and_warped_exactly(tmp_path, monkeypatch):
    rng = np.random.default_rng(19)
    photo = rng.integers(0, 255, (3, 200, 300), dtype="uint8")
    path = tmp_path / "photo.tif"
    with rasterio.open(path, "w", driver="GTiff", width=300, height=200, count=3,
                       dtype="uint8", photometric="RGB") as dst:
        dst.write(photo)
        dst.set_band_description(1, "red channel")
    # cell (i, j) of a 1-unit grid 80 x 100 is source pixel (row i + 5, col j + 10): the
    # source pixel convention puts a pixel's centre at +0.5, as the cells' centres are
    grid = GridSpec(Affine(1, 0, 0, 0, -1, 80), 100, 80, None)
    hmap = HomographyMap(np.array([[1.0, 0.0, 10.0], [0.0, -1.0, 85.0], [0.0, 0.0, 1.0]]),
                         grid.transform)
    opened = []
    real_open = rasterio.open

    def counting_open(fp, *args, **kwargs):
        opened.append(str(fp))
        return real_open(fp, *args, **kwargs)

    monkeypatch.setattr(rasterio, "open", counting_open)
    out = tmp_path / "ortho.tif"
    warp_to_geotiff(str(path), hmap, grid, out, resampling="nearest",
                    executor=Executor("local", 1))
    monkeypatch.undo()
    assert opened.count(str(path)) == 1
    with rasterio.open(out) as src:
        data = src.read()
        assert src.descriptions[0] == "red channel"  # the band names, from the one open
    np.testing.assert_array_equal(data[:3], photo[:, 5:85, 10:110])
    assert (data[3] == 255).all()
