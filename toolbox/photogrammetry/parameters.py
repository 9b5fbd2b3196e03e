"""Parameters shared by the orientation algorithms (light: declarations only)."""

from __future__ import annotations

from toolbox.parameters import Enum, File, Parameter, String

TABLE_EXTENSIONS = [".csv", ".txt", ".gpkg"]


def measurement_parameters(project: str = "orientation project (YAML)") -> list[Parameter]:
    """PROJECT, and the image measurements: INPUT, its LAYER and its COORDINATES columns."""
    return [
        File("PROJECT", project, extensions=[".yaml", ".yml"]),
        File("INPUT", "image measurements (CSV or GeoPackage table)", extensions=TABLE_EXTENSIONS),
        String("LAYER", "GeoPackage layer of INPUT (default: the first)", optional=True),
        Enum("COORDINATES", "measurement columns: auto (pixels when col_px/row_px exist), pixel, "
             "image (x_mm/y_mm)", options=("auto", "pixel", "image"), default="auto"),
    ]


def control_parameter() -> File:
    """CONTROL: surveyed points with id, X, Y, Z and an optional role."""
    return File("CONTROL", "surveyed points: id, X, Y, Z, optional role (control/check)",
                extensions=TABLE_EXTENSIONS)
