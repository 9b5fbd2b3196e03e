"""The typed grid request: one rule for CELL_SIZE with TEMPLATE (refused: the template's cells
are used), in the engine's grids and in the ortho lattice, with one message."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine
from pyproj import CRS

from toolbox.errors import ParameterError
from toolbox.io.grid import GridSpec
from toolbox.io.raster import open_raster_info
from toolbox.raster.grid_request import GridRequest, template_lattice

X0, Y0 = 1_688_000.0, 4_799_500.0


def template(tmp_path, transform, crs="EPSG:3003"):
    path = tmp_path / "t.tif"
    with rasterio.open(path, "w", driver="GTiff", width=90, height=60, count=1, dtype="float32",
                       crs=crs, transform=transform) as dst:
        dst.write(np.zeros((1, 60, 90), "float32"))
    return open_raster_info(path)


def test_cell_size_with_a_template_is_refused_alike_by_grid_and_lattice(tmp_path):
    t = Affine(2.5, 0, X0 + 13.3, 0, -2.5, Y0 + 181.7)
    info = template(tmp_path, t)
    assert GridRequest(template=info).grid(None, None) == GridSpec(t, 90, 60, info.crs)
    assert template_lattice(info) == (2.5, (X0 + 13.3, Y0 + 181.7))
    message = "CELL_SIZE must not be given with TEMPLATE"
    for cell in (2.5, 2.0):  # even the template's own cell: one rule, no tolerance to argue
        with pytest.raises(ParameterError, match=message):
            GridRequest(cell_size=cell, template=info).grid(None, None)
        with pytest.raises(ParameterError, match=message):
            GridRequest(cell_size=cell, template=info).check()
        with pytest.raises(ParameterError, match=message):
            template_lattice(info, cell)


def test_a_template_in_another_crs_or_rotated_is_refused(tmp_path):
    info = template(tmp_path, Affine(2.5, 0, X0, 0, -2.5, Y0))
    with pytest.raises(ParameterError, match="TEMPLATE is in EPSG:3003, the ortho in EPSG:6707"):
        template_lattice(info, None, CRS.from_epsg(6707), "the ortho")
    rotated = template(tmp_path, Affine(2.5, 0.1, X0, 0.1, -2.5, Y0))
    with pytest.raises(ParameterError, match="TEMPLATE must be a raster without rotation"):
        template_lattice(rotated)
    rect = template(tmp_path, Affine(2.5, 0, X0, 0, -2.0, Y0))
    with pytest.raises(ParameterError, match="square cells"):
        template_lattice(rect)


def test_no_cell_no_template_no_default_names_cell_size():
    with pytest.raises(ParameterError, match="CELL_SIZE is required"):
        GridRequest().check()
    # the data's bounds snapped outwards to whole cells (independent arithmetic)
    grid = GridRequest(cell_size=4.0).grid((X0 + 3, Y0 + 7, X0 + 96, Y0 + 61), None)
    assert grid.bounds == (X0, Y0 + 4, X0 + 96, Y0 + 64) and (grid.width, grid.height) == (24, 15)


def test_an_extent_in_another_crs_is_its_bounding_box_in_the_grids_crs(tmp_path):
    """EXTENT "... [EPSG:32632]" for data in EPSG:3003: the grid covers the extent's bounding
    box in EPSG:3003 (pyproj's densified transform_bounds, as QGIS and gdalwarp -te_srs convert
    it); dem:* refused it with "reproject the inputs to one CRS first" (the inputs were in one
    CRS). The CLI runs and says what it took."""
    import geopandas as gpd
    import shapely
    from pyproj import Transformer

    from tests.helpers_cli import cli
    from toolbox.parameters.values import Extent

    utm = Transformer.from_crs("EPSG:3003", "EPSG:32632", always_xy=True).transform_bounds(
        X0, Y0, X0 + 200, Y0 + 150)
    truth = Transformer.from_crs("EPSG:32632", "EPSG:3003", always_xy=True).transform_bounds(
        *utm, densify_pts=21)
    grid = GridRequest(cell_size=1.0, extent=Extent(*utm, CRS.from_epsg(32632))).grid(
        None, CRS.from_epsg(3003))
    t = grid.transform
    assert (t.c, t.f) == pytest.approx((truth[0], truth[3]), abs=1e-6)
    assert (grid.width, grid.height) == (int(np.ceil(truth[2] - truth[0])),
                                         int(np.ceil(truth[3] - truth[1])))
    rng = np.random.default_rng(3)
    points = gpd.GeoDataFrame(geometry=shapely.points(
        X0 - 50 + 300 * rng.random(200), Y0 - 50 + 250 * rng.random(200), rng.random(200)),
        crs="EPSG:3003")
    points.to_file(tmp_path / "p.gpkg")
    extent = ",".join(f"{v:.3f}" for v in utm) + " [EPSG:32632]"
    code, _, err = cli("run", "dem:nearest", "--INPUT", tmp_path / "p.gpkg", "--CELL_SIZE", "1",
                       "--EXTENT", extent, "--OUTPUT", tmp_path / "d.tif")
    assert code == 0, err
    assert "EXTENT is in EPSG:32632: taken as its bounding box in EPSG:3003" in err
    with rasterio.open(tmp_path / "d.tif") as src:
        assert src.crs.to_epsg() == 3003
        assert (src.transform.c, src.transform.f) == pytest.approx((truth[0], truth[3]),
                                                                   abs=1e-3)
