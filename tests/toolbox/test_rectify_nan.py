"""rectify:image on a partly-NaN float photo (issue 24 §4): the cells on NaN pixels are no data
(alpha 0, or nodata without alpha), never opaque NaN, and the report counts them.

Truth: four control points define an exact similarity, pixel (col, row) -> (X0 + col, Y0 - row)
in metres, so the output grid at 1 m is the photo's own grid and, with nearest resampling, the
NaN block of the photo is exactly the block of no-data cells."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.feedback import Feedback

X0, Y0 = 1688000.0, 4800000.0
W, H = 120, 80
ROWS, COLS = slice(10, 20), slice(30, 50)  # the NaN block: 10 x 20 = 200 pixels


@pytest.fixture
def nan_photo(tmp_path):
    rng = np.random.default_rng(4)
    data = rng.uniform(10, 200, (3, H, W)).astype("float32")
    data[:, ROWS, COLS] = np.nan
    photo = tmp_path / "photo.tif"
    with rasterio.open(photo, "w", driver="GTiff", width=W, height=H, count=3,
                       dtype="float32") as dst:
        dst.write(data)
    gcps = tmp_path / "gcps.csv"
    corners = [(0.0, 0.0), (W, 0.0), (W, H), (0.0, H), (W / 2, H / 3)]
    gcps.write_text("id,col,row,X,Y,Z,role\n" + "".join(
        f"P{k},{c},{r},{X0 + c},{Y0 - r},0,control\n" for k, (c, r) in enumerate(corners)))
    transform = tmp_path / "t.json"
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "MODEL": "homography",
                                     "OUTPUT": transform})
    return photo, transform, data


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
@pytest.mark.parametrize("outside", ["alpha", "nodata"])
def test_nan_pixels_become_no_data_and_are_counted(nan_photo, tmp_path, outside):
    photo, transform, data = nan_photo
    out = tmp_path / f"r_{outside}.tif"
    feedback = Feedback()
    result = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": transform,
                                           "CELL_SIZE": 1, "RESAMPLING": "nearest",
                                           "OUTSIDE": outside, "OUTPUT": out},
                         feedback=feedback)
    assert result["STATISTICS"]["nan_cells"] == 200
    assert any("200 output cells fall on NaN pixels" in w for w in feedback.warnings)
    with rasterio.open(out) as ds:
        assert (ds.width, ds.height) == (W, H)
        assert ds.transform.c == X0 and ds.transform.f == Y0
        bands = ds.read()
        # a float photo gets NaN nodata, not an alpha band (GDAL masks only Byte/UInt16 alpha):
        # its dataset mask is what a reader sees
        assert ds.count == 3 and np.isnan(ds.nodata)
        valid = ds.dataset_mask() > 0
    expected = np.ones((H, W), bool)
    expected[ROWS, COLS] = False
    assert (valid == expected).all()  # no data exactly where the photo is NaN
    assert not np.isnan(bands[:3][:, valid]).any()  # no NaN among the valid cells
    np.testing.assert_array_equal(bands[:3][:, valid], data[:, expected])
    assert np.isnan(bands[:, ~expected]).all()
