"""Round 20 (seamfast): read_window reads a window inside an ortho in the file's own type and
converts it to float32 with numpy (GDAL's conversion was the slower part of the copy out of its
block cache). The reference is GDAL's own float32 read of the same window."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine
from rasterio.io import DatasetReader
from rasterio.windows import Window

from toolbox.mosaic.sources import open_source, read_window


@pytest.mark.parametrize("dtype", ["uint8", "int8", "uint16", "int16", "float32"])
def test_window_inside_is_read_in_its_type_as_gdal_reads_float32(tmp_path, dtype, monkeypatch):
    info = np.iinfo(dtype) if dtype != "float32" else None
    rng = np.random.default_rng(5)
    if info is None:
        data = rng.normal(0, 1e6, (3, 30, 40)).astype(dtype)
    else:
        data = rng.integers(info.min, info.max, (3, 30, 40), endpoint=True).astype(dtype)
    path = tmp_path / "o.tif"
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=3, dtype=dtype,
                       crs="EPSG:3003", transform=Affine(1, 0, 1000, 0, -1, 2000)) as d:
        d.write(data)
    asked = []
    read = DatasetReader.read

    def spy(self, *args, **kwargs):
        asked.append(kwargs.get("out_dtype"))
        return read(self, *args, **kwargs)

    monkeypatch.setattr(DatasetReader, "read", spy)
    src = open_source(path, 0)
    grid = Affine(1, 0, 990, 0, -1, 2005)  # aligned, 10 cells west, 5 north of the ortho
    got, valid = read_window(src, grid, None, Window(13, 8, 25, 20))
    monkeypatch.undo()
    assert asked == [None]  # the file's type: no conversion asked of GDAL
    with rasterio.open(path) as ds:
        want = ds.read(window=Window(3, 3, 25, 20), out_dtype="float32")
    assert got.dtype == np.float32 and got.flags.c_contiguous
    assert np.array_equal(got, want) and valid.all()


@pytest.mark.parametrize("cell", [1.0, 0.7])  # on the ortho's grid, and resampled onto another
def test_read_valid_writes_gdals_mask_into_the_given_array(tmp_path, cell):
    from toolbox.mosaic.sources import read_valid

    data = np.full((3, 30, 40), 9, dtype="uint8")
    data[:, :6, :11] = 0  # no data in a corner
    path = tmp_path / "o.tif"
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=3, dtype="uint8",
                       nodata=0, crs="EPSG:3003", transform=Affine(1, 0, 1000, 0, -1, 2000)) as d:
        d.write(data)
    src = open_source(path, 0)
    grid = Affine(cell, 0, 990, 0, -cell, 2005)
    window = Window(0, 0, 60, 45)
    out = np.zeros((2, 45, 60), dtype=bool)
    got = read_valid(src, grid, "EPSG:3003", window, out=out[1])
    assert got is out[1] or np.shares_memory(got, out)
    assert not out[0].any()
    with rasterio.open(path) as ds:  # GDAL's mask of the ortho, cell centres sampled
        mask = ds.dataset_mask() > 0
    cx = 990 + (np.arange(60) + 0.5) * cell
    cy = 2005 - (np.arange(45) + 0.5) * cell
    col, row = np.floor(cx - 1000).astype(int), np.floor(2000 - cy).astype(int)
    inside = (row[:, None] >= 0) & (row[:, None] < 30) & (col[None, :] >= 0) & (col[None, :] < 40)
    want = np.zeros((45, 60), dtype=bool)
    want[inside] = mask[np.clip(row, 0, 29)[:, None].repeat(60, 1)[inside],
                        np.clip(col, 0, 39)[None, :].repeat(45, 0)[inside]]
    np.testing.assert_array_equal(out[1], want)
