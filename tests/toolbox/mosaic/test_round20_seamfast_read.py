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
