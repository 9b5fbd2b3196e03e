"""mosaic:build and mosaic:seamlines name an ortho in another CRS by its 1-based input number
(``INPUT[2] (b)``), as carto:sheet names ``LAYERS[1]``: they said ``INPUT[1]`` for the second
ortho and ``INPUT[0]`` for the first (counted from 0)."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

from tests.helpers_cli import cli, one_error


def ortho(path, crs, x0, y0):
    r, c = np.indices((40, 50))
    with rasterio.open(path, "w", driver="GTiff", width=50, height=40, count=1, dtype="uint8",
                       crs=crs, transform=Affine(1, 0, x0, 0, -1, y0), nodata=0) as dst:
        dst.write((40 + c + r).astype("uint8"), 1)
    return path


@pytest.mark.parametrize("algorithm, output", [("mosaic:build", "m.tif"),
                                               ("mosaic:seamlines", "s.gpkg")])
def test_the_ortho_in_another_crs_is_named_by_its_1_based_number(tmp_path, algorithm, output):
    a = ortho(tmp_path / "a.tif", "EPSG:3003", 1688000.0, 4800000.0)
    b = ortho(tmp_path / "b.tif", "EPSG:32632", 688000.0, 4800000.0)
    code, _, err = cli("run", algorithm, "--INPUT", a, "--INPUT", b,
                       "--OUTPUT", tmp_path / output)
    assert code == 2, err
    line = one_error(err)
    assert "INPUT[2] (b) is in EPSG:32632" in line and "INPUT[1] (a) is in EPSG:3003" in line, line
    assert "INPUT[0]" not in line
    assert not (tmp_path / output).exists()
