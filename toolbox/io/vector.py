"""Vector reading: any layer OGR reads, into a GeoDataFrame or plain arrays.

Reading: GeoPackage, Shapefile, GeoJSON, FlatGeobuf, GeoParquet, DXF, GML, ... (whatever the GDAL
in pyogrio reads) and CSV, read as points from columns named (case-insensitively)
``x``/``east``/``easting``/``lon``, ``y``/``north``/``northing``/``lat`` and optionally
``z``/``elev``/``elevation``/``height``. A layer is addressed with QGIS's layer-source syntax::

    path[|layername=NAME | |layerid=N][|geometrytype=Point|LineString|Polygon][|subset=SQL]

``layerid`` is the 0-based index of the layer in the file; ``geometrytype`` keeps the features of
that kind (multi-part included); ``subset`` is an SQL WHERE clause handed to OGR (it comes last and
may itself contain ``|``).

Writing: :mod:`toolbox.io.vector_write` (the extension picks the OGR driver,
:data:`VECTOR_DRIVERS`); the layers written beside a one-layer format's file are found again by
``path|layername=NAME``. A ``|subset=`` SQL filter is not available on GeoParquet (read through
pyarrow/geopandas: the GDAL in pyogrio's wheels has no Parquet driver).

Curves (CircularString, CompoundCurve, CurvePolygon, MultiCurve, MultiSurface of a GeoPackage,
GML...; the ARCs, CIRCLEs and bulges of a DXF read through OGR) are linearised by GDAL with
chords of :data:`ARC_STEP_DEGREES` of arc (``OGR_ARC_STEPSIZE``; GDAL's default, 4 degrees, is
0.6 m off a curve of radius 1 km): at most ``radius * (1 - cos(step / 2))``, 1e-5 of the radius,
from the curve. An ``OGR_ARC_STEPSIZE`` of the environment is kept.

A GeoPackage in WAL mode: OGR reads the rows of its ``-wal``. GDAL (``CloseDB`` of its SQLite
drivers) reopens a file it read, read-write, when a ``-wal`` is beside it, so that SQLite, if no
other connection has it open, writes the ``-wal`` into the file and deletes it (the same rows,
other bytes); no open or config option avoids it (``NOLOCK`` changes nothing, ``IMMUTABLE``
leaves the ``-wal``'s rows out). A ``-wal`` OGR can only open with ``IMMUTABLE`` (no ``-shm``
can be created: a read-only folder) is refused by :func:`open_layer`, as SQLite refuses it
(:func:`toolbox.io.gpkg_summary.unread_wal`).
"""

from __future__ import annotations

import functools
import glob
import os
import re
import sys
import threading
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError

CSV_COORDINATE_NAMES = {  # in order of preference, matched case-insensitively
    "X_POSSIBLE_NAMES": ("x", "east", "easting", "e", "lon", "longitude"),
    "Y_POSSIBLE_NAMES": ("y", "north", "northing", "n", "lat", "latitude"),
    "Z_POSSIBLE_NAMES": ("z", "elev", "elevation", "height", "h", "quota"),
}
_NUMERIC_KINDS = "iuf"

#: output extension -> OGR driver (the formats :func:`write_layers` writes)
VECTOR_DRIVERS = {".gpkg": "GPKG", ".fgb": "FlatGeobuf", ".parquet": "Parquet",
                  ".shp": "ESRI Shapefile", ".geojson": "GeoJSON"}
#: GeoPackage creation options: version 1.2 (GDAL 3.6 / QGIS 3.22 warn on the newer 1.4)
GPKG_DATASET_OPTIONS = {"VERSION": "1.2"}
_GEOMETRY_FAMILIES = {"point": ("Point", "MultiPoint"),
                      "line": ("LineString", "MultiLineString", "LinearRing"),
                      "polygon": ("Polygon", "MultiPolygon")}


#: the angle (degrees) of the chords that replace the curves read through OGR
ARC_STEP_DEGREES = 0.5
os.environ.setdefault("OGR_ARC_STEPSIZE", str(ARC_STEP_DEGREES))  # GDAL reads it at each use

#: the OGR filter of a DXF's model-space entities (GDAL's DXF driver flags the others)
_MODEL_SPACE = '"PaperSpace" IS NULL'

_OGR_LOCK = threading.RLock()
#: pyogrio's warning when it reads a measured (M) layer without its M values (repeated at each
#: read, naming no layer): replaced by one warning per input naming it (:func:`_warn_measured`)
_MEASURED = "Measured \\(M\\) geometry types are not supported"


def _ogr():
    """``pyogrio.core`` (``list_layers``, ``read_info``) without importing pandas and geopandas.

    ``import pyogrio`` runs the package's ``__init__``, which imports ``pyogrio.geopandas`` and
    so pandas and geopandas (about 0.45 s) even for metadata. Opening an input (parameter
    validation) needs only ``pyogrio.core``: the package is registered without running its
    ``__init__``, ``core`` is loaded, and the ``__init__`` runs on the first use of any other
    name (``pyogrio.read_dataframe``, ``from pyogrio import ...``; PEP 562 module
    ``__getattr__``), so every other use of pyogrio is unchanged.
    """
    with _OGR_LOCK:
        if "pyogrio" not in sys.modules:
            import importlib.util

            import shapely  # noqa: F401  (before GDAL's GEOS, as pyogrio's __init__ does)

            spec = importlib.util.find_spec("pyogrio")
            package = importlib.util.module_from_spec(spec)
            state = {"done": False}

            def finish(name: str):
                with _OGR_LOCK:
                    if not state["done"]:
                        state["done"] = True
                        spec.loader.exec_module(package)
                if name in package.__dict__:
                    return package.__dict__[name]
                raise AttributeError(f"module 'pyogrio' has no attribute {name!r}")

            package.__getattr__ = finish
            sys.modules["pyogrio"] = package
        import pyogrio.core

    _pyogrio_errors_here()
    return pyogrio.core


_THREAD = threading.local()


def _pyogrio_errors_here() -> None:
    """Give the calling thread pyogrio's GDAL error handler (once a thread). pyogrio pushes it
    at import on the importing thread's stack only (GDAL's handler stacks are per thread): on
    any other thread GDAL printed its warnings raw on stderr ("Warning 6: Normalized/laundered
    field name ...", after the toolbox's own warning) instead of raising Python warnings, which
    the writers filter or report once (seen in a batch, whose steps run off the importing
    thread). Pushed again on the importing thread, it is only the same handler on top."""
    if getattr(_THREAD, "pyogrio_errors", False):
        return
    from pyogrio._err import _register_error_handler

    _register_error_handler()
    _THREAD.pyogrio_errors = True


