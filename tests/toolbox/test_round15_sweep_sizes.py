"""Round 15, sizes and extents at the edges: one-cell-wide DEMs, the outer half cell of a DEM,
empty outputs of algorithms without EXTENT/MASK, a one-row DSM, empty sheet layers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.raster.writer import write_raster

X0, Y0, CRS = 500_000.0, 4_500_000.0, "EPSG:32632"


def dem(path, z, cell=10.0, nodata=-9999.0):
    z = np.asarray(z, "float32")
    write_raster(path, z, Affine(cell, 0, X0, 0, -cell, Y0), CRS, nodata=nodata)
    return path


def band(path):
    with rasterio.open(path) as ds:
        return ds.read(1)


@pytest.mark.parametrize("shape", [(1, 5), (5, 1)])
def test_slope_of_a_one_cell_wide_plane_is_exact_to_its_ends(tmp_path, shape):
    """A 1 x N (or N x 1) DEM of a plane rising 1 m per 10 m cell: every cell's slope is
    atan(0.1) = 5.71 deg (analytic). The edge extrapolation repeated the edge along both axes
    as soon as one was one cell wide, so the two end cells had half the gradient (2.86 deg),
    and their hillshade and the aspect's magnitude with it."""
    z = (100.0 + np.arange(5.0)).reshape(shape)
    path = dem(tmp_path / "row.tif", z)
    toolbox.run("dem:slope", {"INPUT": path, "OUTPUT": tmp_path / "s.tif"})
    np.testing.assert_allclose(band(tmp_path / "s.tif"), math.degrees(math.atan(0.1)),
                               rtol=1e-6)
    toolbox.run("dem:hillshade", {"INPUT": path, "OUTPUT": tmp_path / "h.tif"})
    assert np.unique(band(tmp_path / "h.tif")).size == 1  # a plane: one grey everywhere
