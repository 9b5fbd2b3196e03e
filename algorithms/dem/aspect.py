"""dem:aspect - direction a DEM's slope faces, degrees clockwise from north (as gdaldem)."""

from __future__ import annotations

from toolbox.parameters.outputs import Output
from toolbox.registry import register
from toolbox.ui.shading import ShadingAlgorithm, shading_parameters


@register
class Aspect(ShadingAlgorithm):
    """Aspect of every DEM cell, as ``gdaldem aspect`` (Horn 1981).

    The downhill direction of Horn's gradient ``(-dz/dx, -dz/dy)``, in degrees clockwise from
    north in [0, 360): 0 faces north, 90 east. Flat cells (zero gradient) have no aspect and are
    written as nodata -9999, as gdaldem does without ``-zero_for_flat``. Float32 GeoTIFF. Edges
    are extrapolated linearly, cells next to nodata are nodata; tiled with a one-cell halo.
    """

    id = "dem:aspect"
    display_name = "Aspect"
    short_help = "Aspect of a DEM, degrees clockwise from north (Horn's 3x3 method)."
    parameters = shading_parameters("DEM (band 1)", "aspect GeoTIFF", [])
    outputs = [Output("STATISTICS", "cell counts", "dict")]

    empty_output_hint = ("flat cells have no aspect, nor cells next to nodata: the DEM is flat "
                         "or no cell has its 8 neighbours valid")
    kernel_name = "aspect"

    def band_meaning(self, params):
        return "aspect (degrees clockwise from north)", "degree"