def vector_driver(path: str | Path) -> str:
    """OGR driver of an output path, from its extension (:data:`VECTOR_DRIVERS`)."""
    suffix = Path(path).suffix.lower()
    if suffix not in VECTOR_DRIVERS:
        raise ParameterError("", f"vector output '{path}' must end with "
                             f"{', '.join(VECTOR_DRIVERS)}, got '{suffix or '(no extension)'}'")
    return VECTOR_DRIVERS[suffix]


def is_multi_layer(path: str | Path) -> bool:
    """True for formats holding several layers in one file (GeoPackage)."""
    return Path(path).suffix.lower() in (".gpkg", ".sqlite")


def sibling_layer_path(path: str | Path, layer: str) -> Path:
    """The file holding ``layer`` beside a one-layer-per-file output ``path``."""
    path = Path(path)
    return path.with_name(f"{path.stem}_{layer}{path.suffix}")


def _geometry_kind(geometry_type: str | None) -> str | None:
    if not geometry_type:
        return None
    text = geometry_type.lower()
    for kind, words in (("point", ("point",)), ("line", ("line", "curve")),
                        ("polygon", ("polygon", "surface"))):
        if any(w in text for w in words):
            return kind
    return None  # "Unknown" / "Geometry": mixed, decided per feature


@dataclass
class VectorLayerRef:
    """A validated reference to a vector layer (a file layer or an in-memory GeoDataFrame).

    ``where`` (the ``|subset=`` SQL) and ``geometry_filter`` (the ``|geometrytype=`` kind: point,
    line or polygon) restrict the features read; readers that bypass :func:`read_vector` must
    honour them or take the general path.
    """

    path: Path | None
    layer: str | None
    info: dict[str, Any]
    open_options: dict[str, str] = field(default_factory=dict)
    frame: Any = None  # GeoDataFrame given directly in Python
    where: str | None = None
    geometry_filter: str | None = None
    #: the file's other layers when none was named and its first one was taken (the reader
    #: warns once, see :func:`open_layer`)
    default_of: tuple[str, ...] = ()
    #: the layer's M values were dropped and the reader warned about it (once)
    m_warned: bool = False
    #: a DXF layer (GDAL's DXF driver reads paper space too): its model space only is read
    model_space: bool = False

    def __str__(self) -> str:
        if self.path is None:
            return "<GeoDataFrame>"
        return f"'{self.as_text()}'"

    @property
    def filtered(self) -> bool:
        """True when only some features of the layer are read (subset or geometry type)."""
        return bool(self.where) or self.geometry_filter is not None

    @property
    def read_where(self) -> str | None:
        """The OGR filter the readers apply: the ``|subset=`` and, for a DXF, model space only
        (GDAL reads the entities of the layouts' paper space into the same layer, in sheet
        units: a title block at (10, 10) beside world coordinates)."""
        if not self.model_space:
            return self.where or None
        return f"({self.where}) AND {_MODEL_SPACE}" if self.where else _MODEL_SPACE

    @property
    def crs(self):
        from pyproj import CRS

        crs = self.info.get("crs")
        return None if crs is None else CRS.from_user_input(crs)

    @property
    def geometry_type(self) -> str | None:
        if self.geometry_filter is not None:  # the kind the user asked for
            return _FILTER_NAMES[self.geometry_filter]
        return self.info.get("geometry_type")

    @property
    def geometry_kind(self) -> str | None:
        return _geometry_kind(self.geometry_type)

    @property
    def fields(self) -> list[str]:
        return list(self.info.get("fields", []))

    @property
    def coordinate_columns(self) -> list[str]:
        """A CSV's X, Y (and Z) columns, read as the point geometry and so not among
        :attr:`fields` (empty for other layers)."""
        return csv_coordinate_columns(self.open_options)

    @property
    def field_types(self) -> dict[str, str]:
        return dict(zip(self.info.get("fields", []), self.info.get("dtypes", []), strict=True))

    @property
    def count(self) -> int:
        return int(self.info.get("features", -1))

    def is_numeric(self, name: str) -> bool:
        return np.dtype(self.field_types[name]).kind in _NUMERIC_KINDS

    def as_text(self) -> str:
        """The reference as the user would type it (for reports and pipelines)."""
        if self.path is None:
            return "<GeoDataFrame>"
        text = f"{self.path}|layername={self.layer}" if self.layer else str(self.path)
        if self.geometry_filter:
            text += f"|geometrytype={_FILTER_NAMES[self.geometry_filter]}"
        if self.where:
            text += f"|subset={self.where}"
        return text


def _frame_info(frame) -> dict[str, Any]:
    geom_types = sorted(set(frame.geom_type.dropna())) if len(frame) else []
    has_z = bool(len(frame)) and bool(frame.geometry.has_z.any())
    gtype = geom_types[0] if len(geom_types) == 1 else ("Unknown" if geom_types else None)
    if gtype and has_z and gtype != "Unknown":
        gtype += " Z"
    cols = [c for c in frame.columns if c != frame.geometry.name]
    return {"crs": None if frame.crs is None else frame.crs.to_wkt(), "fields": cols,
            "dtypes": [str(frame[c].dtype) for c in cols], "geometry_type": gtype,
            "features": len(frame)}


_FILTER_NAMES = {"point": "Point", "line": "LineString", "polygon": "Polygon"}


@dataclass
class LayerSource:
    """The parts of a QGIS layer-source string ``path|key=value|...``."""

    path: str
    layername: str | None = None
    layerid: int | None = None
    geometry_filter: str | None = None
    subset: str | None = None


def parse_layer_source(text: str, name: str = "INPUT") -> LayerSource:
    """Split ``path|layername=x|layerid=n|geometrytype=T|subset=SQL`` (QGIS's syntax).

    ``subset`` comes last and keeps any ``|`` it contains. Raises :class:`ParameterError`
    naming ``name`` for an unknown key or a malformed value.
    """
    path, *parts = text.split("|")
    source = LayerSource(path)
    for i, part in enumerate(parts):
        key, eq, value = part.partition("=")
        key = key.strip().lower()
        if key == "subset":
            source.subset = "|".join([value, *parts[i + 1:]]).strip() or None
            break
        if not eq or not value.strip():
            raise ParameterError(name, f"{text!r}: '{part}' must be key=value (layername=, "
                                 "layerid=, geometrytype=, subset=)")
        value = value.strip()
        if key == "layername":
            source.layername = value
        elif key == "layerid":
            if not value.isdigit():
                raise ParameterError(name, f"{text!r}: layerid must be a layer index 0, 1, ..., "
                                     f"got {value!r}")
            source.layerid = int(value)
        elif key == "geometrytype":
            kind = _geometry_kind(value)
            if kind is None:
                raise ParameterError(name, f"{text!r}: geometrytype must be Point, LineString or "
                                     f"Polygon (or their Multi/25D forms), got {value!r}")
            source.geometry_filter = kind
        else:
            raise ParameterError(name, f"{text!r}: unknown option '{key}'; expected layername=, "
                                 "layerid=, geometrytype= or subset=")
    if source.layername is not None and source.layerid is not None:
        raise ParameterError(name, f"{text!r}: give layername= or layerid=, not both")
    return source


