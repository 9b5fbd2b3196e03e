"""Deliverables as COGs by default (issue 30): the mosaic and its source index pass the COG layout
check without asking; COG=false gives a plain tiled GeoTIFF."""

from __future__ import annotations

import mosaic_scene
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
