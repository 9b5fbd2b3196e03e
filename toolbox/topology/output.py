"""Output tables of the topology kernels: layers (geometries + columns), stable ids, errors."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely

from toolbox.topology.issues import Issue
from toolbox.topology.noding import grid_keys


@dataclass
class Layer:
    """Geometries (map coordinates) and attribute columns of one output layer."""

    geometry: np.ndarray
    columns: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.geometry)


@dataclass
class TopologyOutput:
    """``areas``, ``arcs``, ``nodes``, ``errors`` layers and the per-step ``statistics``.

    ``errors`` holds points and lines together (one row per issue); it is written as two layers,
    ``errors_points`` and ``errors_lines`` (see :func:`split_errors`).
    """

    areas: Layer
    arcs: Layer
    nodes: Layer
    errors: Layer
    statistics: dict[str, Any]


def subset_csr(indptr: np.ndarray, values: np.ndarray, rows: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``rows`` of a CSR pair, as a new CSR pair."""
    counts = np.diff(indptr)[rows]
    new_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    if len(rows) == 0:
        return new_ptr, values[:0]
    # entry k of the new CSR is entry (start of its old row) + (k - start of its new row)
    take = np.repeat(np.asarray(indptr)[rows] - new_ptr[:-1], counts) + np.arange(new_ptr[-1])
    return new_ptr, values[take]


def order_key(geoms: np.ndarray, precision: float) -> np.ndarray:
    """Permutation sorting geometries by (xmin, ymin, xmax, ymax, size) on the grid; exact ties
    (rare) are broken by the normalized WKB, so the order depends on the geometry alone."""
    n = len(geoms)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    b = grid_keys(shapely.bounds(geoms), precision)
    size = np.rint(np.where(shapely.get_dimensions(geoms) == 2, shapely.area(geoms),
                            shapely.length(geoms)) / precision**2).astype(np.int64)
    keys = np.column_stack([b, size])
    order = np.lexsort(keys.T[::-1])
    ks = keys[order]
    same = np.r_[False, (ks[1:] == ks[:-1]).all(axis=1)]
    if same.any():
        group = np.cumsum(~same)
        for g in np.unique(group[same]):
            idx = np.flatnonzero(group == g)
            wkb = shapely.to_wkb(shapely.normalize(geoms[order[idx]]))
            order[idx] = order[idx][sorted(range(len(idx)), key=lambda i: wkb[i])]
    return order.astype(np.int64)


def joined_rows(indptr: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``;``-joined 1-based feature numbers of each CSR row group (text column)."""
    counts = np.diff(indptr)
    out = np.full(len(counts), "", dtype=object)
    single = counts == 1
    out[single] = (rows[indptr[:-1][single]] + 1).astype(str)
    for i in np.flatnonzero(counts > 1):
        out[i] = ";".join(map(str, (rows[indptr[i]:indptr[i + 1]] + 1).tolist()))
    return out


def shift(geoms: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Geometries translated by ``offset`` (x, y): local frame <-> map coordinates."""
    return shapely.transform(np.asarray(geoms, dtype=object), lambda c: c + offset)


def issues_layer(issues: list[Issue], origin: np.ndarray,
                 area_id: Callable[[int], int] | None = None) -> Layer:
    """The ``errors`` layer from issues (kernel coordinates shifted by ``origin``); ``area_id``
    maps a kernel face index to the output area id (default: index + 1, 0 for -1)."""
    area_id = area_id or (lambda f: int(f) + 1 if f >= 0 else 0)
    geoms = np.array([i.geometry for i in issues], dtype=object)
    has = np.array([g is not None for g in geoms], dtype=bool)
    out = np.full(len(issues), None, dtype=object)
    if has.any():
        out[has] = shift(geoms[has], origin)
    cols = {
        "id": np.arange(1, len(issues) + 1),
        "type": np.array([i.type for i in issues], dtype=object),
        "severity": np.array([i.severity for i in issues], dtype=object),
        "detail": np.array([i.detail for i in issues], dtype=object),
        "lines": np.array([";".join(str(r + 1) for r in sorted(set(i.lines))) for i in issues],
                          dtype=object),
        "area_id": np.array([area_id(i.area) for i in issues], dtype=np.int64),
        "label_id": np.array([i.label + 1 for i in issues], dtype=np.int64),
    }
    return Layer(out, cols)


#: the layers an errors table is written as: QGIS draws one geometry kind per layer
ERROR_LAYERS = {"errors_points": "Point", "errors_lines": "LineString"}


def split_errors(errors: Layer) -> dict[str, Layer]:
    """``errors_points`` and ``errors_lines`` from a mixed errors :class:`Layer`.

    Points (and issues without a geometry, kept with a NULL geometry) go to ``errors_points``;
    lines go to ``errors_lines`` (multi-part lines stay multi-part; an area given as a polygon
    would be written as its boundary). Rows keep their ``id``, unique over both layers, and
    their order. Both layers always exist, empty when no issue of their kind was found.
    """
    geoms = np.asarray(errors.geometry, dtype=object)
    has = np.array([g is not None and not g.is_empty for g in geoms], dtype=bool)
    dims = np.zeros(len(geoms), dtype=int)
    if has.any():
        dims[has] = shapely.get_dimensions(np.array(list(geoms[has]), dtype=object))
    polygons = has & (dims == 2)
    if polygons.any():
        geoms = geoms.copy()
        geoms[polygons] = shapely.boundary(np.array(list(geoms[polygons]), dtype=object))
    out = {}
    for name, rows in (("errors_points", ~has | (dims == 0)), ("errors_lines", has & (dims >= 1))):
        index = np.flatnonzero(rows)
        out[name] = Layer(geoms[index], {k: np.asarray(v)[index] for k, v in
                                         errors.columns.items()})
    return out
