"""A raster band with a scale or an offset stores codes (value = code x scale + offset): every
algorithm reading it refused it with a one-line error naming the parameter and the
gdal_translate command that writes the values (contours of such a DEM came out at the codes:
5..10000 m for a 100..200 m terrain)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox


def dem(path, scale=None, offset=None):
    r, c = np.indices((60, 70))
    codes = (5000 + 40 * c + 30 * r).astype("int16")  # centimetres above 100 m
    with rasterio.open(path, "w", driver="GTiff", width=70, height=60, count=1, dtype="int16",
                       crs="EPSG:3003", transform=Affine(1, 0, 1688000, 0, -1, 4800000),
                       nodata=-32768) as dst:
        dst.write(codes, 1)
        if scale is not None:
            dst.scales = (scale,)
            dst.offsets = (offset,)
    return path


@pytest.mark.parametrize("algorithm, extra", [("carto:contours", {"INTERVAL": 5.0}),
                                              ("dem:slope", {})])
def test_a_scaled_raster_is_refused_naming_the_parameter(tmp_path, algorithm, extra):
    path = dem(tmp_path / "scaled.tif", 0.01, 100.0)
    out = tmp_path / ("out.gpkg" if algorithm == "carto:contours" else "out.tif")
    with pytest.raises(toolbox.ParameterError,
                       match=r"INPUT .*band 1 has scale 0\.01 and offset 100.*gdal_translate "
                             r"-unscale"):
        toolbox.run(algorithm, {"INPUT": path, "OUTPUT": out} | extra)
    assert not out.exists()


def test_the_cli_says_it_in_one_line_with_exit_2(tmp_path):
    path = dem(tmp_path / "scaled.tif", 0.5, 0.0)
    run = subprocess.run([sys.executable, "-m", "toolbox", "run", "dem:slope", "--INPUT",
                          str(path), "--OUTPUT", str(tmp_path / "s.tif")],
                         capture_output=True, text=True)
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "scale 0.5" in lines[0] and "Traceback" not in run.stderr


def test_scale_one_and_offset_zero_are_plain_values(tmp_path):
    path = dem(tmp_path / "plain_scaled.tif", 1.0, 0.0)
    toolbox.run("dem:slope", {"INPUT": path, "OUTPUT": tmp_path / "s.tif"})
    with rasterio.open(tmp_path / "s.tif") as src:
        slope = src.read(1)[1:-1, 1:-1]
    np.testing.assert_allclose(slope, np.degrees(np.arctan(np.hypot(40, 30))), atol=1e-3)
