"""Vector writing: named layers in the format the output's extension names (GeoDataFrames or
plain arrays of WKB geometries).

The extension picks the OGR driver (:data:`toolbox.io.vector.VECTOR_DRIVERS`). A GeoPackage holds
every layer in the one file, written as GeoPackage 1.2 (QGIS 3.22 and GDAL 3.6 read it without
"only partially supported" warnings). The other formats hold one layer per file: the first layer
goes to the path given, each further layer to a file beside it named ``<stem>_<layer><ext>``
(``topo.shp``, ``topo_arcs.shp``, ...). GeoParquet is written through pyarrow/geopandas (the GDAL
in pyogrio's wheels has no Parquet driver).
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.io.vector import (
    _GEOMETRY_FAMILIES,
    GPKG_DATASET_OPTIONS,
    _ogr,
    is_multi_layer,
    no_geometry,
    sibling_layer_path,
    vector_driver,
)


@contextmanager
def staged_gpkg_writes():
    """Let SQLite skip fsync and keep its rollback journal in memory while writing a GeoPackage
    (about 15% faster on big layers; a layer's create, open and close no longer creates and
    deletes a ``-journal`` file beside it: about 0.7 ms of CPU per layer written).

    Safe for the toolbox's outputs: they are written to a staged file that is renamed into
    place only after a successful run, so a crash mid-write never leaves a damaged output. The
    in-memory journal still rolls a failed transaction back (``OFF`` would not).
    """
    ogr = _ogr()  # pyogrio.core: no pandas for a config option

    options = {"OGR_SQLITE_SYNCHRONOUS": "OFF", "OGR_SQLITE_JOURNAL": "MEMORY"}
    previous = {name: ogr.get_gdal_config_option(name) for name in options}
    ogr.set_gdal_config_options(options)
    try:
        yield
    finally:
        ogr.set_gdal_config_options(previous)


#: OGR's names of shapely's geometry type ids (``shapely.get_type_id``), as geopandas' geom_type
_TYPE_NAMES = ("Point", "LineString", "LinearRing", "Polygon", "MultiPoint", "MultiLineString",
               "MultiPolygon", "GeometryCollection")


def geometry_type_names(geoms) -> set[str]:
    """The geometry types (geopandas' ``geom_type`` names) of the geometries ``geoms`` (a
    GeoSeries, GeoDataFrame geometry or array; missing ones left out), from shapely's type ids
    in one pass: pandas' ``geom_type.dropna().unique()`` cost about 1 ms a layer."""
    import shapely

    counts = np.bincount(shapely.get_type_id(np.asarray(geoms, dtype=object)) + 1,
                         minlength=len(_TYPE_NAMES) + 1)  # -1 (missing) counted first
    return {name for name, n in zip(_TYPE_NAMES, counts[1:].tolist(), strict=False) if n}


def geometry_kinds(frame) -> set[str]:
    """Kinds (point, line, polygon) of the non-empty geometries of a frame."""
    if not len(frame):
        return set()
    return _kinds(geometry_type_names(frame.geometry.values))


def _kinds(types: set[str]) -> set[str]:
    """Kinds (point, line, polygon) of the geometry type names ``types``."""
    return {kind for kind, family in _GEOMETRY_FAMILIES.items() if types & set(family)}


def layer_paths(path: str | Path, names: list[str]) -> dict[str, Path]:
    """Where :func:`write_layers` puts each named layer: all in ``path`` for a GeoPackage; else
    the first in ``path`` and each other one in :func:`sibling_layer_path`."""
    path = Path(path)
    if is_multi_layer(path):
        return {name: path for name in names}
    return {name: path if i == 0 else sibling_layer_path(path, name)
            for i, name in enumerate(names)}


