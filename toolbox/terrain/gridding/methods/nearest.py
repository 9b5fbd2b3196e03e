"""Nearest neighbour: the height of the data point nearest to the cell centre (thesis par. 2.5.2,
method 1); an IDW on one neighbour."""

from __future__ import annotations

from typing import Any

from toolbox.terrain.gridding.methods.base import Method, NeighbourMethod
from toolbox.terrain.gridding.methods.idw import IdwMethod, idw_tile
from toolbox.terrain.gridding.request import MethodOptions


class NearestMethod(NeighbourMethod):
    name = "nearest"
    min_points = 1
    default_neighbours = 1
    min_neighbours = 1
    tile_kernel = staticmethod(idw_tile)

    def options(self, request: MethodOptions) -> dict[str, Any]:
        return Method.options(self, request) | {"neighbours": 1}

    def loo_chunk(self, bins, z, targets, options):
        return IdwMethod.loo_chunk(self, bins, z, targets, options)
