"""The DEM terrain algorithms (dem:slope, dem:aspect, dem:hillshade): their shared parameters
and run. Each sets ``kernel_options`` (its own parameters -> kernel keywords), the kernel and
its output type; everything else is here once."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Integer, Parameter, RasterLayer
from toolbox.parameters.outputs import OutputRaster
from toolbox.ui.execution import executor_of, scheduler_parameter


def shading_parameters(input_help: str, output_help: str, own: list[Parameter]) -> list:
    """INPUT, BAND, the algorithm's ``own`` parameters, TILE_SIZE, SCHEDULER, OVERVIEWS, COG,
    OUTPUT."""
    return [
        RasterLayer("INPUT", input_help, role="heights"),
        Integer("BAND", "band of the DEM", default=1, min_value=1),
        *own,
        Integer("TILE_SIZE", "tile side in cells", default=512, min_value=16),
        scheduler_parameter(),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Boolean("COG", "write a Cloud Optimized GeoTIFF", default=False),
        OutputRaster("OUTPUT", output_help),
    ]


class ShadingAlgorithm(Algorithm):
    """Base of dem:slope/aspect/hillshade: a 3x3 kernel of :mod:`toolbox.terrain.shading` over
    the DEM in tiles with a one-cell halo (BAND within the DEM's bands: the runner checks it)."""

    length_units = "one"  # x, y and heights in one unit (metres or feet): slopes mix them
    empty_output_hint = "cells next to nodata are nodata: no cell of the DEM has its 8 " \
                        "neighbours valid"

    group = "DEM terrain"
    kernel_name: ClassVar[str] = ""  # a function of toolbox.terrain.shading
    dtype: ClassVar[str] = "float32"
    nodata: ClassVar[float] = -9999.0

    def kernel_options(self, params: dict[str, Any]) -> dict[str, Any]:
        return {}

    def band_meaning(self, params: dict[str, Any]) -> tuple[str | None, str | None]:
        """``(description, unit)`` of the output band (GDAL's description and unit type)."""
        return None, None

    def check(self, params: dict[str, Any]) -> None:
        from toolbox.terrain.shading import check_georeferenced

        check_georeferenced(params["INPUT"])

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from functools import partial

        from toolbox.terrain import shading

        kernel: Callable = partial(getattr(shading, self.kernel_name),
                                   **self.kernel_options(params))
        stats = shading.shade_raster(params["INPUT"], params["BAND"], params["OUTPUT"], kernel,
                                     self.dtype, self.nodata, feedback, params["TILE_SIZE"],
                                     params["OVERVIEWS"], params["COG"],
                                     executor=executor_of(params, workers=1),
                                     **dict(zip(("description", "unit"),
                                                self.band_meaning(params), strict=True)))
        declared = {output.name for output in self.outputs}
        return {"OUTPUT": params["OUTPUT"]} | ({"STATISTICS": stats} if "STATISTICS" in declared
                                               else {})