def _resolve_layer_file(path: Path, layer: str | None, layers: list[str]) -> Path | None:
    """For one-layer-per-file outputs: the sibling file ``<stem>_<layer><ext>`` holding
    ``layer`` when ``path`` itself does not (see :func:`write_layers`)."""
    if layer is None or layer in layers or is_multi_layer(path):
        return None
    sibling = sibling_layer_path(path, layer)
    return sibling if sibling.exists() else None


#: one-layer formats whose layer is named after the file (no layer name is recorded in it)
_STEM_NAMED = (".shp", ".parquet")


def _refuse_first_of_set(path: Path, layer: str | None, name: str) -> None:
    """Refuse ``path|layername=layer`` where ``path`` heads a set of layer files the toolbox
    wrote in a one-layer format that records no layer name (Shapefile, GeoParquet): its first
    layer is ``path`` itself, the others ``<stem>_<layer><ext>`` beside it (:func:`write_layers`),
    so the name cannot be checked (a misspelt one would read the first layer): the message says
    what to give instead. Nothing when ``path`` has no such siblings."""
    if layer is None or path.suffix.lower() not in _STEM_NAMED:
        return
    others = sorted(p.stem[len(path.stem) + 1:]
                    for p in path.parent.glob(f"{glob.escape(path.stem)}_*{path.suffix}"))
    if others:
        raise ParameterError(name, f"layer '{layer}' is not a file beside '{path.name}', and a "
                             f"{path.suffix} records no layer name to check it against: the "
                             "toolbox writes the first layer of a multi-layer output to "
                             f"'{path.name}' itself and the others beside it "
                             f"({', '.join(f'{path.stem}_{o}{path.suffix}' for o in others)}); "
                             f"give '{path.name}' without |layername= for the first layer")


def open_layer(value: Any, name: str = "INPUT", known_layer: str | None = None) -> VectorLayerRef:
    """Validate a vector layer reference and read its metadata (not its features).

    ``value`` is a path, a QGIS layer source (see the module docstring), a
    :class:`VectorLayerRef` or a GeoDataFrame. Raises :class:`ParameterError` naming ``name``
    for a missing file, an unknown layer or a file OGR cannot read.

    A file of several layers given without ``|layername=``/``|layerid=`` is read from its first
    layer (OGR's default). The readers (:func:`read_vector`, :func:`read_geometries`,
    :func:`toolbox.io.vector_points.read_points_xyz`) open the validated reference again before
    reading its features: then a warning names the layer taken and the others, once. Code that
    reads such a file by its layer names (a TIN's ``nodes``, ``vector:info``) does not read the
    default layer through them, so it is not warned about. ``known_layer``: the layer read,
    without a warning, from a file of several that has it and was given without a layer (the
    toolbox's own outputs: mosaic:seamlines' ``cut_polygons``).
    """
    if isinstance(value, VectorLayerRef):
        _warn_default_layer(value, name)
        _warn_measured(value, name)
        return value
    if hasattr(value, "geometry") and hasattr(value, "crs"):  # GeoDataFrame
        return VectorLayerRef(None, None, _frame_info(value), frame=value)
    if not isinstance(value, (str, Path)):
        raise ParameterError(name, f"must be a vector layer path, got {value!r}")
    source = parse_layer_source(str(value), name) if "|" in str(value) else \
        LayerSource(str(value))
    text, layer = source.path, source.layername
    path = Path(text).expanduser()
    if not path.exists():
        raise ParameterError(name, f"file '{text}' does not exist")
    if path.suffix.lower() == ".parquet":
        return _open_parquet(path, source, name)
    from toolbox.io.gpkg_summary import unread_wal

    refused = unread_wal(path)
    if refused:
        raise ParameterError(name, refused)
    ogr = _ogr()
    try:
        options = _csv_open_options(path) if path.suffix.lower() == ".csv" else {}
        rows, _ = _without_m_warning(ogr.list_layers, path)
        layers = [str(row[0]) for row in rows]
    except Exception as exc:  # pyogrio raises DataSourceError and friends
        raise ParameterError(name, f"cannot read '{text}' as a vector layer: "
                             f"{str(exc).splitlines()[0]}") from None
    sibling = _resolve_layer_file(path, layer, layers)
    if sibling is not None:
        path, layer = sibling, None
        rows, _ = _without_m_warning(ogr.list_layers, path)
        layers = [str(row[0]) for row in rows]
    elif layer is not None and layer not in layers and len(layers) == 1:
        _refuse_first_of_set(path, layer, name)
    if source.layerid is not None:
        if source.layerid >= len(layers):
            raise ParameterError(name, f"layerid={source.layerid} but '{text}' has "
                                 f"{len(layers)} layer(s): {', '.join(layers)}")
        layer = layers[source.layerid]
    if layer is not None and layer not in layers:
        raise ParameterError(name, f"layer '{layer}' is not in '{text}'; layers are: "
                             f"{', '.join(layers)}")
    default_of = ()
    if layer is None and len(layers) > 1 and known_layer in layers:
        layer = known_layer
    elif layer is None and len(layers) > 1:
        layer = layers[0]  # OGR's default layer, named so that pyogrio does not warn
        # the other layers of features (not tables such as layer_styles): warned about
        default_of = tuple(str(n) for n, kind in rows[1:] if kind is not None)
    info = _layer_info(path, layer, options, name, f"'{text}'")
    ref = VectorLayerRef(path, layer, info, options, where=source.subset,
                         geometry_filter=source.geometry_filter, default_of=default_of,
                         model_space=_warn_paper_space(path, layer, info, name))
    if ref.where:  # an SQL error is the user's: report it now, naming the parameter
        import pyogrio

        try:
            pyogrio.read_dataframe(path, layer=layer, where=ref.where, max_features=1,
                                   read_geometry=False, **options)
        except Exception as exc:
            raise ParameterError(name, f"subset {ref.where!r} is not a valid filter of "
                                 f"'{text}': {str(exc).splitlines()[0]}") from None
    return ref


def _warn_paper_space(path: Path, layer: str | None, info: dict[str, Any], name: str) -> bool:
    """True for a layer of GDAL's DXF driver (its readers then leave paper space out), with a
    warning when the drawing has entities in paper space. The model space's texts (TEXT,
    MTEXT: OGR points with a ``Text``) are counted in ``info["dxf_texts"]`` for the point
    readers' warning."""
    fields = list(info.get("fields", []))
    if info.get("driver") != "DXF" or "PaperSpace" not in fields:
        return False
    stat = path.stat()
    counts = _dxf_counts(str(path), layer, stat.st_mtime_ns, stat.st_size,
                         tuple(c for c in ("PaperSpace", "Text", "Layer") if c in fields))
    if counts is None:  # the readers report an unreadable file
        return True
    paper, texts = counts
    if texts is not None:
        info["dxf_texts"] = texts
    if paper:
        import logging

        logging.getLogger("toolbox").warning(
            f"{name} '{path}': {paper} entities of the drawing's paper space (layouts, in "
            "sheet units) left out: only model space is read")
    return True


