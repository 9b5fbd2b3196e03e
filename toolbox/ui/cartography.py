"""Parameters shared by the map-sheet algorithms (carto:grid, carto:sheet) and their request."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from toolbox.errors import ParameterError
from toolbox.parameters import ExtentParameter, Field, Number, Parameter, VectorLayer


def sheet_parameters(extent_help: str, sheets_help: str) -> list[Parameter]:
    """EXTENT, or SHEETS polygons with their SHEET_ID field; the map SCALE."""
    return [
        ExtentParameter("EXTENT", extent_help, optional=True),
        VectorLayer("SHEETS", sheets_help, geometry_types=["polygon"], optional=True),
        Field("SHEET_ID", "sheet id field of SHEETS (default: feature number)", parent="SHEETS",
              optional=True),
        Number("SCALE", "map scale denominator (5000 for 1:5000)", default=5000.0, min_value=1),
    ]


def sheet_source(params: Mapping[str, Any]):
    """The :class:`toolbox.cartography.grid_io.SheetSource` of EXTENT or SHEETS (exactly one)."""
    from toolbox.cartography.grid_io import SheetSource

    if (params.get("EXTENT") is None) == (params.get("SHEETS") is None):
        raise ParameterError("EXTENT", "or SHEETS: give exactly one of them")
    return SheetSource(extent=params.get("EXTENT"), sheets=params.get("SHEETS"),
                       sheet_id=params.get("SHEET_ID"), crs=params.get("CRS"))