def write_layers(path: str | Path, layers: dict[str, Any], crs: Any = None,
                 geometry_types: dict[str, str] | None = None, arrow: bool = False) -> Path:
    """Write GeoDataFrames as named layers, in the format of ``path``'s extension.

    A GeoPackage (version 1.2) receives every layer (created or extended); a one-layer format
    (FlatGeobuf, GeoParquet, Shapefile, GeoJSON) gets the first layer in ``path`` and the others
    beside it (:func:`layer_paths`). ``geometry_types`` gives the OGR type (e.g.
    ``"Polygon Z"``, ``"Point"``) for layers that may be empty; every layer carries ``crs``
    (when its frame has none), empty ones too. A layer must hold one kind of geometry (points,
    lines or polygons: QGIS draws only one kind per layer); single and multi parts of a kind are
    written as multi. Inside an algorithm, ``path`` is the staged output path the runner handed
    over. ``arrow`` writes a GeoPackage through GDAL's Arrow interface (OGR_L_WriteArrowBatch:
    the same table, about a quarter less CPU on a big layer than feature by feature); it is for
    frames of plain numbers, text and shapely geometries.
    """
    import pyogrio

    from toolbox.io.write_failures import writing

    path = Path(path)
    driver = vector_driver(path)
    targets = layer_paths(path, list(layers))
    if driver == "GeoJSON":
        warn_empty_geojson([targets[n] for n, frame in layers.items() if not len(frame)])
    crs_texts: dict[int, tuple[Any, str]] = {}  # the layers' CRS as pyogrio passes it to GDAL
    for layer_name, frame in layers.items():
        if crs is not None and frame.crs is None:
            frame = frame.set_crs(crs)
        geometry = frame.geometry  # a new GeoSeries at each access: taken once
        types = geometry_type_names(geometry.values) if len(frame) else set()
        kinds = _kinds(types)
        if len(kinds) > 1:
            raise ValueError(f"internal: layer '{layer_name}' mixes {' and '.join(sorted(kinds))}"
                             "; write one layer per kind (see toolbox.topology.layers)")
        kwargs: dict[str, Any] = {}
        if geometry_types and layer_name in geometry_types:
            kwargs["geometry_type"] = geometry_types[layer_name]
        elif len(types) > 1:
            kwargs["promote_to_multi"] = True
        target = targets[layer_name]
        if driver == "ESRI Shapefile":
            frame = _dbf_frame(frame)
        if driver == "Parquet":  # GeoParquet 1.x through pyarrow (no Parquet driver in pyogrio)
            with writing(target):
                frame.to_parquet(target, index=False)
            continue
        if driver == "GPKG" and not target.exists():
            kwargs["dataset_options"] = GPKG_DATASET_OPTIONS
        if driver == "GPKG":
            kwargs["layer_options"] = _fid_column(frame)
        if driver == "FlatGeobuf" and len(frame) and geometry.isna().any():
            kwargs["layer_options"] = {"SPATIAL_INDEX": "NO"}  # its index takes no null geometry
        with staged_gpkg_writes(), writing(target), warnings.catch_warnings():
            if geometry.crs is None:  # a layer without CRS as read (stored coordinates): meant
                warnings.filterwarnings("ignore", "'crs' was not provided", UserWarning)
            warnings.filterwarnings("ignore", "Normalized/laundered field name")  # see below
            warnings.filterwarnings("ignore", "Value '.*' of field .* has been truncated")
            warnings.filterwarnings("ignore", "NaN of Infinity value found")  # warned below
            if not (arrow and driver == "GPKG"
                    and _write_arrow(frame, target, layer_name, kwargs)):
                resolved = _resolved_promotion(kwargs, driver, types, len(frame))
                if not _write_plain(frame, geometry, target, layer_name, driver, resolved,
                                    crs_texts):
                    pyogrio.write_dataframe(frame, target, layer=layer_name, driver=driver,
                                            **resolved)
        if driver == "GPKG":
            declare_optional_z(target, layer_name, geometry.values,
                               kwargs.get("geometry_type"))
        if driver == "ESRI Shapefile":
            fields = [c for c in frame.columns if c != geometry.name]
            note_shapefile_fields(target, fields)
            warn_cut_texts(target, {c: frame[c].to_numpy() for c in fields})
            warn_made_up_z(target, geometry.values)
        if driver == "GeoJSON":
            warn_infinite_values(target, {c: frame[c].to_numpy() for c in frame.columns
                                          if c != geometry.name})
    return path