@functools.lru_cache(maxsize=8)
def _dxf_counts(path: str, layer: str | None, mtime: int, size: int, columns: tuple[str, ...]):
    """``(paper-space entities, (model-space texts, their layers) or None)`` of a DXF layer
    (one parse of the file per version of it, however often it is opened); None when OGR
    cannot read it."""
    import pyogrio

    try:
        table = pyogrio.read_dataframe(path, layer=layer, read_geometry=False,
                                       columns=list(columns))
    except Exception:  # noqa: BLE001 - the readers report an unreadable file
        return None
    paper = table["PaperSpace"].notna().to_numpy()
    texts = None
    if "Text" in table:
        rows = table[~paper & table["Text"].notna().to_numpy()]
        texts = (len(rows), sorted(map(str, rows["Layer"].unique())) if "Layer" in rows else [])
    return int(paper.sum()), texts


def warn_dxf_texts(ref: VectorLayerRef, name: str) -> None:
    """Warn when a DXF layer read as points holds texts (GDAL gives TEXT/MTEXT as points at
    their insertion, Z often 0): they are read as points unless a ``|subset=`` leaves them
    out."""
    count, layers = ref.info.get("dxf_texts", (0, []))
    if not count or ref.where:
        return
    import logging

    logging.getLogger("toolbox").warning(
        f"{name} {ref}: {count} of its points are DXF texts (layers {', '.join(layers[:5])}), "
        "read as points at their insertion point; if they are labels, leave them out with "
        f"'{ref.path}|subset=\"Text\" IS NULL'")


def _warn_default_layer(ref: VectorLayerRef, name: str) -> None:
    """Warn (once per reference) that the features of ``ref`` come from the first layer of a
    file of several, taken because none was named."""
    if not ref.default_of:
        return
    import logging

    others = ", ".join(f"'{n}'" for n in ref.default_of)
    logging.getLogger("toolbox").warning(
        f"{name} '{ref.path}' has {len(ref.default_of) + 1} layers and none was named: read its "
        f"first layer '{ref.layer}' (others: {others}); choose one with "
        f"'{ref.path}|layername=NAME'")
    ref.default_of = ()


def _warn_measured(ref: VectorLayerRef, name: str) -> None:
    """Warn (once per reference) that the layer's geometries carry M values, which are dropped
    (pyogrio reads X, Y and Z only)."""
    measured = ref.info.get("measured_type")
    if not measured or ref.m_warned:
        return
    import logging

    layer = ref.layer or ref.info.get("layer_name")
    layer = f" layer '{layer}'" if layer else ""
    logging.getLogger("toolbox").warning(
        f"{name} '{ref.path}'{layer} has measured geometries ({measured}): their M values are "
        "dropped, only X, Y (and Z) are read")
    ref.m_warned = True


@contextmanager
def quiet_m_warning():
    """pyogrio's M warning silenced (for the readers of a reference :func:`open_layer` opened:
    it says it once)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_MEASURED)
        yield


def _without_m_warning(call, *args, **kwargs):
    """``call(*args, **kwargs)`` with pyogrio's M warning silenced (:func:`_warn_measured`
    says it once), and the original measured type it names, or None."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = call(*args, **kwargs)
    measured = None
    for w in caught:
        match = re.search(_MEASURED + r"\. Original type '([^']*)'", str(w.message))
        if match:
            measured = match.group(1)
        else:  # the other warnings as they came
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return result, measured


def _open_parquet(path: Path, source: LayerSource, name: str) -> VectorLayerRef:
    """A GeoParquet file (metadata only: its schema and GeoParquet ``geo`` key). The GDAL in
    pyogrio's wheels has no Parquet driver, so :func:`read_vector` reads it with geopandas.
    ``|layername=`` finds a sibling ``<stem>_<layer>.parquet``; ``|subset=`` (SQL) is not
    available for GeoParquet."""
    import json

    import pyarrow.parquet as pq

    if source.subset:
        raise ParameterError(name, f"'{path}': |subset= (SQL) is not supported for GeoParquet; "
                             "convert the file to GeoPackage or filter it first")
    if source.layerid not in (None, 0):
        raise ParameterError(name, f"layerid={source.layerid} but '{path}' has 1 layer")
    if source.layername and source.layername != path.stem:
        sibling = sibling_layer_path(path, source.layername)
        if not sibling.exists():
            _refuse_first_of_set(path, source.layername, name)
            raise ParameterError(name, f"layer '{source.layername}' is neither '{path}' nor a "
                                 f"file '{sibling.name}' beside it")
        path = sibling
    try:
        schema = pq.read_schema(path)
        geo = json.loads((schema.metadata or {})[b"geo"])
        column = geo["primary_column"]
        meta = geo["columns"][column]
        rows = pq.ParquetFile(path).metadata.num_rows
    except Exception as exc:
        raise ParameterError(name, f"cannot read '{path}' as GeoParquet: "
                             f"{str(exc).splitlines()[0]}") from None
    crs = meta.get("crs", "OGC:CRS84")  # GeoParquet: a missing crs means OGC:CRS84
    if isinstance(crs, dict):
        from pyproj import CRS

        crs = CRS.from_json_dict(crs).to_wkt()
    types = meta.get("geometry_types") or []
    fields = [f for f in schema if f.name != column]
    info = {"layer_name": path.stem, "crs": crs, "fields": [f.name for f in fields],
            "dtypes": [np.dtype(f.type.to_pandas_dtype()).name for f in fields],
            "geometry_type": types[0] if len(types) == 1 else ("Unknown" if types else None),
            "features": rows, "geometry_name": column}
    return VectorLayerRef(path, None, info, geometry_filter=source.geometry_filter)


def is_parquet(path: Path | None) -> bool:
    return path is not None and path.suffix.lower() == ".parquet"


def _csv_open_options(path: Path) -> dict[str, str]:
    """GDAL CSV open options naming exactly one X, Y and (if present) Z column.

    One name per axis: GDAL (3.10) with several candidate columns and KEEP_GEOM_COLUMNS=NO
    crashes, so the header is inspected here and the first preferred name is chosen. The
    coordinate columns are kept as fields (KEEP_GEOM_COLUMNS=YES) so that a ``|subset=`` WHERE
    can name them (``Z > 300``); :func:`csv_coordinate_columns` lists them, and the layer's fields
    (:func:`open_layer`) and features (:func:`read_vector`) leave them out.
    """
    encoding = _csv_encoding(path)
    extra = {} if encoding is None else {"encoding": encoding}
    fields = [str(f) for f in _ogr().read_info(path, **extra)["fields"]]
    lower = {f.lower(): f for f in fields}
    options = {"AUTODETECT_TYPE": "YES", **extra}
    for key, names in CSV_COORDINATE_NAMES.items():
        found = next((lower[n] for n in names if n in lower), None)
        if found is not None:
            options[key] = found
    if "X_POSSIBLE_NAMES" in options and "Y_POSSIBLE_NAMES" in options:
        options["KEEP_GEOM_COLUMNS"] = "YES"
        _check_csv_coordinates(path, encoding or "utf-8-sig", fields,
                               csv_coordinate_columns(options))
    else:  # no coordinates: a plain table
        options = {"AUTODETECT_TYPE": "YES", **extra}
    return options


