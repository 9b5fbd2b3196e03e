"""Points and vertices of a vector layer as (n, 3) float64 arrays: Z from the geometry or a
field, read through Arrow when the driver allows it (no per-feature Python objects), every
coordinate checked finite."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.io.vector import (
    VectorLayerRef,
    _ogr,
    feature_rows,
    is_parquet,
    no_geometry,
    open_layer,
    quiet_m_warning,
    read_vector,
    warn_dxf_texts,
)


def _check_finite(values: np.ndarray, what: str, rows: np.ndarray | None = None) -> None:
    """InputDataError naming the features with a NaN/inf value; ``rows``: the 0-based feature
    of each row of ``values`` (default: one feature per row)."""
    bad = ~np.isfinite(values)
    if bad.any():
        bad = np.flatnonzero(bad.any(axis=1) if values.ndim > 1 else bad)
        owners = np.unique(bad if rows is None else rows[bad])
        raise InputDataError(f"{what}: {len(owners)} feature(s) ({feature_rows(owners)}) have "
                             "NaN/inf coordinates or Z")


def _check_z(has_z: np.ndarray, what: str, rows: np.ndarray, hint: str) -> None:
    """InputDataError when features lack Z: all of them (the layer has none) or some, named
    by their 0-based ``rows``; ``hint`` says what to do."""
    if has_z.all():
        return
    if not has_z.any():
        raise InputDataError(f"{what} has no Z in its geometry: {hint}")
    raise InputDataError(f"{what}: {int((~has_z).sum())} of {len(has_z)} features "
                         f"({feature_rows(rows[~has_z])}) have no Z: {hint}")


def skip_no_geometry(frame, name: str):
    """``frame`` without its features that have no geometry (null or empty: what a GeoPackage
    or a shapefile may hold), with one warning naming ``name``, their count and first rows
    (:func:`input_rows`); ``frame`` itself when every feature has one."""
    missing = no_geometry(frame.geometry.values)
    if not missing.any():
        return frame
    import logging

    logging.getLogger("toolbox").warning(
        f"{name}: {int(missing.sum())} of {len(frame)} feature(s) have no geometry (null or "
        f"empty) and are skipped ({feature_rows(input_rows(frame)[missing])})")
    return frame[~missing]


def points_xyz(frame, z_field: str | None = None, name: str = "INPUT") -> np.ndarray:
    """(N, 3) float64 X, Y, Z of every point (multipoints exploded).

    Z comes from ``z_field`` when given, else from the geometry; a layer without Z and without a
    field is an :class:`InputDataError`, as are NaN/inf coordinates: refusals name the features by
    :func:`input_rows`. Features without a geometry or with an empty one are skipped with a
    warning (:func:`skip_no_geometry`).
    """
    import shapely

    if len(frame.geometry.values) == 0:
        raise InputDataError(f"{name} has no features")
    frame = skip_no_geometry(frame, name)
    geoms = frame.geometry.values
    kinds = set(shapely.get_type_id(geoms).tolist())
    if not kinds <= {0, 4}:  # Point, MultiPoint
        raise InputDataError(f"{name} must contain points, found other geometry types")
    rows = input_rows(frame)
    if z_field is None:
        _check_z(shapely.has_z(geoms), name, rows,
                 "give a Z field (Z_FIELD) or use 3D points")
    coords, owner = shapely.get_coordinates(geoms, include_z=z_field is None, return_index=True)
    if z_field is not None:
        z_values = np.asarray(frame[z_field], dtype="float64")
        coords = np.column_stack([coords, z_values[owner]])
    _check_finite(coords, name, rows[owner])
    return coords


def read_points_xyz(source: Any, z_field: str | None = None, name: str = "INPUT") -> np.ndarray:
    """(N, 3) float64 X, Y, Z of a point layer (path, ``path|layername=x``, reference or frame).

    The same result and errors as ``points_xyz(read_vector(source), z_field, name)``, but a file
    layer of single points (Point or Point Z) is decoded straight from the WKB that GDAL hands
    over through Arrow, without building a GeoDataFrame of shapely objects: about ten times
    faster for a million points. Other layers (multipoints, CSV, empty points, in-memory frames,
    no pyarrow) take the general path.
    """
    ref = open_layer(source, name)
    warn_dxf_texts(ref, name)
    if ref.frame is None and not ref.open_options and ref.geometry_filter is None:
        xyz = _points_from_parquet(ref, z_field) if is_parquet(ref.path) else \
            _points_from_arrow(ref, z_field)
        if xyz is not None:
            _check_finite(xyz, name)
            return xyz
    return points_xyz(read_vector(ref, name=name), z_field, name)


def _points_from_arrow(ref: VectorLayerRef, z_field: str | None) -> np.ndarray | None:
    """Decode fixed-size little-endian WKB points; ``None`` when the layer needs the general path."""
    try:
        import pyarrow  # noqa: F401  (pyogrio's Arrow reader needs it)
    except ImportError:  # pragma: no cover - pyarrow is optional
        return None
    try:
        meta, table = _read_arrow(ref, [z_field] if z_field else [])
    except Exception:  # let the general path report the problem
        return None
    return _decode_points(table, meta.get("geometry_name") or "wkb_geometry", z_field)


def _points_from_parquet(ref: VectorLayerRef, z_field: str | None) -> np.ndarray | None:
    """A GeoParquet layer's WKB points read with pyarrow and decoded as :func:`_points_from_arrow`
    does (the general path builds a GeoDataFrame: 10 M points peaked at 3.6 GB through it)."""
    try:
        import pyarrow.parquet as pq

        column = ref.info["geometry_name"]
        table = pq.read_table(ref.path, columns=[column, *([z_field] if z_field else [])])
    except Exception:  # let the general path report the problem
        return None
    xyz = _decode_points(table, column, z_field)
    del table
    import pyarrow as pa

    pa.default_memory_pool().release_unused()  # Arrow's allocator keeps freed pages otherwise
    return xyz


def _decode_points(table, column: str, z_field: str | None) -> np.ndarray | None:
    """XYZ of an Arrow table's WKB point column (and Z field); None when not fixed-size
    little-endian points."""
    n = table.num_rows
    if n == 0 or column not in table.column_names:
        return None
    wkb = table.column(column).combine_chunks()
    if wkb.null_count or str(wkb.type) not in ("binary", "large_binary"):
        return None
    offset_type = np.int32 if str(wkb.type) == "binary" else np.int64
    offsets = np.frombuffer(wkb.buffers()[1], dtype=offset_type)[wkb.offset:wkb.offset + n + 1]
    size = int(offsets[1] - offsets[0])
    if size not in (21, 29) or not np.all(np.diff(offsets) == size):
        return None
    raw = np.frombuffer(wkb.buffers()[2], dtype=np.uint8)[offsets[0]:offsets[-1]].reshape(n, size)
    kinds = raw[:, 1:5].copy().view("<u4").ravel()
    wanted = (1,) if size == 21 else (1001, 0x80000001)
    if not (np.all(raw[:, 0] == 1) and np.isin(kinds, wanted).all()):
        return None
    coords = raw[:, 5:].copy().view("<f8")
    if np.isnan(coords).any():  # empty points: the general path skips them
        return None
    if z_field is not None:
        z = _float_column(table.column(z_field))
        return None if z is None else np.column_stack([coords[:, :2], z])
    if size == 21:
        return None  # no Z in the geometry: the general path explains
    return np.ascontiguousarray(coords)


def _read_arrow(ref: VectorLayerRef, columns: list[str]):
    """``(meta, pyarrow.Table)`` of a file layer, as ``pyogrio.read_arrow`` returns them, but
    without importing pandas and geopandas (``pyogrio.raw`` imports both, about 0.45 s of a
    small run): GDAL's Arrow stream opened through the call ``pyogrio.raw.open_arrow`` makes.
    That call is not public: with another signature the public reader is used."""
    _ogr()
    from pyogrio._io import ogr_open_arrow
    from pyogrio.util import get_vsi_path_or_buffer

    with quiet_m_warning():
        return _open_arrow(ref, columns, ogr_open_arrow, get_vsi_path_or_buffer)


def _open_arrow(ref: VectorLayerRef, columns: list[str], ogr_open_arrow, get_vsi_path_or_buffer):
    try:
        source = ogr_open_arrow(
            get_vsi_path_or_buffer(str(ref.path)), layer=ref.layer, encoding=None,
            columns=columns, read_geometry=True, force_2d=False, skip_features=0,
            max_features=0, where=ref.read_where, bbox=None, mask=None, fids=None, sql=None,
            sql_dialect=None, return_fids=False, dataset_kwargs={}, batch_size=65_536,
            use_pyarrow=True, datetime_as_string=False)
    except TypeError:  # another pyogrio
        import pyogrio

        return pyogrio.read_arrow(ref.path, layer=ref.layer, where=ref.read_where,
                                  columns=columns)
    with source as (meta, reader):
        return meta, reader.read_all()


def _float_column(column) -> np.ndarray | None:
    """A numeric Arrow column as float64, from its buffer (pyarrow's ``to_numpy`` imports
    pandas); ``None`` when it has nulls or is not numeric (the general path then decides)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    array = column.combine_chunks()
    if array.null_count or not (pa.types.is_integer(array.type)
                                or pa.types.is_floating(array.type)):
        return None
    array = pc.cast(array, pa.float64())
    return np.frombuffer(array.buffers()[1], dtype="<f8")[array.offset:array.offset + len(array)]


