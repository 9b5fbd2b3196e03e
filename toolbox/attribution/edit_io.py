"""The I/O side of the editing algorithms (``attribution:square``, ``:align``, ``:sample``):
read a layer into local-frame vertex arrays, write the edited layer, the ``moved_vertices``
layer and the input layer's style (when it had one in ``layer_styles``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from toolbox.errors import InputDataError


@dataclass
class Parts:
    """The rings/lines of a layer: ``coords`` (local frame; (N, 3) for a feature with Z,
    (N, 2) without), ``feature``, ``closed`` and ``exterior`` (the ring starts a part: a
    polygon's shell, or a line) per part, and how to rebuild each feature (``kinds``: point,
    line, polygon or none per feature; ``multi``: the layer is written as multi-geometries)."""

    frame: Any
    coords: list[np.ndarray]
    feature: np.ndarray
    closed: np.ndarray
    exterior: np.ndarray
    ring_of_feature: list[list[int]]
    kinds: list[str]
    origin: np.ndarray
    has_z: bool
    multi: bool


def read_parts(ref: Any, name: str = "INPUT") -> Parts:
    """Read ``ref`` (a VectorLayerRef); explode multi-geometries; lines and rings as arrays
    shifted to a local origin (the rounded centre of the layer's bounds). Each feature keeps
    its own dimension (a 2D feature among 3D ones stays 2D); a NaN/inf Z is refused."""
    from toolbox.io.vector import read_vector

    frame = read_vector(ref, name=name)
    if len(frame) == 0:
        raise InputDataError(f"{name} {ref} has no features")
    geoms = np.asarray(frame.geometry.values, dtype=object)
    has = np.array([g is not None and not g.is_empty for g in geoms])
    b = shapely.total_bounds(geoms[has]) if has.any() else np.zeros(4)
    origin = np.round([(b[0] + b[2]) / 2, (b[1] + b[3]) / 2], -2)
    coords, feature, closed, exterior, rof, kinds = [], [], [], [], [], []
    for f, g in enumerate(geoms):
        rof.append([])
        if g is None or g.is_empty:
            kinds.append("none")
            continue
        z = bool(shapely.has_z(g))
        if z and not np.isfinite(shapely.get_coordinates(g, include_z=True)[:, 2]).all():
            raise InputDataError(f"{name} feature {f + 1} has a NaN/inf Z: give it a Z on "
                                 "every vertex, or none")
        parts = shapely.get_parts(g)
        first = shapely.get_type_id(parts[0])
        kinds.append("polygon" if first == 3 else "line" if first in (1, 2) else "point")
        for part in parts:
            t = shapely.get_type_id(part)
            rings = [part.exterior, *part.interiors] if t == 3 else [part]
            for k, ring in enumerate(rings):
                c = shapely.get_coordinates(ring, include_z=z).astype(float)
                c[:, :2] -= origin
                rof[-1].append(len(coords))
                coords.append(c)
                feature.append(f)
                exterior.append(k == 0)
                closed.append(t in (2, 3) or (t == 1 and len(c) > 2 and
                                              np.array_equal(c[0, :2], c[-1, :2])))
    multi = bool(np.isin(shapely.get_type_id(geoms[has]), (4, 5, 6)).any())
    return Parts(frame, coords, np.array(feature, dtype=np.int64), np.array(closed, bool),
                 np.array(exterior, bool), rof, kinds, origin,
                 bool(shapely.has_z(geoms[has]).any()), multi)


def rebuild(parts: Parts, coords: list[np.ndarray]) -> list[Any]:
    """Feature geometries from edited part arrays (same structure as read: every part of a
    multi-geometry a part again, each polygon with its own holes). A feature read without a
    geometry (null or empty) is returned as read; with ``parts.multi`` every feature is a
    multi-geometry."""
    geoms = []
    for f, rings in enumerate(parts.ring_of_feature):
        kind = parts.kinds[f]
        if not rings:
            geoms.append(parts.frame.geometry.values[f])
            continue
        groups: list[list[np.ndarray]] = []
        for r in rings:
            c = coords[r].copy()
            c[:, :2] += parts.origin
            if parts.exterior[r]:
                groups.append([])
            groups[-1].append(c)
        if kind == "polygon":
            pieces = [shapely.Polygon(g[0], g[1:]) for g in groups]
            multi = shapely.MultiPolygon
        elif kind == "line":
            pieces = [shapely.LineString(g[0]) for g in groups]
            multi = shapely.MultiLineString
        else:
            pieces = [shapely.Point(g[0][0]) for g in groups]
            multi = shapely.MultiPoint
        geoms.append(multi(pieces) if parts.multi or len(pieces) > 1 else pieces[0])
    return geoms


#: the ``moved_vertices`` fields, in order
MOVED_FIELDS = ("feature", "vertex", "change", "dx", "dy", "displacement")
#: rows written at a time into a GeoPackage's ``moved_vertices`` layer
MOVED_BLOCK = 65536


class MovedVertices:
    """The ``moved_vertices`` rows as numeric columns, added a feature at a time: about 50
    bytes a row (a densification of 10 million vertices is 10 million rows; one dict each took
    about 1 kB). ``feature`` and ``change`` are one text per :meth:`add` (or one per row); the
    numbers broadcast (``dx=0.0`` for every added vertex). Coordinates are in the local frame."""

    def __init__(self) -> None:
        self._chunks: list[tuple[Any, ...]] = []
        self.count = 0

    def add(self, feature: Any, vertex: Any, change: Any, x: Any, y: Any, dx: Any = 0.0,
            dy: Any = 0.0, displacement: Any = 0.0) -> None:
        """Rows for the 1-based ``vertex`` numbers (an array) of one feature."""
        vertex = np.asarray(vertex, dtype=np.int64).ravel()
        if not len(vertex):
            return
        numbers = [np.asarray(v, dtype=np.float64) for v in (x, y, dx, dy, displacement)]
        self._chunks.append((feature, vertex, change, *numbers))
        self.count += len(vertex)

    @classmethod
    def from_rows(cls, rows: list[dict[str, Any]]) -> MovedVertices:
        """From dicts with the keys of :data:`MOVED_FIELDS` and ``x``, ``y``."""
        moved = cls()
        if rows:
            def column(key: str, dtype: Any) -> np.ndarray:
                return np.array([r[key] for r in rows], dtype=dtype)

            moved.add(column("feature", object), column("vertex", np.int64),
                      column("change", object), column("x", float), column("y", float),
                      column("dx", float), column("dy", float), column("displacement", float))
        return moved

    def blocks(self, size: int):
        """Yield ``(x, y, {field: array})`` of at most ``size`` rows each, in order (one empty
        block when there is no row)."""
        pending: list[tuple[np.ndarray, ...]] = []
        held = 0
        for feature, vertex, change, *numbers in self._chunks:
            n = len(vertex)
            start = 0
            while start < n:
                stop = min(n, start + size - held)
                part = slice(start, stop)
                m = stop - start
                pending.append((np.broadcast_to(np.asarray(feature, dtype=object), (n,))[part],
                                vertex[part],
                                np.broadcast_to(np.asarray(change, dtype=object), (n,))[part],
                                *(np.broadcast_to(v, (n,))[part] for v in numbers)))
                held += m
                start = stop
                if held == size:
                    yield self._joined(pending)
                    pending, held = [], 0
        if pending or not self.count:
            yield self._joined(pending)

    @staticmethod
    def _joined(pending: list[tuple[np.ndarray, ...]]):
        kinds = (object, np.int64, object, *(np.float64,) * 5)
        cols = [np.concatenate([p[k] for p in pending]).astype(kind, copy=False) if pending
                else np.zeros(0, dtype=kind) for k, kind in enumerate(kinds)]
        feature, vertex, change, x, y, dx, dy, displacement = cols
        return x, y, dict(zip(MOVED_FIELDS, (feature, vertex, change, dx, dy, displacement),
                              strict=True))


def write_moved(path: Path, moved: MovedVertices, origin: np.ndarray, crs: Any) -> None:
    """The ``moved_vertices`` layer in ``path`` (a GeoPackage: beside the others): one point
    per changed vertex, at its new position (removed vertices at their old one), with feature,
    vertex, change, dx, dy, displacement. A GeoPackage is written :data:`MOVED_BLOCK` rows at a
    time (only that many points and WKB texts exist at once)."""
    from toolbox.io.vector import vector_driver
    from toolbox.io.vector_write import write_wkb_layer

    size = MOVED_BLOCK if vector_driver(path) == "GPKG" else max(moved.count, 1)
    for k, (x, y, fields) in enumerate(moved.blocks(size)):
        wkb = shapely.to_wkb(shapely.points(x + origin[0], y + origin[1]))
        write_wkb_layer(path, "moved_vertices", wkb, fields, "Point", crs, append=k > 0)


def layer_name_of(ref: Any) -> str:
    """The input layer's name (its layer name, else the file stem)."""
    if getattr(ref, "layer", None):
        return str(ref.layer)
    name = (getattr(ref, "info", None) or {}).get("layer_name")
    if name:
        return str(name)
    path = getattr(ref, "path", None)
    if path is not None:
        import pyogrio

        layers = pyogrio.list_layers(path)
        return str(layers[0][0]) if len(layers) == 1 else Path(path).stem
    return "features"


def write_edited(path: Path, ref: Any, parts: Parts, coords: list[np.ndarray],
                 moved_rows: list[dict[str, Any]] | MovedVertices,
                 extra_columns: dict[str, Any] | None = None) -> str:
    """Write the edited layer (input attributes kept, named as the input layer) and
    ``moved_vertices`` (rows as :class:`MovedVertices` or dicts, see
    :meth:`MovedVertices.from_rows`); copy the input layer's default style. Returns the layer
    name."""
    import geopandas as gpd

    from toolbox.attribution.output import store_style
    from toolbox.io.vector_write import layer_paths, write_layers
    from toolbox.styles.gpkg import read_layer_styles
    from toolbox.styles.model import CodeStyle, LayerStyle
    from toolbox.styles.qml import qml_document
    from toolbox.styles.sld import sld_document

    name = layer_name_of(ref)
    if name == "moved_vertices":
        name = "edited"
    frame = parts.frame.drop(columns=parts.frame.geometry.name).copy()
    for column, values in (extra_columns or {}).items():
        frame[column] = values
    crs = parts.frame.crs
    geoms = rebuild(parts, coords)
    edited = gpd.GeoDataFrame(frame, geometry=gpd.GeoSeries(geoms, crs=crs), crs=crs)
    kinds = {k for k in parts.kinds if k != "none"}
    types = {}
    if len(kinds) == 1:
        base = {"polygon": "Polygon", "line": "LineString", "point": "Point"}[kinds.pop()]
        types[name] = ("Multi" if parts.multi else "") + base + (" Z" if parts.has_z else "")
    layers = [name, "moved_vertices"]
    write_layers(path, {name: edited}, crs=crs, geometry_types=types)
    moved = moved_rows if isinstance(moved_rows, MovedVertices) else \
        MovedVertices.from_rows(moved_rows)
    write_moved(layer_paths(path, layers)["moved_vertices"], moved, parts.origin, crs)
    source = getattr(ref, "path", None)
    if source is not None and Path(source).suffix.lower() == ".gpkg":
        for row in read_layer_styles(source):
            if row["f_table_name"] == getattr(ref, "layer", None) and row["useAsDefault"]:
                store_style(path, layers, name, row["styleQML"], row["styleSLD"],
                            row["styleName"], row["description"] or "",
                            fields=list(frame.columns))
    style = LayerStyle("moved_vertices", "point", [CodeStyle(
        "moved", "point", (255, 0, 255), 0.2, (255, 0, 255, 255), "moved vertex", 1.5)])
    store_style(path, layers, "moved_vertices", qml_document(style), sld_document(style))
    return name