def _csv_encoding(path: Path) -> str | None:
    """None for a UTF-8 (or ASCII) CSV, ``cp1252`` for one that is not UTF-8 (Windows/Latin-1,
    as Italian offices' spreadsheets save it): GDAL hands the bytes on undecoded, and pyogrio
    failed on the first accented value ('utf-8' codec can't decode)."""
    import codecs

    decoder = codecs.getincrementaldecoder("utf-8")()
    with open(path, "rb") as fh:
        try:
            while chunk := fh.read(1 << 20):
                decoder.decode(chunk)
            decoder.decode(b"", final=True)
        except UnicodeDecodeError:
            return "cp1252"
    return None


_PLAIN_NUMBER = r"^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*$"
_COMMA_NUMBER = r"^\s*[+-]?(\d+,?\d*|,\d+)([eE][+-]?\d+)?\s*$"  # a ';' file's decimal comma


def _csv_numbers_plain(path: Path, encoding: str, delimiter: str, width: int,
                       indices: list[int]) -> bool:
    """True when every row has a plain number (digits, one '.' or none) in each column of
    ``indices``; False when one has not (or pyarrow cannot tell): the caller looks row by row."""
    try:
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.csv as pacsv

        names = [f"c{k}" for k in range(width)]
        table = pacsv.read_csv(
            path, read_options=pacsv.ReadOptions(encoding=encoding, skip_rows=1,
                                                 column_names=names),
            parse_options=pacsv.ParseOptions(delimiter=delimiter),
            convert_options=pacsv.ConvertOptions(
                include_columns=[names[k] for k in indices],
                column_types={names[k]: pa.string() for k in indices},
                strings_can_be_null=False))
        patterns = [_PLAIN_NUMBER] + ([_COMMA_NUMBER] if delimiter == ";" else [])
        return all(any(pc.all(pc.match_substring_regex(table.column(names[k]), pattern)
                              ).as_py() is not False for pattern in patterns)
                   for k in indices)
    except Exception:  # a ragged row, an encoding pyarrow lacks, ...
        return False


def _check_csv_coordinates(path: Path, encoding: str, fields: list[str],
                           columns: list[str]) -> None:
    """Every X/Y/Z cell of the CSV is a number as written, else a ``ValueError`` naming the line,
    column and cell.

    GDAL reads ``1.000,5`` (a thousands dot, as a spreadsheet with an Italian locale writes it) as
    no value, so that the row's point was dropped in silence, ``1.010`` beside decimal commas as
    1.01 instead of 1010, and a row with an empty X or Y as no point (dropped too). A ``;`` file's
    decimal comma (``1234,5``) is read by GDAL as 1234.5 and is accepted here too.
    """
    import csv

    with open(path, encoding=encoding, newline="", errors="replace") as fh:
        header_line = fh.readline()
        delimiter = next((d for d in (",", ";", "\t", "|", " ")
                          if [c.strip().strip('"') for c in next(csv.reader(
                              [header_line], delimiter=d), [])] == fields), None)
        if delimiter is None:
            return  # a header GDAL reads otherwise: left to GDAL
        index = {fields.index(c): c for c in columns}
        if _csv_numbers_plain(path, encoding, delimiter, len(fields), list(index)):
            return  # the usual file: checked at C speed (1 M rows: 0.3 s, the loop 3.4 s)
        comma_seen: dict[int, int] = {}
        dotted: dict[int, tuple[int, str]] = {}
        for lineno, row in enumerate(csv.reader(fh, delimiter=delimiter), start=2):
            if not any(cell.strip() for cell in row):
                continue
            for k, column in index.items():
                cell = row[k].strip() if k < len(row) else ""
                if cell == "":
                    if column in columns[:2]:
                        raise ValueError(f"line {lineno}: column {column} is empty (the row has "
                                         "no point; fill it or remove the row)")
                    continue
                number = cell.replace(",", ".") if delimiter == ";" and "." not in cell \
                    else cell
                try:
                    float(number)
                except ValueError:
                    raise ValueError(f"line {lineno}: column {column} holds {cell!r}, not a number"
                                     " (expected digits with one decimal mark, '.' or, in a "
                                     "';'-separated file, ','; no thousands separator)") from None
                if "," in cell:
                    comma_seen.setdefault(k, lineno)
                elif "." in cell:
                    dotted.setdefault(k, (lineno, cell))
                if k in comma_seen and k in dotted:
                    line, dot = dotted[k]
                    raise ValueError(f"line {line}: column {column} holds {dot!r} while line "
                                     f"{comma_seen[k]} has a decimal comma: is '.' a thousands "
                                     "separator? (write every number with one decimal mark and "
                                     "no thousands separator)")


def csv_coordinate_columns(options: dict[str, str]) -> list[str]:
    """The X, Y (and Z) columns the CSV open ``options`` read as the point geometry."""
    return [options[key] for key in CSV_COORDINATE_NAMES if key in options]


def _without_csv_coordinates(info: dict[str, Any], options: dict[str, str]) -> dict[str, Any]:
    """``info`` (``pyogrio.read_info``) without the CSV's coordinate columns among its fields."""
    drop = set(csv_coordinate_columns(options))
    if not drop:
        return info
    keep = [i for i, f in enumerate(info["fields"]) if f not in drop]
    return info | {"fields": info["fields"][keep], "dtypes": info["dtypes"][keep]}


