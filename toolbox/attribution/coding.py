"""Entities + code table -> coded layers (thesis S002 §2.2.1, §3.6: one layer per code, Z-Map's
way, or one layer per geometry type with a code field) and the ``unresolved`` layer.

Every entity ends in exactly one place: a coded layer, the ``labels`` layer (texts), or the
``unresolved`` layer with its reason (:data:`REASONS`). Nothing is dropped silently.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely

from toolbox.attribution.resolve import resolve_geometries, z_statistics
from toolbox.io.code_file import CodeTable, code_colour, hex_colour

#: reason -> meaning (the ``reason`` column of ``unresolved``)
REASONS: dict[str, str] = {
    "no_code": "the entity has no code",
    "unknown_code": "the code is not in the code file",
    "no_vertices": "the entity has no coordinates",
    "type_mismatch": "the geometry does not match the type the code file declares",
    "degenerate": "a line with one vertex or zero length, a polygon with fewer than three "
                  "distinct vertices or zero area",
    "unclosed_polygon": "an outline of a polygon code whose ends miss by more than the closure "
                        "tolerance",
    "invalid_polygon": "a closed outline that crosses itself",
}
LAYOUTS = ("code", "type")
TYPE_LAYERS = {"point": "points", "line": "lines", "polygon": "polygons"}
GPKG_TYPES = {"point": "Point", "line": "LineString", "polygon": "Polygon"}
BLOCK = 1 << 16  # entities whose geometries are checked together


def layer_name(code: str) -> str:
    """A GeoPackage-safe layer name for a code (letters, digits and ``_``)."""
    name = re.sub(r"[^0-9A-Za-z_]+", "_", str(code)).strip("_") or "code"
    return name if not name[0].isdigit() else f"c_{name}"


#: the output's own layers and tables (compared case-insensitively, as SQLite names are)
RESERVED_LAYERS = ("unresolved", "labels", "merge", "layer_styles")
RESERVED_PREFIXES = ("gpkg_", "rtree_", "sqlite_")


def unique_layer_name(name: str, taken: set[str]) -> str:
    """``name``, or ``name_2``, ``name_3``... when another layer already has it (codes 'A-1' and
    'A 1' both make 'A_1'; 'ab01' and 'AB01' are one SQLite table) or when it is one of the
    output's own layers or tables; the lower-cased name chosen is added to ``taken``."""
    def free(candidate: str) -> bool:
        low = candidate.lower()
        return low not in taken and low not in RESERVED_LAYERS \
            and not low.startswith(RESERVED_PREFIXES)

    chosen, k = name, 1
    while not free(chosen):
        k += 1
        chosen = f"{name}_{k}"
    taken.add(chosen.lower())
    return chosen


@dataclass
class Attribution:
    """Result of :func:`attribute`: frames by layer name, the kind and codes of each layer."""

    layers: dict[str, Any]
    kinds: dict[str, str]
    codes: dict[str, list[str]]
    unresolved: Any
    labels: Any
    statistics: dict[str, Any]


