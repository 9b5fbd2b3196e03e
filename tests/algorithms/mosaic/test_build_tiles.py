"""mosaic:build on the raster engine: cut into 64-cell tiles (blending margins crossing tile
borders), the mosaic and its source index equal the run in 512-cell tiles exactly; a COG
mosaic passes the COG layout check."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
import rasterio

import toolbox
import toolbox.mosaic.build as mosaic_build
from toolbox.raster.writer import cog_problems


def _build(pair, folder, blend, **params):
    orthos, _ = pair
    out, index = folder / f"{blend}.tif", folder / f"{blend}_index.tif"
    stats = toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos], "BLEND": blend,
                                         "OUTPUT": str(out), "SOURCE_INDEX": str(index)}
                        | params)["STATISTICS"]
    with rasterio.open(out) as ds, rasterio.open(index) as ix:
        return ds.read(), ix.read(1), stats


@pytest.mark.parametrize("blend", ["feather", "multiband"])
def test_small_tiles_equal_large_tiles(pair, tmp_path, monkeypatch, blend):
    (tmp_path / "big").mkdir()
    (tmp_path / "small").mkdir()
    big, big_index, big_stats = _build(pair, tmp_path / "big", blend)
    monkeypatch.setattr(mosaic_build, "write_mosaic",
                        partial(mosaic_build.write_mosaic, tile_size=64))
    small, small_index, small_stats = _build(pair, tmp_path / "small", blend)
    assert small_stats["tiles"] > 4 * big_stats["tiles"]
    np.testing.assert_array_equal(small, big)
    np.testing.assert_array_equal(small_index, big_index)
    assert set(np.unique(big_index)) == {0, 1, 2}
    assert small_stats["cells_per_source"] == big_stats["cells_per_source"]


def test_cog_mosaic(pair, tmp_path):
    (tmp_path / "plain").mkdir()
    (tmp_path / "cog").mkdir()
    plain, _, _ = _build(pair, tmp_path / "plain", "none")
    cog, _, _ = _build(pair, tmp_path / "cog", "none", COG=True)
    np.testing.assert_array_equal(cog, plain)
    assert cog_problems(tmp_path / "cog" / "none.tif") == []
