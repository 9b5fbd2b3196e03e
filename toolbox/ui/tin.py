"""Parameters shared by the algorithms that read a TIN (tin:* and carto:profile)."""

from __future__ import annotations

from toolbox.parameters import VectorLayer
from toolbox.terrain.tin.help import TIN_HELP


def tin_parameter(description: str = TIN_HELP, optional: bool = False) -> VectorLayer:
    """TIN: the triangles (polygons with Z) of a tin:delaunay output."""
    return VectorLayer("TIN", description, geometry_types=["polygon"], optional=optional)