def _resolved_promotion(kwargs: dict[str, Any], driver: str, types: set[str],
                        rows: int) -> dict[str, Any]:
    """``kwargs`` with ``promote_to_multi`` set to what ``pyogrio.write_dataframe`` resolves it
    to when given ``geometry_type`` and no ``promote_to_multi``: True for a layer of a driver
    that takes no mixed single and multi parts (GeoPackage, FlatGeobuf) whose geometries are
    exactly one single type and its multi type, else whether ``geometry_type`` is a multi type
    there. Given, pyogrio skips its own inference from the frame (``geom_type``, ``notna``,
    ``is_empty``, ``has_z`` through pandas: about 1.3 ms a layer); the file is the same.
    Unchanged without ``geometry_type``, with ``promote_to_multi``, and for a driver that takes
    no mixed 2D and 3D (FlatGeobuf: the inference refuses them)."""
    from pyogrio.raw import DRIVERS_NO_MIXED_DIMENSIONS, DRIVERS_NO_MIXED_SINGLE_MULTI

    if "geometry_type" not in kwargs or "promote_to_multi" in kwargs \
            or driver in DRIVERS_NO_MIXED_DIMENSIONS:
        return kwargs
    no_mix = driver in DRIVERS_NO_MIXED_SINGLE_MULTI
    pairs = ({"Point", "MultiPoint"}, {"LineString", "MultiLineString"},
             {"Polygon", "MultiPolygon"})
    promote = no_mix and ((rows > 0 and types in pairs)
                          or kwargs["geometry_type"].startswith("Multi"))
    return {**kwargs, "promote_to_multi": promote}


def _write_plain(frame, geometry, target: Path, layer: str, driver: str,
                 kwargs: dict[str, Any], crs_texts: dict[int, tuple[Any, str]]) -> bool:
    """What ``pyogrio.write_dataframe(frame, target, layer=layer, driver=driver, **kwargs)``
    does without Arrow once ``geometry_type`` and ``promote_to_multi`` are given
    (:func:`_resolved_promotion`): the same columns, masks, WKB and CRS text handed to
    ``pyogrio.raw.write``, without its pandas round trips (``geom_type`` of every geometry, a
    ``dtypes`` scan, ``to_epsg`` for each layer of one CRS: about 0.7 ms a layer). False, and
    nothing written, for a frame that needs pyogrio's own conversion (dates with a time zone,
    a second geometry column) or a layer whose promotion it resolves itself.
    ``geometry``: ``frame.geometry``; ``crs_texts`` keeps the CRS text of the CRS objects
    already seen (``id`` -> (CRS, text))."""
    import pandas as pd
    import pyogrio.raw
    from geopandas.array import GeometryDtype, to_wkb
    from pandas.arrays import BooleanArray, FloatingArray, IntegerArray

    if "geometry_type" not in kwargs or "promote_to_multi" not in kwargs:
        return False
    fields, data, masks = [], [], []
    for name in frame.columns:
        if name == geometry.name:
            continue
        column = frame[name]
        dtype = column.dtype
        if isinstance(dtype, (pd.DatetimeTZDtype, GeometryDtype)) or (
                dtype == "object" and pd.api.types.infer_dtype(column) == "datetime"):
            return False
        values = column.values
        if isinstance(values, (IntegerArray, FloatingArray, BooleanArray)):
            data.append(values._data)
            masks.append(values._mask)
        elif isinstance(values, pd.api.extensions.ExtensionArray):
            data.append(np.asarray(values))
            masks.append(np.asarray(values.isna()))
        else:
            data.append(values)
            masks.append(None)
        fields.append(name)
    crs = None
    if geometry.crs:
        seen = crs_texts.get(id(geometry.crs))
        if seen is None:
            seen = crs_texts[id(geometry.crs)] = (geometry.crs, gdal_crs_text(geometry.crs))
        crs = seen[1]  # the CRS object kept alive beside its text: ids are not reused
    pyogrio.raw.write(target, to_wkb(geometry.values), data, fields, field_mask=masks,
                      layer=layer, driver=driver, crs=crs, gdal_tz_offsets={}, **kwargs)
    return True


def gdal_crs_text(crs: Any) -> str:
    """The text a layer's pyproj ``crs`` is handed to GDAL as, what ``pyogrio.write_dataframe``
    hands it: ``EPSG:<code>`` when the CRS is an EPSG one (GDAL then writes its own definition,
    with every AUTHORITY node), else its WKT1 (GDAL flavour)."""
    epsg = crs.to_epsg()
    return f"EPSG:{epsg}" if epsg else crs.to_wkt("WKT1_GDAL")


