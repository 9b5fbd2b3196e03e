"""Parameters shared by the orientation algorithms (light: declarations only)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from toolbox.errors import InputDataError
from toolbox.parameters import Enum, File, Integer, Number, Parameter, RasterLayer, String
from toolbox.parameters.outputs import Layer, OutputFile
from toolbox.photogrammetry.tables import PROJECT_EXTENSIONS

TABLE_EXTENSIONS = [".csv", ".txt", ".gpkg"]


def table_parameters(name: str, description: str) -> list[Parameter]:
    """A table (CSV, text or GeoPackage) ``name`` and the LAYER to read of a GeoPackage."""
    return [File(name, description, extensions=TABLE_EXTENSIONS),
            String("LAYER", f"GeoPackage layer of {name} (default: the first)", optional=True)]


def project_parameter(description: str = "orientation project (YAML)",
                      optional: bool = False) -> File:
    """PROJECT: the orientation project YAML."""
    return File("PROJECT", description, extensions=PROJECT_EXTENSIONS, optional=optional)


def report_output(description: str = "JSON report", optional: bool = True) -> OutputFile:
    """REPORT: the JSON report of an orientation step."""
    return OutputFile("REPORT", description, extensions=[".json"], optional=optional)


def ground_residuals_layer(description: str) -> Layer:
    """The layer ``ground_residuals``: one line per known point, surveyed -> computed position."""
    return Layer("ground_residuals", "LineString Z", [
        ("point_id", "string"), ("role", "string"), ("dx_m", "real"), ("dy_m", "real"),
        ("dz_m", "real")], description)


def dem_parameters(description: str = "terrain heights (same CRS as the project)",
                   optional: bool = False) -> list[Parameter]:
    """DEM and its BAND."""
    return [RasterLayer("DEM", description, optional=optional, role="heights"),
            Integer("BAND", "DEM band", default=1, min_value=1)]


def measurement_parameters(project: str = "orientation project (YAML)") -> list[Parameter]:
    """PROJECT, and the image measurements: INPUT, its LAYER and its COORDINATES columns."""
    return [
        project_parameter(project),
        *table_parameters("INPUT", "image measurements (CSV or GeoPackage table)"),
        Enum("COORDINATES", "measurement columns: auto (pixels when col_px/row_px exist), pixel, "
             "image (x_mm/y_mm)", options=("auto", "pixel", "image"), default="auto"),
    ]


def control_parameter() -> File:
    """CONTROL: surveyed points with id, X, Y, Z and an optional role."""
    return File("CONTROL", "surveyed points: id, X, Y, Z, optional role (control/check)",
                extensions=TABLE_EXTENSIONS)


ORTHO_RESAMPLING = ("nearest", "bilinear", "quadratic", "cubic", "lanczos")


def ortho_method_parameters() -> list[Parameter]:
    """How an orthophoto is computed and what its cells outside the photo hold (ortho:photo and
    ortho:batch): RESAMPLING, DEM_FACTOR, MAP_BLOCK, MAP_TOLERANCE, OUTSIDE, NODATA.
    (MAP_BLOCK, not TILE_SIZE: a distortion block, not the dem:* tiles of 512 cells.)"""
    return [
        Enum("RESAMPLING", "photo interpolation", options=ORTHO_RESAMPLING, default="bilinear"),
        Integer("DEM_FACTOR", "project on a DEM coarsened by this factor (1 = as is)", default=1,
                min_value=1, max_value=64),
        Integer("MAP_BLOCK", "block of the distortion map, cells: the correction is exact at "
                "its corners and blended inside where within MAP_TOLERANCE", default=64,
                min_value=2, max_value=256,
                advanced=True, deprecated_names=("TILE_SIZE",)),
        Number("MAP_TOLERANCE", "largest interpolation error of the map, photo pixels",
               default=0.05, min_value=0),
        Enum("OUTSIDE", "cells outside the photo or the DEM: alpha band (Byte and "
             "UInt16 photos; others get nodata) or nodata",
             options=("alpha", "nodata"), default="alpha"),
        Number("NODATA", "nodata value with OUTSIDE=nodata", optional=True),
    ]


def rpc_gcp_parameters() -> list[Parameter]:
    """CONTROL, MEASUREMENTS and BIAS: the GCP bias refinement of RPC images (ortho:photo,
    ortho:batch)."""
    return [
        File("CONTROL", "RPC images: ground control points (id, X, Y, Z in CRS, heights in "
             "the RPCs' datum) for the bias refinement", extensions=TABLE_EXTENSIONS,
             optional=True),
        File("MEASUREMENTS", "RPC images: the GCPs measured on them (point_id, photo = the "
             "image's file name or stem, col_px, row_px)", extensions=TABLE_EXTENSIONS,
             optional=True),
        Enum("BIAS", "RPC bias refinement from the GCPs: auto (affine from 4 GCPs, else "
             "shift), shift, affine", options=("auto", "shift", "affine"), default="auto"),
    ]


def rpc_gcps(params: Mapping[str, Any], crs: Any = None) -> tuple[tuple, tuple]:
    """MEASUREMENTS (pixels) and CONTROL of :func:`rpc_gcp_parameters`, read for
    :func:`toolbox.ortho.rpc_block.refine_from_gcps`; CONTROL's X, Y are in ``crs`` (the
    ortho's horizontal CRS): a GeoPackage layer in another one is refused, never read as if
    in it."""
    from toolbox.photogrammetry.tables import control_crs, ground_points, image_measurements

    if crs is not None:
        control_crs(params["CONTROL"], crs, horizontal=True)
    return (image_measurements(params["MEASUREMENTS"], None, "pixel", "MEASUREMENTS"),
            ground_points(params["CONTROL"]))


def measured_inputs(params: Mapping[str, Any], control: bool = False,
                    on_image: bool = True) -> tuple:
    """``(project, measurements, control points)`` read from PROJECT, INPUT (LAYER,
    COORDINATES) and, with ``control``, CONTROL (else None). With ``on_image``, a pixel
    measured off its photo's image is an InputDataError naming INPUT."""
    from toolbox.photogrammetry.photo import check_measured_pixels
    from toolbox.photogrammetry.tables import ground_points, image_measurements, load_project_parameter

    project = load_project_parameter(params["PROJECT"])
    measurements = image_measurements(params["INPUT"], params["LAYER"], params["COORDINATES"])
    if on_image and measurements[3] == "pixel":
        check_measured_pixels(project.photos, *measurements[:3])
    return project, measurements, ground_points(params["CONTROL"], crs=project.crs) \
        if control else None


def measured_photos(project: Any, photo_ids: Sequence[str]) -> None:
    """Check that every photo INPUT measures is in PROJECT (InputDataError naming them)."""
    unknown = sorted({p for p in photo_ids if p not in project.photos})
    if unknown:
        raise InputDataError(f"INPUT names photo(s) {', '.join(map(repr, unknown[:5]))} that "
                             f"PROJECT does not have (photos: {', '.join(project.photos)})")