def read_vector(source: Any, crs: Any = None, columns: list[str] | None = None,
                bbox: tuple[float, float, float, float] | None = None, name: str = "INPUT"):
    """Read a layer (path, ``path|layername=x``, :class:`VectorLayerRef` or GeoDataFrame).

    ``crs`` is assigned when the layer has none (CSV, DXF); it does not reproject.
    """
    import pyogrio

    _pyogrio_errors_here()  # a reference opened on another thread: GDAL's warnings as Python's
    ref = open_layer(source, name)
    if ref.frame is not None:
        frame = ref.frame.copy()
    elif is_parquet(ref.path):
        import geopandas as gpd

        try:
            frame = gpd.read_parquet(ref.path, columns=None if columns is None else
                                     [*columns, ref.info["geometry_name"]], bbox=bbox)
        except Exception as exc:
            raise InputDataError(f"{name}: cannot read {ref}: {str(exc).splitlines()[0]}") from None
    else:
        try:
            frame, _ = _without_m_warning(
                pyogrio.read_dataframe, ref.path, layer=ref.layer, columns=columns, bbox=bbox,
                where=ref.read_where, **ref.open_options)
        except Exception as exc:
            raise InputDataError(f"{name}: cannot read {ref}: {str(exc).splitlines()[0]}") from None
        frame = frame.drop(columns=csv_coordinate_columns(ref.open_options), errors="ignore")
    _check_finite_xy(frame, f"{name} {ref}")
    if not hasattr(frame, "geometry"):  # a table without geometry (CSV without X/Y columns)
        import geopandas as gpd

        frame = gpd.GeoDataFrame(frame, geometry=gpd.GeoSeries([None] * len(frame),
                                                               index=frame.index))
    if ref.geometry_filter is not None:
        keep = frame.geom_type.isin(_GEOMETRY_FAMILIES[ref.geometry_filter]).to_numpy()
        frame = frame[keep].reset_index(drop=True)
    if crs is not None and frame.crs is None:
        frame = frame.set_crs(crs)
    return frame


def layer_names(path: str | Path) -> list[str]:
    """The names of the layers of a vector file, in OGR's order (without importing pandas)."""
    return [str(row[0]) for row in _without_m_warning(_ogr().list_layers, path)[0]]


def every_layer(ref: VectorLayerRef, name: str = "INPUT") -> list[VectorLayerRef]:
    """A reference to each layer of ``ref``'s file, in OGR's order: the file listed once (a
    reference made by :func:`open_layer` per layer listed the whole file again for each, a
    file of 200 layers 200 times)."""
    return [_layer_ref(ref, layer, name) for layer in layer_names(ref.path)]


def _layer_ref(ref: VectorLayerRef, layer: str, name: str) -> VectorLayerRef:
    """A reference to ``layer`` of ``ref``'s file, its information read by OGR (one open)."""
    return VectorLayerRef(ref.path, layer, _layer_info(ref.path, layer, ref.open_options, name,
                                                       f"layer '{layer}' of '{ref.path}'"),
                          dict(ref.open_options), model_space=ref.model_space)


#: the most tables one SQL statement of :func:`layers_geometries` joins (SQLite allows 64),
#: unites (SQLite allows 500 SELECTs in a compound one) and features it reads at once
_SQL_TABLES = 60
_SQL_PARTS = 200
_SQL_FEATURES = 500_000


def layers_geometries(ref: VectorLayerRef, name: str = "INPUT",
                      layers: list[str] | None = None):
    """``(reference, geometries)`` of each layer of ``ref``'s file in OGR's order: the values
    of :func:`read_geometries` of each reference of :func:`every_layer`, with the same checks.

    Each OGR call opens the file again, and GDAL opens a GeoPackage of 200 layers with their
    R-trees in 70 ms (its work grows with the tables): two calls per layer took 34 s for it.
    A GeoPackage's feature tables (without M values) are read here by a few SQL statements
    over many of them, each through one open, and OGR gives the same field definitions, CRS
    and WKB (curves linearised alike) as it gives per layer: the fields by joins of up to
    :data:`_SQL_TABLES` tables without rows, a CRS per spatial reference system, the
    geometries by ``UNION ALL`` of up to :data:`_SQL_PARTS` tables and :data:`_SQL_FEATURES`
    features (a larger table alone). The other layers (tables without geometry, measured
    layers, other formats) and any statement OGR refuses take the per-layer path.
    ``layers``: :func:`layer_names` of the file, when the caller has them."""
    layers = layer_names(ref.path) if layers is None else layers
    plan = _gpkg_plan(ref.path, layers) \
        if ref.info.get("driver") == "GPKG" and not ref.open_options else None
    chunk_of = {} if plan is None else \
        {layer: i for i, chunk in enumerate(plan["chunks"]) for layer in chunk}
    done, geoms_of = None, {}
    for layer in layers:
        if layer in chunk_of and chunk_of[layer] != done:
            done = chunk_of[layer]
            geoms_of = _gpkg_geometries(ref.path, plan["chunks"][done], plan["columns"])
        if layer in geoms_of:
            sub = VectorLayerRef(ref.path, layer, plan["info"][layer], {},
                                 model_space=ref.model_space)
            geoms = geoms_of.pop(layer)
            _check_finite_xy(geoms, f"{name} {sub}")
            yield sub, geoms
        else:
            yield read_geometries(_layer_ref(ref, layer, name), name)


def _quote(identifier: str) -> str:
    """An SQL identifier, quoted."""
    return '"' + identifier.replace('"', '""') + '"'


def _sql_read(path: Path, sql: str, read_geometry: bool = False):
    """``(meta, WKB or None, field arrays)`` of an SQL statement OGR runs on the file (a
    GeoPackage: SQLite's SQL), by ``pyogrio._io.ogr_read`` as :func:`_wkb_geometries` reads."""
    _ogr()
    from pyogrio._io import ogr_read
    from pyogrio.util import get_vsi_path_or_buffer

    meta, _, wkb, data = ogr_read(
        get_vsi_path_or_buffer(str(path)), layer=None, encoding=None, columns=None,
        read_geometry=read_geometry, force_2d=False, skip_features=0, max_features=0,
        where=None, bbox=None, mask=None, fids=None, sql=sql, sql_dialect=None,
        return_fids=False, dataset_kwargs={}, datetime_as_string=False)
    return meta, wkb, data


def _parts(items: list, size: int) -> list[list]:
    return [items[i:i + size] for i in range(0, len(items), size)]