def dbf_booleans(values):
    """``values`` (a numpy array or pandas Series) as a Shapefile should hold them: a Boolean
    column (numpy ``bool``, pandas ``boolean``, or object values all True/False/None) as
    Integer 0/1, nulls kept; any other column unchanged (the same object).

    GDAL before 3.9 (Debian's 3.6 under QGIS 3.22, and the 3.8 of QGIS 3.34) reads a DBF
    Logical field as String 'T'/'F' (Logical <-> Boolean came with GDAL 3.9, OSGeo/gdal#9515),
    so a QGIS filter or rule like ``"closed" = 1`` or ``"breakline"`` matched no feature or
    every one; 0/1 reads as Integer in every GDAL and QGIS. GeoPackage, GeoJSON and
    FlatGeobuf keep the Boolean subtype (GDAL 3.6 and QGIS 3.22 read it as Boolean)."""
    import pandas as pd

    if isinstance(values, np.ndarray):
        return _dbf_array(values)
    dtype = getattr(values, "dtype", None)
    if dtype is None:
        return values
    if pd.api.types.is_bool_dtype(dtype):  # numpy bool or the nullable "boolean"
        return values.astype("Int32")
    if pd.api.types.is_object_dtype(dtype) and len(values):
        present = values[values.notna()]
        if len(present) and all(isinstance(v, (bool, np.bool_)) for v in present):
            return values.astype("boolean").astype("Int32")
    return values


def _dbf_array(values: np.ndarray) -> np.ndarray:
    """A numpy Boolean array as Integer 0/1 (:func:`dbf_booleans`); other arrays unchanged."""
    return values.astype(np.int32) if values.dtype == np.bool_ else values


def _dbf_frame(frame):
    """``frame`` with its Boolean columns as Integer 0/1 (:func:`dbf_booleans`); the frame
    itself when it has none."""
    changed = {}
    for column in frame.columns:
        if column != frame.geometry.name:
            series = frame[column]
            values = dbf_booleans(series)
            if values is not series:
                changed[column] = values
    return frame.assign(**changed) if changed else frame


def _fid_column(frame) -> dict[str, str]:
    """The GeoPackage layer option naming its primary key (FID) column, away from the frame's
    fields: GDAL takes a field named ``fid`` (any case: an input's field, as a Shapefile or
    GeoJSON exported from a GeoPackage carries it) as the key, so text values, nulls or repeated
    numbers failed the write (the error blamed OUTPUT, or INPUT as corrupt) and unique numbers
    left the attribute table; with another key column the field is written as it is."""
    names = {str(c).casefold() for c in frame.columns}
    if "fid" not in names:
        return {}
    k = 1
    while f"fid_{k}" in names:
        k += 1
    return {"FID": f"fid_{k}"}


def warn_made_up_z(path: Path, geoms) -> None:
    """One warning when a Shapefile layer got 2D and 3D features: a Shapefile is 3D (PolyLineZ,
    PointZ...) or 2D throughout, so GDAL writes the 2D features with Z = 0, a height nobody
    measured (a 2D contour at 0 m)."""
    import shapely

    geoms = np.asarray(geoms, dtype=object)
    present = geoms[~no_geometry(geoms)]
    flat = int((~shapely.has_z(present)).sum()) if len(present) else 0
    if 0 < flat < len(present):
        import logging

        logging.getLogger("toolbox").warning(
            f"{path.name}: {flat} of {len(present)} features have no Z; a Shapefile layer is "
            "all 3D or all 2D, so they were written with Z = 0, a height they do not have "
            "(a .gpkg or .geojson output keeps them 2D)")


