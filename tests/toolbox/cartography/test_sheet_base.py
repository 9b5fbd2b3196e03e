"""The map sheet's base raster (toolbox.cartography.sheet_io.read_base): a raster stored
south-up, east to west or rotated is drawn where it lies, north up, as the same raster stored
north-up (it was left out in silence, or drawn unrotated, or crashed); a Float32 raster with NaN
and no nodata tag is stretched over its values (it came out blank)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import rasterio
from affine import Affine

from toolbox.cartography.sheet_io import read_base

X0, Y0, CELL, ROWS, COLS = 1688000.0, 4800000.0, 2.0, 120, 150
BOUNDS = (X0 + 20, Y0 - 200, X0 + 260, Y0 - 10)  # a sheet inside the raster


def grey(rows=ROWS, cols=COLS):
    r, c = np.indices((rows, cols))
    return (40 + (1.5 * c + 0.7 * r) % 180).astype("uint8")  # asymmetric: flips show


def write(path: Path, data: np.ndarray, transform, **profile) -> SimpleNamespace:
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[1], height=data.shape[0],
                       count=1, dtype=data.dtype, crs="EPSG:3003", transform=transform,
                       **profile) as dst:
        dst.write(data, 1)
    return SimpleNamespace(path=path)


def north_up(tmp_path, data=None):
    data = grey() if data is None else data
    return write(tmp_path / "north_up.tif", data, Affine(CELL, 0, X0, 0, -CELL, Y0))


@pytest.mark.parametrize("storage", ["south_up", "east_to_west", "transposed"])
def test_a_raster_stored_another_way_is_drawn_as_the_north_up_one(tmp_path, storage):
    z = grey()
    if storage == "south_up":
        info = write(tmp_path / "b.tif", z[::-1].copy(),
                     Affine(CELL, 0, X0, 0, CELL, Y0 - CELL * ROWS))
    elif storage == "east_to_west":
        info = write(tmp_path / "b.tif", z[:, ::-1].copy(),
                     Affine(-CELL, 0, X0 + CELL * COLS, 0, -CELL, Y0))
    else:  # rows along x, columns along -y: a rotated geotransform
        info = write(tmp_path / "b.tif", z.T.copy(), Affine(0, CELL, X0, -CELL, 0, Y0))
    image, extent = read_base(north_up(tmp_path), BOUNDS, 1000)
    other, other_extent = read_base(info, BOUNDS, 1000)
    assert other.shape == image.shape and other_extent == pytest.approx(extent)
    diff = np.abs(other.astype(int) - image.astype(int))
    if storage == "transposed":  # GDAL's warper with its approximate transformer
        assert np.median(diff) <= 1 and np.percentile(diff, 95) <= 6
    else:
        assert diff.max() == 0


def test_nan_without_a_nodata_tag_is_no_value(tmp_path):
    z = grey().astype("float32") * 10.0
    z[:40, :50] = np.nan
    image, _ = read_base(write(tmp_path / "nan.tif", z, Affine(CELL, 0, X0, 0, -CELL, Y0)),
                         (X0, Y0 - CELL * ROWS, X0 + CELL * COLS, Y0), 1000)
    assert image[:40, :50].min() == 255  # white where there is no value
    assert image[50:, 60:].std() > 30  # the relief stretched, not a blank page
