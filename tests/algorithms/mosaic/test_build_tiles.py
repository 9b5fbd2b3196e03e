"""mosaic:build on the raster engine: cut into 64-cell tiles (blending margins crossing tile
borders), the mosaic and its source index equal the run in 512-cell tiles exactly; a COG
mosaic passes the COG layout check."""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path

import numpy as np
import pyogrio
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


def _open_files() -> set[str]:
    """The files this process holds open (Linux /proc)."""
    out = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            out.add(os.path.realpath(os.readlink(f"/proc/self/fd/{fd}")))
        except OSError:
            continue
    return out


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="Linux /proc")
def test_rasters_kept_open_during_the_run_give_the_same_mosaic_and_are_closed(
        pair, tmp_path, monkeypatch):
    """open_block keeps each ortho open for the run (GDAL's block cache serves the tiles' halo
    reads): the same mosaic, index and seams as with every read opening its file, and no
    input left open when the runs return."""
    import toolbox.mosaic.block as block

    orthos, _ = pair
    inputs = {str(Path(o.path).resolve()) for o in orthos}
    (tmp_path / "kept").mkdir()
    (tmp_path / "each").mkdir()
    kept = _build(pair, tmp_path / "kept", "feather")
    toolbox.run("mosaic:seamlines", {"INPUT": [str(o.path) for o in orthos],
                                     "OUTPUT": str(tmp_path / "kept" / "seams.gpkg")})
    assert not inputs & _open_files()
    real = block.open_source
    unused = []  # the block's settings (GDAL's cache, threads) are restored by closing these

    def each_read_opens(path, k, datasets=None):
        unused.append(datasets)
        return real(path, k)

    monkeypatch.setattr(block, "open_source", each_read_opens)
    try:
        each = _build(pair, tmp_path / "each", "feather")
        toolbox.run("mosaic:seamlines", {"INPUT": [str(o.path) for o in orthos],
                                         "OUTPUT": str(tmp_path / "each" / "seams.gpkg")})
    finally:
        for datasets in reversed({id(d): d for d in unused if d is not None}.values()):
            datasets.close()  # the last opened first: rasterio's settings nest
    assert not rasterio.env.hasenv() or "GDAL_CACHEMAX" not in rasterio.env.getenv()
    np.testing.assert_array_equal(kept[0], each[0])
    np.testing.assert_array_equal(kept[1], each[1])
    for layer in ("cut_polygons", "seamlines"):
        a = pyogrio.read_dataframe(tmp_path / "kept" / "seams.gpkg", layer=layer)
        b = pyogrio.read_dataframe(tmp_path / "each" / "seams.gpkg", layer=layer)
        assert a.geometry.to_wkb().tolist() == b.geometry.to_wkb().tolist()


def test_open_files_sees_an_open_raster(pair):
    """The check above can fail: a raster held open is listed."""
    orthos, _ = pair
    with rasterio.open(orthos[0].path):
        assert str(Path(orthos[0].path).resolve()) in _open_files()
