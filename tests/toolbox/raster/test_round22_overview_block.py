"""Overview blocks of a tiled GeoTIFF (toolbox.raster.writer.overview_block): GDAL takes
GDAL_TIFF_OVR_BLOCKSIZE as a power of two from 64 to 4096 only; TILE_SIZE 16 or 48 (allowed:
multiples of 16) printed "Wrong value for GDAL_TIFF_OVR_BLOCKSIZE" on every run. Read back with
tifffile (the overview IFDs' tile sizes)."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely
import tifffile

from tests.helpers_cli import cli

X0, Y0 = 1_688_000.0, 4_799_500.0


@pytest.mark.parametrize(("tile", "overview_tile"), [(16, 64), (48, 64), (256, 256)])
def test_overview_blocks_are_a_size_gdal_takes(tmp_path, tile, overview_tile):
    rng = np.random.default_rng(8)
    xy = rng.uniform(0, 600, (400, 2)) + [X0, Y0]
    z = 250 + 0.01 * (xy[:, 0] - X0)
    src = tmp_path / "p.gpkg"
    gpd.GeoDataFrame(geometry=shapely.points(np.c_[xy, z]), crs="EPSG:3003").to_file(src)
    out = tmp_path / "dem.tif"
    code, _, err = cli("run", "dem:nearest", "--INPUT", src, "--OUTPUT", out, "--CELL_SIZE", 1,
                       "--TILE_SIZE", tile)
    assert code == 0, err
    assert "GDAL_TIFF_OVR_BLOCKSIZE" not in err
    with tifffile.TiffFile(out) as tif:
        pages = [p for p in tif.pages if not p.is_mask]
        assert pages[0].tilewidth == tile
        assert len(pages) > 1  # overviews were built
        assert {p.tilewidth for p in pages[1:]} == {overview_tile}
