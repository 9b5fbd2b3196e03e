"""Reading the topology inputs and writing its GeoPackage layers (the algorithms' I/O side)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from toolbox.feedback import Feedback
from toolbox.io.parameter_file import ParameterFile, read_parameter_file
from toolbox.topology.output import ERROR_LAYERS, Layer, TopologyOutput, split_errors
from toolbox.topology.tolerances import (
    TOPOLOGY_FILE_KEYS,
    Tolerances,
    resolve_tolerances,
)

CODE_FIELD_NAMES = ("code", "codice", "cod", "codes")
#: names the areas layer uses itself; label attributes with these names get a ``label_`` prefix
AREA_COLUMNS = ("id", "code", "labels", "area", "perimeter")
GEOMETRY_TYPES = {"areas": "Polygon", "arcs": "LineString", "nodes": "Point", **ERROR_LAYERS}
_METRE = {"m", "metre", "metres", "meter", "meters", "metro", "metri"}


def default_code_field(fields: list[str]) -> str | None:
    """The first field named like a code (code, codice, cod, codes), case-insensitively."""
    lower = {f.lower(): f for f in fields}
    for name in CODE_FIELD_NAMES:
        if name in lower:
            return lower[name]
    return None


def tolerances_from(explicit: dict[str, float | None], parameters: Path | None = None,
                    feedback: Feedback | None = None, crs: Any = None
                    ) -> tuple[Tolerances, dict[str, str], ParameterFile | None]:
    """Tolerances from the explicit values (by parameter name, None: not given) and the
    optional parameter file; warns about unknown entries of the file and a coordinate unit
    that does not match the CRS."""
    file = None if parameters is None else read_parameter_file(parameters, "PARAMETERS")
    tol, sources = resolve_tolerances(explicit, file)
    if feedback is not None and file is not None:
        file.warn_unused(TOPOLOGY_FILE_KEYS, feedback, "area building")
        file.check_unit(crs, feedback)
    return tol, sources, file


def label_inputs(frame, code_field: str | None) -> tuple[np.ndarray, np.ndarray,
                                                        dict[str, np.ndarray], dict[str, Any]]:
    """Geometries, codes and attributes of a label layer; attribute dtypes for the output."""
    geoms = np.asarray(frame.geometry.values, dtype=object)
    codes = (frame[code_field].to_numpy(dtype=object) if code_field is not None
             else np.full(len(frame), None, dtype=object))
    attrs: dict[str, np.ndarray] = {}
    dtypes: dict[str, Any] = {}
    for column in frame.columns:
        if column in (frame.geometry.name, code_field):
            continue
        name = f"label_{column}" if column.lower() in AREA_COLUMNS else column
        attrs[name] = frame[column].to_numpy(dtype=object)
        dtypes[name] = frame[column].dtype
    if len(frame) and bool(frame.geometry.has_z.any()) and "label_z" not in attrs:
        # a spot height plotted as a 3D point: its Z becomes an attribute of the area
        import shapely

        z = np.full(len(geoms), np.nan)
        point = (shapely.get_type_id(geoms) == 0) & shapely.has_z(geoms)
        z[point] = shapely.get_z(geoms[point])
        attrs["label_z"] = z.astype(object)
        dtypes["label_z"] = np.dtype("float64")
    return geoms, codes, attrs, dtypes


def _column(values: Any, dtype: Any = None):
    import pandas as pd

    series = pd.Series(np.asarray(values, dtype=object) if dtype is not None else values)
    if dtype is None:
        return series
    series = series.where(series.notna(), None)
    if pd.api.types.is_bool_dtype(dtype):
        return series.astype("boolean")
    if pd.api.types.is_integer_dtype(dtype):
        return series.astype("Int64")
    if pd.api.types.is_float_dtype(dtype):
        return pd.to_numeric(series, errors="coerce").astype("float64")
    return series.astype(object)


def to_frame(layer: Layer, crs: Any, dtypes: dict[str, Any] | None = None):
    """GeoDataFrame of a :class:`Layer` (columns in order, label attribute dtypes restored)."""
    import geopandas as gpd

    dtypes = dtypes or {}
    data = {name: _column(values, dtypes.get(name)) for name, values in layer.columns.items()}
    return gpd.GeoDataFrame(data, geometry=gpd.GeoSeries(list(layer.geometry), crs=crs),
                            crs=crs)


def error_frames(errors: Layer, crs: Any) -> dict[str, Any]:
    """The ``errors_points`` and ``errors_lines`` GeoDataFrames of a mixed errors layer."""
    return {name: to_frame(layer, crs) for name, layer in split_errors(errors).items()}


def write_topology(path: str | Path, output: TopologyOutput, crs: Any,
                   label_dtypes: dict[str, Any] | None = None,
                   layers: tuple[str, ...] = ("areas", "arcs", "nodes", "errors")) -> Path:
    """Write the chosen layers of a :class:`TopologyOutput` into one GeoPackage (or the format
    of ``path``); ``"errors"`` becomes the ``errors_points`` and ``errors_lines`` layers."""
    from toolbox.io.vector_write import write_layers

    frames = {}
    for name in layers:
        if name == "errors":
            frames |= error_frames(output.errors, crs)
        else:
            frames[name] = to_frame(getattr(output, name), crs, label_dtypes if name == "areas"
                                    else None)
    return write_layers(path, frames, crs=crs,
                        geometry_types={k: GEOMETRY_TYPES[k] for k in frames}, arrow=True)
