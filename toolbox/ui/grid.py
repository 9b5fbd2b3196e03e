"""CELL_SIZE / EXTENT / TEMPLATE / MAX_CELLS -> :class:`~toolbox.raster.grid_request.GridRequest`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from toolbox.raster.grid_request import GridRequest


def grid_request(params: Mapping[str, Any]) -> GridRequest:
    """The output grid asked by validated parameters (missing ones: not given)."""
    return GridRequest(cell_size=params.get("CELL_SIZE"), extent=params.get("EXTENT"),
                       template=params.get("TEMPLATE"), max_cells=params.get("MAX_CELLS"))
