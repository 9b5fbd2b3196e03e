"""Parameters shared by the mosaic algorithms (mosaic:seamlines, mosaic:build)."""

from __future__ import annotations

from toolbox.parameters import MultipleLayers

#: the fields of a seamlines layer (mosaic:seamlines' and mosaic:build's SEAMLINES), as
#: :func:`toolbox.mosaic.block.seams_table` writes them
SEAM_FIELDS = (("a_id", "integer", "1-based input number of the first ortho (the lower)"),
               ("b_id", "integer", "1-based input number of the second ortho"),
               ("a", "string", "file name of the first ortho"),
               ("b", "string", "file name of the second ortho"),
               ("method", "string", "how the seam was made: least_cost, voronoi or cut polygons"),
               ("length", "real", "length, CRS units"))


def orthos_parameter() -> MultipleLayers:
    """INPUT: the orthophotos of the block, at least one."""
    return MultipleLayers("INPUT", "the orthophoto GeoTIFFs (north-up, one CRS), or their "
                          "folder (e.g. ortho:batch's FOLDER)",
                          layer_type="raster", min_count=1)