def declare_optional_z(path: Path, layer: str, geoms, geometry_type: str | None = None) -> None:
    """Declare Z *optional* (``z = 2`` in ``gpkg_geometry_columns``) for a GeoPackage layer whose
    geometries do not all agree with its declared Z flag: GDAL declares a layer with any 3D
    geometry ``z = 1`` (Z mandatory; ``geometry_types`` may declare it too) and writes its 2D
    geometries as they are, which the GeoPackage specification forbids (requirement 19: GDAL's
    ``validate_gpkg.py`` rejects the file, 'geometry without Z found'). 2D and 3D features both
    stay as they are (no height is made up); GDAL and QGIS read a ``z = 2`` layer as 3D.
    ``geometry_type``: the OGR type the layer was declared with, if any (``"Polygon Z"``); the
    file is opened only when the geometries disagree with each other or with it."""
    import shapely

    geoms = np.asarray(geoms, dtype=object)
    present = geoms[~no_geometry(geoms)]
    if not len(present):
        return
    has_z = shapely.has_z(present)
    all_z = bool(has_z.all())
    declared_z = None if geometry_type is None else \
        geometry_type.upper().rstrip().endswith("Z") or geometry_type.upper().startswith("3D")
    if (all_z or not has_z.any()) and declared_z in (None, all_z):
        return  # one kind, as GDAL declares it (a sqlite open per layer saved)
    import sqlite3

    with sqlite3.connect(path) as db:
        row = db.execute("SELECT z FROM gpkg_geometry_columns WHERE lower(table_name) = "
                         "lower(?)", (layer,)).fetchone()
        if row is not None and ((row[0] == 1 and not has_z.all())
                                or (row[0] == 0 and has_z.any())):
            db.execute("UPDATE gpkg_geometry_columns SET z = 2 WHERE lower(table_name) = "
                       "lower(?)", (layer,))
    db.close()


#: the longest text a DBF field holds, in bytes (UTF-8 in the toolbox's Shapefiles)
DBF_TEXT_BYTES = 254


