"""Round 17, raster metadata: rectify:image with OUTSIDE=nodata on a photo without nodata
guesses the nodata value (0 for Byte): the photo's own 0 samples then read as no data in the
output in silence; now a warning counts them and names NODATA."""

from __future__ import annotations

import numpy as np
import rasterio
import rectify_scene as scene

import toolbox
from toolbox.feedback import Feedback


def test_guessed_nodata_held_by_the_photo_is_warned(tmp_path):
    photo = np.clip(scene.photo(1, "float32"), 1, 255).astype("uint8")
    photo[0, 100:110, 100:110] = 0  # black pixels: valid data
    path = scene.write_photo(tmp_path / "photo.tif", photo)
    with rasterio.open(path) as src:
        assert src.nodata is None and int((src.read(1) == 0).sum()) == 100
    ids, image, ground, roles = scene.gcp_table(12)
    gcps = scene.write_gcp_csv(tmp_path / "gcps.csv", ids, image, ground, roles)
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "ROBUST": "none",
                                     "OUTPUT": tmp_path / "t.json"})
    feedback = Feedback()
    toolbox.run("rectify:image", {"INPUT": path, "TRANSFORM": tmp_path / "t.json",
                                  "CELL_SIZE": 0.5, "OUTSIDE": "nodata", "COG": False,
                                  "OVERVIEWS": False, "OUTPUT": tmp_path / "r.tif"}, feedback)
    assert any(w.startswith("INPUT: 100 photo sample(s) hold 0") and "NODATA" in w
               for w in feedback.warnings)
    chosen = Feedback()  # NODATA given: the user's choice, no warning
    toolbox.run("rectify:image", {"INPUT": path, "TRANSFORM": tmp_path / "t.json",
                                  "CELL_SIZE": 0.5, "OUTSIDE": "nodata", "NODATA": 0,
                                  "COG": False, "OVERVIEWS": False,
                                  "OUTPUT": tmp_path / "n.tif"}, chosen)
    assert not any("photo sample(s)" in w for w in chosen.warnings)
