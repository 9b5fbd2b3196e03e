"""The algorithm class of every ``dem:<method>`` (light: kernels are imported by process())."""

from __future__ import annotations

from typing import Any, ClassVar

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.terrain.gridding.inputs import check_sources
from toolbox.terrain.gridding.parameters import DEFAULT_TILE


class GriddingAlgorithm(Algorithm):
    """Base of ``dem:<method>``: subclasses set ``method`` (a name in
    :data:`toolbox.terrain.gridding.methods.METHODS`) and the method's parameters."""

    group = "DEM gridding"
    method: ClassVar[str] = ""

    def check(self, params: dict[str, Any]) -> None:
        from toolbox.raster.engine import check_grid_parameters

        check_sources(self, params)
        self.check_method(params)
        check_grid_parameters(params)
        guard_grid_size(params)
        if params.get("TILE_SIZE", DEFAULT_TILE) % 16:
            raise self.fail("TILE_SIZE", f"must be a multiple of 16 (GeoTIFF blocks), got "
                            f"{params['TILE_SIZE']}")

    def check_method(self, params: dict[str, Any]) -> None:
        k, min_k = params.get("NEIGHBOURS"), params.get("MIN_NEIGHBOURS")
        if k is not None and min_k is not None and min_k > k:
            raise self.fail("MIN_NEIGHBOURS", f"must be <= NEIGHBOURS ({k}), got {min_k}")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.terrain.gridding.methods import METHODS
        from toolbox.terrain.gridding.run import grid_dem

        return grid_dem(METHODS[self.method], params, feedback)


def guard_grid_size(params: dict[str, Any]) -> None:
    """The grid's size guard (MAX_CELLS / TOOLBOX_MAX_CELLS) from the inputs' declared bounds,
    before any point is read (also in ``toolbox batch --validate``); the run checks it again on
    the data's exact bounds."""
    import numpy as np

    from toolbox.io.crs import input_crs_and_bounds
    from toolbox.raster.engine import grid_from_parameters

    pairs = [pair for name in ("INPUT", "LINES", "BREAKLINES")
             for pair in input_crs_and_bounds(params.get(name))]
    if not pairs or any(b is None for _, b in pairs):
        return
    b = np.array([bounds for _, bounds in pairs], dtype=float)
    bounds = (b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max())
    grid_from_parameters(params, bounds, pairs[0][0])