def warn_cut_texts(path: Path, fields: dict[str, Any]) -> None:
    """One warning naming the text fields of ``fields`` (name -> values) whose values GDAL cut
    to :data:`DBF_TEXT_BYTES` bytes in the Shapefile ``path`` (an entity's ``geometry_wkt``,
    a long ``detail``), and how many: GDAL's own warning quoted the whole value and named
    no remedy."""
    cut = []
    for name, values in fields.items():
        if getattr(values, "dtype", None) is None or values.dtype.kind not in "OU":
            continue
        n = sum(1 for v in values if isinstance(v, str)
                and len(v) > DBF_TEXT_BYTES // 4 and len(v.encode("utf-8")) > DBF_TEXT_BYTES)
        if n:
            cut.append(f"{name} ({n})")
    if cut:
        import logging

        logging.getLogger("toolbox").warning(
            f"{path.name}: a Shapefile's text fields hold at most {DBF_TEXT_BYTES} bytes; values "
            f"of {', '.join(cut)} were cut to that length (a .gpkg output keeps them whole)")


def warn_infinite_values(path: Path, fields: dict[str, Any]) -> None:
    """One warning naming the number fields of ``fields`` (name -> values) holding +-infinity,
    and how many, which the GeoJSON ``path`` holds as null: JSON has no infinity (GDAL leaves
    the property out, as for NaN, the "no value" of a float field, which goes without a warning), so an
    infinite value is no longer told from a missing one there (a .gpkg keeps it)."""
    found = []
    for name, values in fields.items():
        values = np.asarray(values)
        if values.dtype.kind == "f":
            n = int(np.isinf(values).sum())
        elif values.dtype.kind == "O":
            n = sum(1 for v in values if isinstance(v, float) and np.isinf(v))
        else:
            continue
        if n:
            found.append(f"{name} ({n})")
    if found:
        import logging

        logging.getLogger("toolbox").warning(
            f"{path.name}: GeoJSON has no infinity; the infinite values of {', '.join(found)} "
            "were left empty (null), as missing values are (a .gpkg output keeps them)")


def warn_empty_geojson(paths: list[Path]) -> None:
    """One warning naming the GeoJSON files ``paths`` of layers without features: GeoJSON has
    no schema, so GDAL writes an empty layer as ``"features": []`` with neither its fields nor
    its geometry type (the GeoJSON driver has no option for them) and QGIS opens it as a table
    without geometry, its style not applied (a .gpkg output keeps both)."""
    if paths:
        import logging

        logging.getLogger("toolbox").warning(
            f"{', '.join(p.name for p in paths)}: no features; an empty GeoJSON layer keeps "
            "neither its fields nor its geometry type (QGIS opens it as a table without "
            "geometry, its style not applied); a .gpkg output keeps them")


#: the renamed fields of the Shapefiles this process wrote (:func:`note_shapefile_fields`: the
#: names GDAL wrote, read back after writing), by path: ``(dbf size and mtime, {name: held})``;
#: the last few only, an entry valid while its .dbf is unchanged
_HELD_NAMES: dict[str, tuple[tuple[int, int], dict[str, str]]] = {}
_HELD_NAMES_KEPT = 64
_HELD_NAMES_LOCK = threading.Lock()


def _dbf_state(path: Path) -> tuple[int, int] | None:
    try:
        stat = Path(path).with_suffix(".dbf").stat()
    except OSError:
        return None
    return stat.st_size, stat.st_mtime_ns


def note_shapefile_fields(path: Path, names: list[str]) -> None:
    """After writing the fields ``names`` (in order) to the Shapefile ``path``: read the names
    GDAL gave them (a DBF field name has at most 10 characters: GDAL cuts longer ones and
    makes them unique, ``quadratic_z`` -> ``quadratic_``, ``quadratic_err`` -> ``quadrati_1``),
    keep the renamed ones for :func:`shapefile_renames` (a style written beside the file later
    names them as the file holds them) and warn once listing them."""
    written = [str(name) for name in _ogr().read_info(path)["fields"]]
    renamed = {old: new for old, new in zip(names, written, strict=False) if old != new}
    state = _dbf_state(path)
    with _HELD_NAMES_LOCK:
        key = str(Path(path).absolute())
        _HELD_NAMES.pop(key, None)
        if renamed and state is not None:
            _HELD_NAMES[key] = (state, renamed)
            while len(_HELD_NAMES) > _HELD_NAMES_KEPT:
                _HELD_NAMES.pop(next(iter(_HELD_NAMES)))
    if renamed:
        import logging

        logging.getLogger("toolbox").warning(
            f"{path.name}: a Shapefile's field names have at most 10 characters; renamed "
            f"{', '.join(f'{old} -> {new}' for old, new in renamed.items())} (a .gpkg output "
            "keeps the names)")


def shapefile_renames(path: Path, names: list[str] | None,
                      referenced: Iterable[str | None] = ()) -> dict[str, str]:
    """``{name: name in the file}`` of the fields ``names`` (in the order written) that the
    Shapefile ``path`` holds under another (cut) name; without ``names``, of the
    ``referenced`` fields (a style's): as this process wrote them (:func:`note_shapefile_fields`:
    exact, ``quadrati_1`` for a second cut alike), else (a file written by another program, or
    changed since) those the file does not hold but holds cut to 10 characters."""
    written = [str(name) for name in _ogr().read_info(path)["fields"]]
    if names:
        return {old: new for old, new in zip(names, written, strict=False) if old != new}
    held = set(written)
    with _HELD_NAMES_LOCK:
        state, noted = _HELD_NAMES.get(str(Path(path).absolute()), (None, {}))
    if noted and state == _dbf_state(path) and set(noted.values()) <= held:
        return {name: noted[name] for name in referenced if name in noted}
    return {name: name[:10] for name in referenced
            if name and name not in held and name[:10] in held}


def rename_style_fields(text: str | None, renames: dict[str, str]) -> str | None:
    """A QML or SLD style ``text`` with its references to the fields of ``renames`` (a
    label's ``fieldName="..."``, a renderer's ``attr="..."``, an expression's quoted
    ``&quot;name&quot;``, an SLD ``<ogc:PropertyName>``) given the names a Shapefile holds:
    with the long names QGIS drew no label and no class from the style beside the file."""
    import re

    if not text or not renames:
        return text
    for old, new in renames.items():
        text = re.sub(rf'(="|&quot;|>){re.escape(old)}("|&quot;|<)', rf"\g<1>{new}\g<2>",
                      text)
    return text


def _write_arrow(frame, target: Path, layer: str, kwargs: dict[str, Any]) -> bool:
    """Write ``frame`` to a GeoPackage through Arrow; False (nothing written) when a column
    does not convert to an Arrow type (an object column mixing numbers and text): pyogrio
    converts the whole frame before it opens the file."""
    import pyarrow as pa
    import pyogrio

    try:
        pyogrio.write_dataframe(frame, target, layer=layer, driver="GPKG", use_arrow=True,
                                **kwargs)
    except pa.ArrowException:
        return False
    return True


def write_wkb_layer(path: str | Path, layer: str, wkb: np.ndarray, fields: dict[str, np.ndarray],
                    geometry_type: str, crs: Any = None, append: bool = False) -> Path:
    """Write one layer from arrays: ``wkb`` (object array of WKB geometries, e.g.
    ``shapely.to_wkb``) and one numpy array per field, without building a GeoDataFrame.

    A GeoPackage (version 1.2) receives the layer beside its others; GeoParquet goes through
    :func:`write_layers`. ``crs`` is anything with ``to_wkt()`` (pyproj or rasterio), or a
    text GDAL reads (``EPSG:3003``, a WKT; :func:`gdal_crs_text`), handed over as it is.
    ``append`` adds the rows to the layer an earlier call made (a GeoPackage only: a big layer
    written block by block).
    """
    from toolbox.io.write_failures import writing

    path = Path(path)
    driver = vector_driver(path)
    if driver == "Parquet":
        import geopandas as gpd
        import shapely

        frame = gpd.GeoDataFrame(fields, geometry=shapely.from_wkb(wkb), crs=crs)
        return write_layers(path, {layer: frame}, crs=crs, geometry_types={layer: geometry_type})
    _ogr()  # pyogrio registered without its __init__ (no pandas, geopandas, pyarrow)
    # what ``pyogrio.raw.write`` does for a plain path, called below it: the module
    # ``pyogrio.raw`` imports pandas, geopandas and pyarrow (``pyogrio._compat``), about 0.45 s
    # of a contour run; tests/toolbox/test_io.py checks the layer against OGR's reading
    from pyogrio._io import ogr_write

    if append and driver != "GPKG":
        raise ValueError(f"internal: appending to a {driver} layer")
    dataset_kwargs = dict(GPKG_DATASET_OPTIONS) if driver == "GPKG" and not path.exists() \
        else {}
    names = list(fields)
    if driver == "ESRI Shapefile":
        fields = {k: _dbf_array(v) for k, v in fields.items()}
    with staged_gpkg_writes(), writing(path), warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Normalized/laundered field name")  # warned below
        warnings.filterwarnings("ignore", "Value '.*' of field .* has been truncated")
        warnings.filterwarnings("ignore", "NaN of Infinity value found")  # warned below
        ogr_write(str(path), layer=layer, driver=driver, geometry=np.asarray(wkb, dtype=object),
                  fields=names, field_data=[fields[k] for k in names], field_mask=None,
                  crs=crs if crs is None or isinstance(crs, str) else crs.to_wkt(),
                  geometry_type=geometry_type,
                  encoding=None, dataset_kwargs=dataset_kwargs, layer_kwargs={}, append=append,
                  promote_to_multi=geometry_type.startswith("Multi") and driver in (
                      "GPKG", "FlatGeobuf"))
    if driver == "ESRI Shapefile":
        note_shapefile_fields(path, names)
        warn_cut_texts(path, fields)
    if driver == "GeoJSON":
        warn_infinite_values(path, fields)
        warn_empty_geojson([path] if len(wkb) == 0 else [])
    return path


def write_table_layers(path: str | Path, layers: dict[str, tuple[dict[str, np.ndarray], Any]],
                       crs: Any, geometry_types: dict[str, str]) -> Path:
    """Write named layers given as plain columns: ``{layer: (fields, geometries)}``, ``fields``
    one numpy array of numbers or text per field (in order), ``geometries`` shapely ones of
    the layer's ``geometry_types`` type (single parts of a multi type are written as multi);
    every layer in the pyproj ``crs``.

    The file is the one :func:`write_layers` writes from GeoDataFrames of these columns (the
    same features, field types and CRS definition): a GeoPackage's layers go through
    :func:`write_wkb_layer` without a GeoDataFrame (about 7 ms less CPU for the four small
    layers of ``mosaic:seamlines``: pandas' frame and column handling, not GDAL's writing);
    any other format through :func:`write_layers`.
    """
    import shapely

    path = Path(path)
    if vector_driver(path) != "GPKG" or any(
            str(name).casefold() == "fid" for fields, _ in layers.values() for name in fields):
        import geopandas as gpd

        frames = {name: gpd.GeoDataFrame(dict(fields), geometry=list(geoms), crs=crs)
                  for name, (fields, geoms) in layers.items()}
        return write_layers(path, frames, crs=crs, geometry_types=geometry_types)
    text = None if crs is None else gdal_crs_text(crs)
    for name, (fields, geoms) in layers.items():
        wkb = shapely.to_wkb(np.asarray(geoms, dtype=object).reshape(-1))
        write_wkb_layer(path, name, wkb, fields, geometry_types[name], text)
    return path
