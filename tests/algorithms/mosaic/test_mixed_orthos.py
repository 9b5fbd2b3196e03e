"""Orthos of different data types or band counts are refused by mosaic:build and
mosaic:seamlines with one line naming both (a Byte and a UInt16 ortho were mosaicked raw into
one UInt16 raster, the 8-bit half black, exit 0; the seam cost compares their values)."""

from __future__ import annotations

import re

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox

X0, Y0 = 1688000.0, 4800000.0


def ortho(path, x0, dtype="uint8", bands=3):
    r, c = np.indices((100, 120))
    value = (40 + c + r) * (257 if dtype == "uint16" else 1)
    with rasterio.open(path, "w", driver="GTiff", width=120, height=100, count=bands,
                       dtype=dtype, crs="EPSG:3003", transform=Affine(1, 0, x0, 0, -1, Y0),
                       nodata=0) as dst:
        for b in range(1, bands + 1):
            dst.write(value.astype(dtype), b)
    return path


@pytest.mark.parametrize("algorithm, output", [("mosaic:build", "m.tif"),
                                               ("mosaic:seamlines", "s.gpkg")])
def test_orthos_of_two_data_types_are_refused(tmp_path, algorithm, output):
    a = ortho(tmp_path / "a.tif", X0)
    b = ortho(tmp_path / "b.tif", X0 + 80, "uint16")
    with rasterio.open(a) as one, rasterio.open(b) as other:  # GDAL's reading: Byte, UInt16
        assert one.dtypes[0] == "uint8" and other.dtypes[0] == "uint16"
    with pytest.raises(toolbox.ParameterError,
                       match=f"^INPUT '{re.escape(str(a))}' is Byte but '{re.escape(str(b))}' "
                             "is UInt16: the orthos must share a data type; convert one with "
                             "gdal_translate -ot Byte -scale"):
        toolbox.run(algorithm, {"INPUT": [a, b], "OUTPUT": tmp_path / output})
    assert not (tmp_path / output).exists()


@pytest.mark.parametrize("algorithm, output", [("mosaic:build", "m.tif"),
                                               ("mosaic:seamlines", "s.gpkg")])
def test_orthos_of_two_band_counts_are_refused(tmp_path, algorithm, output):
    a = ortho(tmp_path / "a.tif", X0)
    b = ortho(tmp_path / "b.tif", X0 + 80, bands=1)
    with pytest.raises(toolbox.ParameterError,
                       match=f"^INPUT '{re.escape(str(a))}' has 3 bands but "
                             f"'{re.escape(str(b))}' has 1: mosaic orthos of one kind"):
        toolbox.run(algorithm, {"INPUT": [a, b], "OUTPUT": tmp_path / output})
    assert not (tmp_path / output).exists()


def test_orthos_of_one_kind_are_mosaicked(tmp_path):
    a = ortho(tmp_path / "a.tif", X0, "uint16")
    b = ortho(tmp_path / "b.tif", X0 + 80, "uint16")
    toolbox.run("mosaic:build", {"INPUT": [a, b], "OUTPUT": tmp_path / "m.tif"})
    with rasterio.open(tmp_path / "m.tif") as src:
        assert src.dtypes[0] == "uint16" and src.count >= 3
