"""A rectified photo is a COG by default (issue 30); COG=false gives a plain tiled GeoTIFF."""

from __future__ import annotations

import rasterio
import rectify_scene as scene

import toolbox
from toolbox.raster.writer import cog_problems


def test_rectified_photo_is_a_cog_by_default(tmp_path):
    photo = scene.write_photo(tmp_path / "photo.tif", scene.photo(1, "float32"))
    ids, image, ground, roles = scene.gcp_table(12)
    gcps = scene.write_gcp_csv(tmp_path / "gcps.csv", ids, image, ground, roles)
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "ROBUST": "none",
                                     "OUTPUT": tmp_path / "t.json"})
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "t.json",
                                        "CELL_SIZE": 0.5, "OUTPUT": tmp_path / "r.tif"})
    assert cog_problems(out["OUTPUT"]) == []
    plain = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "t.json",
                                          "CELL_SIZE": 0.5, "COG": False,
                                          "OUTPUT": tmp_path / "plain.tif"})
    with rasterio.open(plain["OUTPUT"]) as src:
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") != "COG"