def vertices_xyz(frame, z_field: str | None = None, name: str = "INPUT"):
    """Vertices of every feature: ``(xyz (N, 3), feature_index (N,))``.

    Z from ``z_field`` (same value for every vertex of a feature, e.g. a contour's elevation) or
    from the geometry. Refusals name the features by :func:`input_rows`; features without a
    geometry are skipped with a warning (:func:`skip_no_geometry`).
    """
    import shapely

    frame = skip_no_geometry(frame, name)
    geoms = frame.geometry.values
    rows = input_rows(frame)
    if z_field is None and len(geoms):
        _check_z(shapely.has_z(geoms), name, rows, "give a Z field or use 3D geometries")
    coords, index = shapely.get_coordinates(geoms, include_z=z_field is None, return_index=True)
    if z_field is not None:
        z_values = np.asarray(frame[z_field], dtype="float64")
        coords = np.column_stack([coords, z_values[index]])
    else:
        _warn_zero_z(coords[:, 2], index, name, rows)
    _check_finite(coords, name, rows[index])
    return coords, index


def _warn_zero_z(z: np.ndarray, index: np.ndarray, name: str, rows: np.ndarray) -> None:
    """Warn about features whose Z is exactly 0 at some vertices and another value at others:
    OGR reads a vertex without Z in a 3D feature (GeoJSON ``[x, y]`` among ``[x, y, z]``, a
    Shapefile vertex whose Z was never set) as Z = 0, a height nobody measured."""
    if not len(z):
        return
    count = np.bincount(index, minlength=int(index.max()) + 1)
    zeros = np.bincount(index, weights=(z == 0).astype(float), minlength=len(count))
    mixed = np.flatnonzero((zeros > 0) & (zeros < count))
    if len(mixed):
        import logging

        logging.getLogger("toolbox").warning(
            f"{name}: {len(mixed)} feature(s) ({feature_rows(rows[mixed])}) have Z = 0 at "
            f"{int(zeros[mixed].sum())} vertices and other heights at the rest: a vertex "
            "without Z is read as 0 (GeoJSON [x, y] among [x, y, z], an unset Shapefile Z); "
            "their Z is used as 0")


def input_rows(frame) -> np.ndarray:
    """The 0-based input feature of each row of ``frame``: its index when it is an integer one
    (read_vector's, kept by a caller that drops or explodes features), else the positions."""
    index = np.asarray(frame.index)
    return index if index.dtype.kind in "iu" else np.arange(len(frame))
