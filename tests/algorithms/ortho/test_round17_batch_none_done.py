"""ortho:batch whose every photo fails in its ortho (not in its plan): an error, nothing kept."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.errors import InputDataError

sys.path.insert(0, str(Path(__file__).parent))
import ortho_scene as scene  # noqa: E402


def test_a_batch_of_which_every_photo_fails_is_an_error_and_writes_nothing(tmp_path):
    """A DEM_FACTOR the DEM cannot take fails each photo's ortho: exit 0 with an empty
    listing before; now the run's error names the photo and the cause, and neither FOLDER
    nor OUTPUT is left."""
    sc = scene.make_scene(tmp_path)
    with rasterio.open(sc.dem_path) as src:  # the scene's DEM at 12 x 12 cells
        step = max(src.width, src.height) // 12
        coarse = src.read(1)[::step, ::step][:12, :12]
        profile = src.profile | {"width": 12, "height": 12, "blockxsize": 16, "blockysize": 16,
                                 "transform": src.transform * Affine.scale(step)}
    with rasterio.open(tmp_path / "coarse.tif", "w", **profile) as dst:
        dst.write(coarse, 1)
    with pytest.raises(InputDataError, match=r"no photo could be orthorectified: .*DEM_FACTOR"):
        toolbox.run("ortho:batch", {"PROJECT": sc.project_path, "DEM": tmp_path / "coarse.tif",
                                    "DEM_FACTOR": 12, "FOLDER": str(tmp_path / "orthos"),
                                    "OUTPUT": tmp_path / "block.json"})
    assert not (tmp_path / "orthos").exists() and not (tmp_path / "block.json").exists()
