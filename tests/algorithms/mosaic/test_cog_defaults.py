"""Deliverables as COGs by default (issue 30): the mosaic and its source index pass the COG layout
check without asking; COG=false gives a plain tiled GeoTIFF."""

from __future__ import annotations

import sys

import mosaic_scene
import pytest
import rasterio

import toolbox
from toolbox.raster.writer import cog_problems


def test_mosaic_and_source_index_are_cogs_by_default(tmp_path_factory, tmp_path):
    orthos, _ = mosaic_scene.standard_pair(tmp_path_factory)
    inputs = [str(o.path) for o in orthos]
    toolbox.run("mosaic:build", {"INPUT": inputs, "BLEND": "none", "OUTPUT": tmp_path / "m.tif",
                                 "SOURCE_INDEX": tmp_path / "i.tif"})
    for name in ("m.tif", "i.tif"):
        assert cog_problems(tmp_path / name) == [], name
        with rasterio.open(tmp_path / name) as src:
            assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
    toolbox.run("mosaic:build", {"INPUT": inputs, "BLEND": "none", "COG": False,
                                 "OUTPUT": tmp_path / "plain.tif"})
    with rasterio.open(tmp_path / "plain.tif") as src:
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") != "COG"
    assert not list(tmp_path.glob(".*tiled*"))  # no intermediate left


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_FSIZE fault injection")
def test_a_cog_that_cannot_be_written_is_an_output_error(tmp_path_factory, tmp_path):
    """A full disk while the COG is made (a 20 kB file-size limit): exit 2, one line naming
    OUTPUT (not an unreadable input), nothing left."""
    from tests.helpers_cli import assert_cannot_write, run_on_full_disk

    orthos, _ = mosaic_scene.standard_pair(tmp_path_factory)
    out = tmp_path / "out"
    assert_cannot_write(run_on_full_disk(["mosaic:build", "--INPUT", str(orthos[0].path),
                                          "--INPUT", str(orthos[1].path),
                                          "--OUTPUT", str(out / "m.tif")]), out)
