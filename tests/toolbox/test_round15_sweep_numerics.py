"""Round 15, numerics at real-world coordinates: results must not change when the data set is
translated to projected coordinates (a UTM northing of 5,000,000, EPSG:3857 far from 0)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from toolbox.raster.grid_request import GridRequest


@pytest.mark.parametrize("x0, y0", [(0.0, 0.0), (500_000.0, 5_000_000.0),
                                    (1_688_000.0, 4_799_500.0), (20_000_000.0, 10_000_000.0)])
def test_extent_of_whole_cells_gives_the_same_grid_at_any_origin(x0, y0):
    """EXTENT 0.14 m wide, 5 mm cells: 28 x 28 cells wherever it lies (at a northing of
    5,000,000 the subtraction's last bit was 6e-9 of a cell, over the old 1e-9 slack: 29)."""
    ext = SimpleNamespace(bounds=(x0, y0, x0 + 0.14, y0 + 0.14), crs=None)
    grid = GridRequest(cell_size=0.005, extent=ext).grid(None, None)
    assert (grid.width, grid.height) == (28, 28)


@pytest.mark.parametrize("x0, y0", [(0.0, 0.0), (500_000.0, 5_000_000.0)])
def test_data_bounds_snapped_give_the_same_grid_at_any_origin(x0, y0):
    """Data over [-0.002, 0.143] snapped to 5 mm: [-0.005, 0.145], 30 cells each way."""
    grid = GridRequest(cell_size=0.005).grid((x0 - 0.002, y0 - 0.002, x0 + 0.143, y0 + 0.143),
                                             None)
    assert (grid.width, grid.height) == (30, 30)


@pytest.mark.parametrize("x0, y0", [(0.0, 0.0), (500_000.0, 5_000_000.0)])
def test_extent_on_a_template_lattice_at_any_origin(x0, y0):
    """A TEMPLATE at the origin cut to an EXTENT of 28 x 28 of its 5 mm cells."""
    from affine import Affine

    template = SimpleNamespace(transform=Affine(0.005, 0, x0, 0, -0.005, y0 + 1.0),
                               width=200, height=200, crs=None)
    ext = SimpleNamespace(bounds=(x0, y0 + 0.5, x0 + 0.14, y0 + 0.64), crs=None)
    grid = GridRequest(extent=ext, template=template).grid(None, None)
    assert (grid.width, grid.height) == (28, 28)
    assert grid.transform.c == pytest.approx(x0, abs=1e-9)
