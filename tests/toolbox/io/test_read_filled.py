"""read_filled against rasterio's own masked read (the oracle): the same NaN cells, the same
values, for every mask GDAL gives a band."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin
from rasterio.windows import Window

from toolbox.io.raster import read_filled

CASES = [  # dtype, nodata (None: no nodata)
    ("uint8", None), ("uint8", 0), ("uint8", 255), ("int16", -9999), ("uint16", 65535),
    ("int32", -2147483648), ("float32", -9999.0), ("float32", 0.1), ("float32", float("nan")),
    ("float32", -3.4028234663852886e38), ("float64", -9999.0), ("float64", 0.1),
]


def _values(dtype: str, nodata, rng) -> np.ndarray:
    kind = np.dtype(dtype).kind
    if kind == "f":
        z = rng.uniform(-10, 10, (37, 53)).astype(dtype)
        z[5, 7] = np.nan  # a NaN cell that is not nodata (unless nodata is NaN)
    else:
        info = np.iinfo(dtype)
        z = rng.integers(max(info.min, -1000), min(info.max, 1000), (37, 53)).astype(dtype)
    if nodata is not None:
        z[rng.random(z.shape) < 0.2] = np.array(nodata).astype(dtype)
    return z


@pytest.mark.parametrize(("dtype", "nodata"), CASES)
def test_read_filled_is_the_masked_read(tmp_path, dtype, nodata):
    rng = np.random.default_rng(7)
    z = _values(dtype, nodata, rng)
    path = tmp_path / "band.tif"
    with rasterio.open(path, "w", driver="GTiff", width=53, height=37, count=1, dtype=dtype,
                       nodata=nodata, transform=from_origin(0, 37, 1, 1), tiled=True,
                       blockxsize=16, blockysize=16) as dst:
        dst.write(z, 1)
    with rasterio.open(path) as src:
        for window in (None, Window(3, 4, 20, 17)):
            want = src.read(1, window=window, masked=True).astype("float64").filled(np.nan)
            got = read_filled(src, 1, window=window)
            assert got.dtype == np.float64
            np.testing.assert_array_equal(got, want)  # NaN positions equal too
        if nodata is not None and not (isinstance(nodata, float) and np.isnan(nodata)):
            assert np.isnan(read_filled(src, 1)).sum() >= (z == np.array(nodata).astype(dtype)).sum()


def test_read_filled_with_a_mask_band(tmp_path):
    """A band with an internal mask (not nodata) takes rasterio's masked path: the same array."""
    z = np.arange(20 * 30, dtype="float32").reshape(20, 30)
    mask = np.full(z.shape, 255, dtype="uint8")
    mask[3:9, 4:12] = 0
    path = tmp_path / "masked.tif"
    with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True):
        with rasterio.open(path, "w", driver="GTiff", width=30, height=20, count=1,
                           dtype="float32", transform=from_origin(0, 20, 1, 1)) as dst:
            dst.write(z, 1)
            dst.write_mask(mask)
    with rasterio.open(path) as src:
        got = read_filled(src, 1, dtype="float32")
        want = src.read(1, masked=True).filled(np.nan)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, want)
    assert np.isnan(got[3:9, 4:12]).all() and not np.isnan(got).sum() > 6 * 8
