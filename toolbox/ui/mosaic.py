"""Parameters shared by the mosaic algorithms (mosaic:seamlines, mosaic:build)."""

from __future__ import annotations

from toolbox.parameters import MultipleLayers


def orthos_parameter() -> MultipleLayers:
    """INPUT: the orthophotos of the block, at least one."""
    return MultipleLayers("INPUT", "the orthophoto GeoTIFFs (north-up, one CRS), or their "
                          "folder (e.g. ortho:batch's FOLDER)",
                          layer_type="raster", min_count=1)