def _gpkg_plan(path: Path, layers: list[str]) -> dict[str, Any] | None:
    """What :func:`layers_geometries` reads of a GeoPackage by SQL: ``info`` (per layer, the
    ``fields``, ``dtypes``, ``crs`` and ``features`` of OGR's information), ``columns`` (its
    geometry column) and ``chunks`` (layers in order, read by one statement); None when
    there are not two such layers or OGR refuses a statement (the per-layer path reads)."""
    try:
        _, _, rows = _sql_read(  # each feature table's columns, with its geometry column
            path, "SELECT g.table_name, g.column_name, g.srs_id, g.m, p.name, p.cid, p.pk, "
            "p.hidden FROM gpkg_geometry_columns g JOIN gpkg_contents c ON c.table_name = "
            "g.table_name, pragma_table_xinfo(g.table_name) p WHERE c.data_type = 'features'")
        known, attributes, key_count, generated = {}, {}, {}, set()
        for t, column, srs, m, n, _, k, h in sorted(zip(*rows, strict=True),
                                                     key=lambda row: (str(row[0]), int(row[5]))):
            t, column, n = str(t), str(column), str(n)
            if int(m) == 0:  # measured: the per-layer path warns
                known[t] = (column, int(srs))
            if n == column:
                continue
            if int(h):  # a generated column: the per-layer path reads the table
                generated.add(t)
            elif int(k):  # the FID column (a GeoPackage's table has one INTEGER PRIMARY KEY)
                key_count[t] = key_count.get(t, 0) + 1
            else:
                attributes.setdefault(t, []).append(n)
        order = [layer for layer in layers
                 if layer in known and key_count.get(layer) == 1 and layer not in generated]
        if len(order) < 2:
            return None
        info = {layer: {"fields": np.array(attributes.get(layer, []), dtype=object)}
                for layer in order}
        for part in _parts(order, _SQL_TABLES):
            selected = [f"t{i}.{_quote(n)} AS {_quote(f'{i} {n}')}" for i, t in enumerate(part)
                        for n in attributes.get(t, [])]
            if not selected:
                continue
            tables_sql = ", ".join(f"{_quote(t)} t{i}" for i, t in enumerate(part))
            meta, _, _ = _sql_read(path, f"SELECT {', '.join(selected)} FROM {tables_sql} "
                                   "LIMIT 0")
            if [str(n) for n in meta["fields"]] != [f"{i} {n}" for i, t in enumerate(part)
                                                    for n in attributes.get(t, [])]:
                return None
            dtypes = iter(meta["dtypes"])
            for t in part:
                info[t]["dtypes"] = np.array([next(dtypes) for _ in attributes.get(t, [])],
                                             dtype=object)
        crs_of = _gpkg_crs_texts(path, {known[layer][1] for layer in order})
        for layer in order:
            column, srs_id = known[layer]
            if srs_id not in crs_of:  # OGR's CRS of the layer: one statement per such system
                crs_of[srs_id] = _sql_read(path, f"SELECT {_quote(column)} FROM "
                                           f"{_quote(layer)} LIMIT 0")[0]["crs"]
            info[layer]["crs"] = crs_of[srs_id]
            info[layer].setdefault("dtypes", np.array([], dtype=object))
        for part in _parts(order, _SQL_PARTS):
            _, _, (index, count) = _sql_read(path, " UNION ALL ".join(
                f"SELECT {i} AS i, COUNT(*) AS n FROM {_quote(t)}" for i, t in enumerate(part)))
            for i, n in zip(index, count, strict=True):
                info[part[int(i)]]["features"] = int(n)
        chunks, total = [], 0
        for layer in order:
            if not chunks or total + info[layer]["features"] > _SQL_FEATURES \
                    or len(chunks[-1]) >= _SQL_PARTS:
                chunks.append([])
                total = 0
            chunks[-1].append(layer)
            total += info[layer]["features"]
        return {"info": info, "columns": {t: known[t][0] for t in order}, "chunks": chunks}
    except Exception:  # noqa: BLE001 - the per-layer path reads the file (and reports)
        return None


def _gpkg_crs_texts(path: Path, srs_ids: set[int]) -> dict[int, str]:
    """``{srs_id: CRS text}`` of the GeoPackage's spatial reference systems, from one read of
    its ``gpkg_spatial_ref_sys`` table (a statement per system opened the file once per CRS):
    ``EPSG:code`` for a system OGR reads as that EPSG code (GDAL takes a system from its EPSG
    code when ``organization`` is EPSG and ``organization_coordsys_id`` equals ``srs_id``, else
    from its definition: only a system whose definition's root authority is that same code,
    so that either way OGR, and pyogrio's ``crs``, says ``EPSG:code``); for a custom one
    (``organization`` NONE, as GDAL writes them) its definition as GDAL reads it
    (``definition_12_063``, the WKT 2 extension's, when it has one, else ``definition``),
    which names the same CRS as OGR's WKT of it (the label :func:`toolbox.io.crs.crs_label`
    gives is the same; only vector:info reads this). Ids 0 and -1, other organizations (GDAL's
    99999 "Undefined SRS" of a layer without CRS), a definition ``undefined`` or one PROJ
    cannot read are left to OGR."""
    wanted = sorted(i for i in srs_ids if i > 0)
    if not wanted:
        return {}
    meta, _, columns = _sql_read(path, "SELECT * FROM gpkg_spatial_ref_sys WHERE srs_id IN "
                                       f"({', '.join(map(str, wanted))})")
    rows = [dict(zip([str(n) for n in meta["fields"]], values, strict=True))
            for values in zip(*columns, strict=True)]
    from toolbox.io.gpkg_summary import epsg_label

    out, custom = {}, {}
    for row in rows:
        definition = str(row.get("definition") or "")
        try:
            srs_id = int(row.get("srs_id"))
        except (TypeError, ValueError):  # OGR says
            continue
        if str(row.get("organization") or "").upper() == "EPSG":  # an EPSG code, or OGR's
            label = epsg_label(srs_id, "EPSG", row.get("organization_coordsys_id"), definition)
            if label is not None:
                out[srs_id] = label
            continue
        if str(row.get("organization") or "NONE").upper() != "NONE":  # GDAL's 99999 (none),
            continue  # another authority's code: OGR reads them
        wkt2 = str(row.get("definition_12_063") or "").strip()
        text = wkt2 if wkt2 and wkt2.lower() != "undefined" else definition.strip()
        if text and text.lower() != "undefined":
            custom[srs_id] = text
    if custom:
        from pyproj import CRS
        from pyproj.exceptions import CRSError

        for srs_id, text in custom.items():
            try:
                CRS.from_user_input(text)
            except CRSError:  # OGR says what it makes of it
                continue
            out[srs_id] = text
    return out


def _gpkg_geometries(path: Path, layers: list[str], columns: dict[str, str]) -> dict:
    """``{layer: geometries}`` of GeoPackage tables by one ``UNION ALL`` (their WKB as OGR
    reads each); empty when OGR refuses it (the per-layer path reads them)."""
    import shapely

    sql = " UNION ALL ".join(f"SELECT {i} AS i, {_quote(columns[t])} FROM {_quote(t)}"
                             for i, t in enumerate(layers))
    try:
        wkb, (index,) = _without_m_warning(_sql_read, path, sql, True)[0][1:]
    except Exception:  # noqa: BLE001
        return {}
    if wkb is None:
        return {}
    index = np.asarray(index)
    order = np.argsort(index, kind="stable")
    bounds = np.searchsorted(index[order], np.arange(len(layers) + 1))
    geoms = shapely.from_wkb(wkb[order])
    return {t: geoms[bounds[i]:bounds[i + 1]] for i, t in enumerate(layers)}


