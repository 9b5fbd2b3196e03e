"""Raster inputs GDAL opens as subdatasets: refused with the command that extracts one."""

from __future__ import annotations

import numpy as np


def test_a_geopackage_of_several_rasters_is_refused_with_the_command_that_extracts_one(
        tmp_path):
    """A GeoPackage holding two raster tables, given as a path, was refused as 'has no
    georeferencing' (GDAL opens it as a list of subdatasets); a subdataset name
    'GPKG:file:table' as 'file ... does not exist'. Both now say what they are and give the
    gdal_translate command that extracts one (which GDAL's own tool reads)."""
    import rasterio
    from affine import Affine

    from tests.helpers_cli import cli, one_error

    path = tmp_path / "two.gpkg"
    for k, table in enumerate(("dem1", "dem2")):
        options = {"RASTER_TABLE": table} | ({"APPEND_SUBDATASET": "YES"} if k else {})
        with rasterio.open(path, "w", driver="GPKG", width=8, height=8, count=1,
                           dtype="float32", crs="EPSG:3003",
                           transform=Affine(1, 0, 1688000, 0, -1, 4799500), **options) as dst:
            dst.write(np.full((1, 8, 8), 100.0 + k, "float32"))
    code, _, err = cli("run", "dem:slope", "--INPUT", path, "--OUTPUT", tmp_path / "s.tif")
    line = one_error(err)
    assert code == 2 and "holds 2 rasters" in line and "gdal_translate 'GPKG:" in line, line
    sub = f"GPKG:{path}:dem2"
    code, _, err = cli("run", "dem:slope", "--INPUT", sub, "--OUTPUT", tmp_path / "s.tif")
    line = one_error(err)
    assert code == 2 and "subdataset name" in line and f"gdal_translate '{sub}'" in line, line
    assert not (tmp_path / "s.tif").exists()