def attribute(entities, table: CodeTable, colours: dict[str, tuple[int, int, int]] | None = None,
              closure: float = 0.5, layout: str = "code", decimals: int | None = None,
              ) -> Attribution:
    """Give each entity its code's description, type and colour; sort them into layers.

    Parameters
    ----------
    entities : GeoDataFrame
        Entity table (see :mod:`toolbox.attribution.restitution`).
    table : CodeTable
    colours : dict index -> (R, G, B), optional (the colour file).
    closure : float
        Closure tolerance for outlines of polygon codes (CRS units).
    layout : {"code", "type"}
        One layer per code (named after the code; a code without a declared type that holds
        several geometry kinds gets one layer per kind, ``CODE_point``...), or one layer per
        geometry type (``points``, ``lines``, ``polygons``) with a ``code`` field.
    decimals : int, optional
        Coordinates rounded to this many decimals (the parameter file's "numero di cifre
        decimali"); None keeps them.
    """
    import geopandas as gpd
    import pandas as pd

    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    crs = entities.crs
    codes = entities["code"].to_numpy(dtype=object)
    kinds_read = entities["kind"].to_numpy(dtype=object)
    geoms = np.asarray(entities.geometry.values, dtype=object)
    if decimals is not None:
        present = np.array([g is not None for g in geoms])
        geoms[present] = shapely.set_precision(geoms[present], 10.0 ** -decimals,
                                               mode="pointwise")
    n = len(entities)
    names: list[str | None] = []
    for code in codes:
        blank = code is None or (isinstance(code, float) and np.isnan(code)) or not str(
            code).strip()
        names.append(None if blank else str(code).strip())
    is_label = kinds_read == "label"
    known = np.array([c is not None and c in table for c in names], dtype=bool) & ~is_label
    rows = np.flatnonzero(known)
    declared = np.array([table[names[i]].kind for i in rows], dtype=object)
    parts = [resolve_geometries(geoms[rows[a:a + BLOCK]], declared[a:a + BLOCK], closure)
             for a in range(0, max(len(rows), 1), BLOCK)]  # (bounded temporary arrays)
    kind, shape, why, note = (np.concatenate([p[j] for p in parts]) for j in range(4))
    resolved = np.full(n, -1, dtype=np.intp)  # entity -> its row in kind, shape, why, note
    resolved[rows] = np.arange(len(rows))
    per_code: dict[str, Counter] = {}
    groups: dict[tuple[str, str], list[tuple[int, Any, str]]] = {}
    unresolved: list[tuple[int, Any, str, str]] = []
    label_rows: list[int] = []
    closed = 0
    for i in range(n):
        code = names[i]
        counter = per_code.setdefault(code or "", Counter())
        counter["entities"] += 1
        if is_label[i]:
            label_rows.append(i)
            counter["labels"] += 1
            continue
        if code is None:
            reason, detail = "no_code", "no code"
        elif not known[i]:
            reason, detail = "unknown_code", f"code {code!r} is not in the code file"
        else:
            k = resolved[i]
            reason, detail = why[k], note[k]
            if reason is None:
                key = (code, kind[k]) if layout == "code" else ("", kind[k])
                groups.setdefault(key, []).append((i, shape[k], detail))
                closed += detail.startswith("closed")
                counter["resolved"] += 1
                continue
        unresolved.append((i, geoms[i], reason, detail))
        counter[reason] += 1
    # one layer per code: a code of several kinds gets one layer per kind
    kinds_of_code: dict[str, set[str]] = {}
    for code, kind in groups:
        kinds_of_code.setdefault(code, set()).add(kind)
    layers, layer_kinds, layer_codes, taken = {}, {}, {}, set()
    for (code, kind), members in sorted(groups.items()):
        if layout == "code":
            name = unique_layer_name(layer_name(code) + (
                f"_{kind}" if len(kinds_of_code[code]) > 1 else ""), taken)
        else:
            name = TYPE_LAYERS[kind]
        rows = [m[0] for m in members]
        gs = [m[1] for m in members]
        frame = _attributes(entities, rows, gs, table, colours, kind)
        layers[name] = gpd.GeoDataFrame(frame, geometry=gpd.GeoSeries(gs, crs=crs), crs=crs)
        layer_kinds[name] = kind
        layer_codes[name] = sorted(set(frame["code"]))
    unres_rows = [u[0] for u in unresolved]
    unres = pd.DataFrame({
        "entity": entities["entity"].to_numpy()[unres_rows] if unres_rows else np.zeros(0, int),
        "code": [codes[i] for i in unres_rows],
        "reason": [u[2] for u in unresolved], "detail": [u[3] for u in unresolved],
        "kind_read": [kinds_read[i] for i in unres_rows],
        "source": entities["source"].to_numpy(dtype=object)[unres_rows],
        "file": entities["file"].to_numpy(dtype=object)[unres_rows],
        "line": entities["line"].to_numpy()[unres_rows] if unres_rows else np.zeros(0, int)})
    unres = gpd.GeoDataFrame(unres, geometry=gpd.GeoSeries([u[1] for u in unresolved], crs=crs),
                             crs=crs)
    labels = None
    if label_rows:
        lab = entities.iloc[label_rows]
        labels = gpd.GeoDataFrame({
            "entity": lab["entity"].to_numpy(), "code": lab["code"].to_numpy(dtype=object),
            "description": [table.entries[c].description if c in table else None
                            for c in lab["code"]],
            "text": lab["text"].to_numpy(dtype=object),
            "text_height": lab["text_height"].to_numpy(), "rotation": lab["rotation"].to_numpy()},
            geometry=gpd.GeoSeries(list(lab.geometry.values), crs=crs), crs=crs)
    used = {c for c in per_code if c}
    stats = {
        "entities": len(entities),
        "resolved": int(sum(c["resolved"] for c in per_code.values())),
        "unresolved": len(unresolved), "labels": len(label_rows),
        "polygons_closed": int(closed),
        "unresolved_by_reason": dict(Counter(u[2] for u in unresolved)),
        "per_code": {code or "(none)": dict(c) for code, c in sorted(per_code.items())},
        "unknown_codes": sorted(c for c in used if c not in table),
        "unused_codes": [c for c in table.entries if c not in used],
        "layers": {name: len(frame) for name, frame in layers.items()},
    }
    return Attribution(layers, layer_kinds, layer_codes, unres, labels, stats)


def _attributes(entities, rows: list[int], geoms: list[Any], table: CodeTable,
                colours: dict | None, kind: str) -> dict[str, Any]:
    import pandas as pd

    sub = entities.iloc[rows]
    codes = [str(c).strip() for c in sub["code"]]
    rgb, index = zip(*[code_colour(c, table, colours, e) for c, e in
                       zip(codes, sub["colour"], strict=True)], strict=True) if rows else ((), ())
    data: dict[str, Any] = {
        "entity": sub["entity"].to_numpy(),
        "code": codes,
        "description": [table[c].description for c in codes],
        "colour": [hex_colour(c) if c is not None else None for c in rgb],
        "colour_index": list(index),
        "r": pd.array([c[0] if c else None for c in rgb], dtype="Int64"),
        "g": pd.array([c[1] if c else None for c in rgb], dtype="Int64"),
        "b": pd.array([c[2] if c else None for c in rgb], dtype="Int64"),
        "source": sub["source"].to_numpy(dtype=object),
        "vertices": shapely.get_num_coordinates(np.asarray(geoms, dtype=object)),
    }
    arr = np.asarray(geoms, dtype=object)
    if kind == "line":
        data["length"] = np.round(shapely.length(arr), 6)
    if kind == "polygon":
        data["area"] = np.round(shapely.area(arr), 6)
        data["perimeter"] = np.round(shapely.length(arr), 6)
    if kind == "point" and (sub["kind"] == "symbol").any():
        for col in ("block", "rotation", "scale_x", "scale_y"):
            data[col] = sub[col].to_numpy()
    data.update(z_statistics(geoms))
    return data