def _layer_info(path: Path, layer: str | None, options: dict[str, str], name: str,
                what: str) -> dict[str, Any]:
    """OGR's information of a layer (CSV coordinate columns left out of its fields);
    :class:`ParameterError` naming ``name`` and ``what`` when OGR cannot read it."""
    try:
        info, measured = _without_m_warning(_ogr().read_info, path, layer=layer, **options)
    except Exception as exc:  # pyogrio raises DataSourceError and friends
        raise ParameterError(name, f"cannot read {what} as a vector layer: "
                             f"{str(exc).splitlines()[0]}") from None
    if measured:
        info["measured_type"] = measured
    return _without_csv_coordinates(info, options)


def read_geometries(source: Any, name: str = "INPUT") -> tuple[VectorLayerRef, np.ndarray]:
    """``(reference, geometries)``: the layer's geometries as an object array of shapely
    geometries (None for a feature without one), the values of ``read_vector(source).geometry``
    with the same checks and errors. A file layer read through OGR is decoded straight from
    GDAL's WKB, without a GeoDataFrame (pandas and geopandas are not imported: about 0.5 s of a
    small run); frames, GeoParquet, CSV and ``geometrytype=`` filters take :func:`read_vector`."""
    ref = open_layer(source, name)
    geoms = None
    if ref.frame is None and not is_parquet(ref.path) and not ref.open_options \
            and ref.geometry_filter is None:
        geoms = _wkb_geometries(ref, name)
    if geoms is None:
        return ref, np.asarray(read_vector(ref, name=name).geometry.values, dtype=object)
    _check_finite_xy(geoms, f"{name} {ref}")
    return ref, geoms


def _wkb_geometries(ref: VectorLayerRef, name: str) -> np.ndarray | None:
    """The shapely geometries of a file layer from ``pyogrio._io.ogr_read`` (the call behind
    ``pyogrio.raw.read``, whose module imports pandas and geopandas); a layer without a
    geometry column (a table: ``layer_styles``) gives one None per feature, as the general
    path does; None for another pyogrio (the general path then reads it)."""
    import shapely

    _ogr()
    from pyogrio._io import ogr_read
    from pyogrio.util import get_vsi_path_or_buffer

    try:
        wkb = _without_m_warning(
            ogr_read, get_vsi_path_or_buffer(str(ref.path)), layer=ref.layer, encoding=None,
            columns=[], read_geometry=True, force_2d=False, skip_features=0, max_features=0,
            where=ref.read_where, bbox=None, mask=None, fids=None, sql=None,
            sql_dialect=None, return_fids=False, dataset_kwargs={},
            datetime_as_string=False)[0][2]
        if wkb is None:  # a table: its features have no geometry (a filtered one: general path)
            if ref.read_where:
                return None
            count = ref.count  # as opening the layer read it; -1: the driver must count
            if count < 0:
                count = _ogr().read_info(str(ref.path), layer=ref.layer,
                                         force_feature_count=True)["features"]
            return np.full(int(count), None, dtype=object)
        return shapely.from_wkb(wkb)
    except TypeError:  # another pyogrio
        return None
    except Exception as exc:
        raise InputDataError(f"{name}: cannot read {ref}: {str(exc).splitlines()[0]}") from None


def no_geometry(geoms) -> np.ndarray:
    """Mask of the null and empty geometries of ``geoms`` (an array of shapely geometries)."""
    import shapely

    geoms = np.asarray(geoms, dtype=object)
    return shapely.is_missing(geoms) | shapely.is_empty(geoms)


def read_area(ref: Any, name: str):
    """The union of a layer's polygons (2D, made valid; null, empty and non-polygonal parts
    dropped): a BOUNDARY, a MASK. :class:`InputDataError` naming ``name`` when none has an
    area. An invalid polygon is repaired as topology:overlay repairs it (GEOS ``make_valid``,
    structure method: overlapping parts of a multi-polygon united, as separate features are,
    not cut out as the default method cuts them), with a warning naming its rows."""
    import shapely

    geoms = read_vector(ref, name=name).geometry.values
    rows = np.flatnonzero(~no_geometry(geoms))
    geoms = shapely.force_2d(geoms[rows])
    invalid = np.flatnonzero(~shapely.is_valid(geoms))
    if len(invalid):
        import logging

        logging.getLogger("toolbox").warning(
            f"{name} {ref}: {len(invalid)} invalid polygon(s) ({feature_rows(rows[invalid])}; "
            f"{shapely.is_valid_reason(geoms[invalid[0]])}): repaired (GEOS make_valid, "
            "overlapping parts united)")
        geoms = geoms.copy()
        geoms[invalid] = shapely.make_valid(geoms[invalid], method="structure",
                                            keep_collapsed=False)
    region = shapely.union_all(geoms) if len(geoms) else shapely.Polygon()
    parts = [g for g in shapely.get_parts(region) if shapely.get_type_id(g) == 3]
    if not parts:
        raise InputDataError(f"{name} {ref} has no polygon with an area")
    return shapely.union_all(parts)


def feature_rows(positions) -> str:
    """``"rows 2, 5, counting from 1"``: the first five features at 0-based ``positions``
    (repeats removed), for messages."""
    rows = np.unique(np.asarray(positions, dtype=np.int64)) + 1
    more = ", ..." if len(rows) > 5 else ""
    return (f"row{'s' if len(rows) > 1 else ''} {', '.join(map(str, rows[:5]))}{more}, "
            "counting from 1")


def _check_finite_xy(frame, what: str) -> None:
    """InputDataError when a geometry has a NaN/inf X or Y (GEOS and every kernel fail on them;
    a NaN Z is left to the Z readers). ``frame``: a GeoDataFrame or an array of geometries."""
    import shapely

    if isinstance(frame, np.ndarray):
        geoms = frame
    elif not hasattr(frame, "geometry") or not len(frame):
        return
    else:
        geoms = frame.geometry.values
    counts = shapely.get_num_coordinates(geoms)
    xy = shapely.get_coordinates(geoms)
    bad = ~np.isfinite(xy).all(axis=1)
    if bad.any():
        owner = np.repeat(np.arange(len(geoms)), counts)[bad]
        rows = np.unique(owner)
        raise InputDataError(f"{what}: {len(rows)} feature(s) have NaN/inf coordinates "
                             f"({feature_rows(rows)})")


def single_points(geoms: Any, name: str) -> np.ndarray:
    """``geoms`` (object array) with one-point MultiPoints (as shapefiles store points) made
    Points; null and empty geometries are left to the caller. A MultiPoint of several points
    is refused naming ``name`` and the 1-based feature rows (which point would be meant?)."""
    import shapely

    geoms = np.asarray(geoms, dtype=object)
    multi = shapely.get_type_id(geoms) == 4
    parts = shapely.get_num_geometries(geoms)
    several = np.flatnonzero(multi & (parts > 1))
    if len(several):
        raise ParameterError(name, f"must hold one point per feature: feature row(s) "
                             f"{', '.join(str(r + 1) for r in several[:5])} hold several points "
                             "(explode them into single points first)")
    out = geoms.copy()
    out[multi] = shapely.get_geometry(geoms[multi], 0)
    return out
