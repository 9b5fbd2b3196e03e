"""Nearest neighbour: the height of the data point nearest to the cell centre (thesis par. 2.5.2,
method 1); an IDW on one neighbour."""

from __future__ import annotations

from typing import Any

from toolbox.terrain.gridding.methods.base import Method
from toolbox.terrain.gridding.methods.idw import IdwMethod
from toolbox.terrain.gridding.request import MethodOptions


class NearestMethod(IdwMethod):
    """IDW's kernel and leave-one-out on k = 1 (no power, no sectors)."""

    name = "nearest"
    default_neighbours = 1

    def options(self, request: MethodOptions) -> dict[str, Any]:
        return Method.options(self, request) | {"neighbours": 1}
