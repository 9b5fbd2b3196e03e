"""Writing an attribution: coded layers, ``labels`` and ``unresolved`` into one GeoPackage, each
with its QGIS (QML) and SLD style embedded as the default in ``layer_styles``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import shapely

from toolbox.attribution.coding import GPKG_TYPES, Attribution
from toolbox.io.code_file import CodeTable
from toolbox.styles.files import write_layer_style_files, write_style_files
from toolbox.styles.model import CodeStyle, LayerStyle, layer_style
from toolbox.styles.qml import qml_document
from toolbox.styles.sld import sld_document

UNRESOLVED_STYLE = CodeStyle("unresolved", "point", (228, 26, 28), 0.3, (228, 26, 28, 255),
                             "unresolved entity", size=3.0)
LABEL_STYLE = CodeStyle("labels", "point", (0, 0, 0), 0.1, (0, 0, 0, 255), "text", size=0.8)
MERGE_STYLE = LayerStyle("merge", "point", [CodeStyle("merge", "point", (255, 127, 0), 0.3,
                                                      (255, 127, 0, 255), "merge event", 2.5)],
                         label_field="kind")


def unresolved_points(frame):
    """The ``unresolved`` layer as points (the first vertex: where the operator should look),
    the entity as read kept as WKT (``geometry_wkt``)."""
    import geopandas as gpd

    geoms = np.asarray(frame.geometry.values, dtype=object)
    points = np.full(len(geoms), None, dtype=object)
    wkt = np.full(len(geoms), None, dtype=object)
    has = np.array([g is not None and not g.is_empty for g in geoms], dtype=bool)
    if has.any():
        points[has] = shapely.get_point(shapely.get_exterior_ring(geoms[has]), 0)
        plain = np.flatnonzero(has & (shapely.get_type_id(geoms) != 3))
        points[plain] = [shapely.Point(shapely.get_coordinates(g, include_z=shapely.has_z(g))[0])
                         for g in geoms[plain]]
        wkt[has] = shapely.to_wkt(geoms[has], rounding_precision=-1)
    out = frame.drop(columns=frame.geometry.name).copy()
    if not len(out):  # an empty layer keeps text columns as text
        out = out.astype({c: object for c in out.columns if c not in ("entity", "line")})
    out["geometry_wkt"] = wkt
    return gpd.GeoDataFrame(out, geometry=gpd.GeoSeries(list(points), crs=frame.crs),
                            crs=frame.crs)


def _gpkg_type(kind: str, frame) -> str:
    has_z = bool(len(frame)) and bool(frame.geometry.has_z.any())
    return GPKG_TYPES[kind] + (" Z" if has_z else "")


def attribution_styles(result: Attribution, table: CodeTable,
                       colours: dict | None) -> dict[str, LayerStyle]:
    """The style of every layer :func:`write_attribution` writes."""
    styles = {name: layer_style(name, result.kinds[name], result.codes[name], table, colours)
              for name in result.layers}
    styles["unresolved"] = LayerStyle("unresolved", "point", [UNRESOLVED_STYLE],
                                      label_field="reason")
    if result.labels is not None:
        styles["labels"] = LayerStyle("labels", "point", [LABEL_STYLE], label_field="text")
    return styles


def write_attribution(path: str | Path, result: Attribution, table: CodeTable,
                      colours: dict | None, crs: Any = None, sidecar: bool = False,
                      extra: dict[str, tuple[Any, LayerStyle]] | None = None
                      ) -> dict[str, LayerStyle]:
    """Write every layer of ``result`` (and ``extra``: name -> (point frame, style)) with its
    style embedded as the default; with ``sidecar`` also ``<path>.<layer>.qml`` / ``.sld``.
    Returns the styles by layer name."""
    path = Path(path)
    from toolbox.io.vector_write import write_layers

    frames: dict[str, Any] = dict(result.layers)
    types = {name: _gpkg_type(result.kinds[name], frame) for name, frame in frames.items()}
    unresolved = unresolved_points(result.unresolved)
    frames["unresolved"] = unresolved
    types["unresolved"] = "Point Z"  # restitution is 3D: the same type when the layer is empty
    if result.labels is not None:
        frames["labels"] = result.labels
        types["labels"] = _gpkg_type("point", result.labels)
    styles = attribution_styles(result, table, colours)
    for name, (frame, style) in (extra or {}).items():
        frames[name], styles[name] = frame, style
        types[name] = "Point Z" if len(frame) and bool(frame.geometry.has_z.any()) else "Point"
    write_layers(path, frames, crs=crs, geometry_types=types)
    for name, style in styles.items():
        qml, sld = qml_document(style), sld_document(style)
        frame = frames.get(name)
        fields = None if frame is None else [c for c in frame.columns
                                             if c != frame.geometry.name]
        embedded = store_style(path, list(frames), name, qml, sld, description=(
            f"from the code file {table.path.name if table.path else ''}"), fields=fields)
        if sidecar and embedded:  # named after the GeoPackage: the runner commits them with it
            write_style_files(path.with_name(f"{path.name}.{name}"), qml, sld)
    return styles


def store_style(path: Path, layers: list[str], layer: str, qml: str, sld: str | None,
                name: str | None = None, description: str = "",
                fields: list[str] | None = None) -> bool:
    """Give ``layer`` of the output ``path`` (written with ``layers``, in order) its default
    style: in the GeoPackage's ``layer_styles`` (True), or for a one-layer format as
    ``<layer file stem>.qml`` / ``.sld`` beside the layer's file, which QGIS loads with it.
    ``fields``: the layer's fields in the order written; a Shapefile's style then names them
    as the file holds them (``description`` -> ``descriptio``)."""
    from toolbox.io.vector import vector_driver
    from toolbox.io.vector_write import layer_paths
    from toolbox.styles.gpkg import write_layer_styles

    if vector_driver(path) == "GPKG":
        write_layer_styles(path, layer, qml, sld, True, name, description)
        return True
    write_layer_style_files(layer_paths(path, layers)[layer], qml, sld, fields=fields)
    return False
