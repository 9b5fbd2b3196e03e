"""Model merge ("fusione", thesis S002 §2.2.3): restitution plotted model by model merged into
one set covering the sheet.

1. *Duplicates*: an entity of a later model with the same code as an entity of an earlier model
   and within the planimetric reattach tolerance of it everywhere (Hausdorff distance, XY) and
   within the altimetric tolerance in height (largest Z difference of the two ends) is the
   same object plotted twice in the models' overlap: it is removed and reported.
2. *Joins*: an open line ending within the planimetric tolerance (and the altimetric one in Z)
   of the end of an open line of the same code **from another model** is the same line crossing
   the model edge: the two are joined into one (the meeting vertex is the mean of the two ends).
   Repeated until no more ends meet, so a road crossing three models becomes one line. Ends that
   meet in plan but differ in height beyond the tolerance are reported, not joined.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely


@dataclass
class MergeResult:
    """The merged entity table and what was done (``events``: kind, model(s), entity numbers,
    location, detail)."""

    entities: Any
    events: list[dict[str, Any]] = field(default_factory=list)
    statistics: dict[str, int] = field(default_factory=dict)


def _ends(geom) -> np.ndarray:
    c = shapely.get_coordinates(geom, include_z=True)
    return c[[0, -1]]


def _is_open_line(geom) -> bool:
    if geom is None or shapely.get_type_id(geom) != 1:
        return False
    c = shapely.get_coordinates(geom)
    return len(c) >= 2 and not np.allclose(c[0], c[-1])


def _dz(a: np.ndarray, b: np.ndarray) -> float:
    d = a[:, 2] - b[:, 2]
    d = d[np.isfinite(d)]
    return float(np.abs(d).max()) if len(d) else 0.0


def merge_models(models: list[Any], xy_tolerance: float, z_tolerance: float) -> MergeResult:
    """Merge entity tables of adjacent models (list order = model order; a ``model`` column
    1..M is added; ``entity`` keeps its number within its model)."""
    import geopandas as gpd
    import pandas as pd

    frames = []
    for k, frame in enumerate(models, start=1):
        frame = frame.copy()
        frame["model"] = k
        frames.append(frame)
    merged = gpd.GeoDataFrame(pd.concat(frames, ignore_index=True), crs=frames[0].crs)
    geoms = np.asarray(merged.geometry.values, dtype=object).copy()
    codes = merged["code"].astype(object).to_numpy()
    model = merged["model"].to_numpy()
    alive = np.array([g is not None for g in geoms], dtype=bool)
    events: list[dict[str, Any]] = []

    def ref(i: int) -> str:
        return f"model {model[i]} entity {merged['entity'].iloc[i]}"

    # 1. duplicates across models
    idx = np.flatnonzero(alive)
    tree = shapely.STRtree(geoms[idx])
    a, b = tree.query(geoms[idx], predicate="dwithin", distance=xy_tolerance)
    removed = 0
    for i, j in zip(idx[a], idx[b], strict=True):
        if i >= j or model[i] == model[j] or codes[i] != codes[j] or not (alive[i] and alive[j]):
            continue
        gi, gj = geoms[i], geoms[j]
        if shapely.get_type_id(gi) != shapely.get_type_id(gj):
            continue
        if shapely.hausdorff_distance(shapely.force_2d(gi), shapely.force_2d(gj)) > xy_tolerance:
            continue
        ei, ej = _ends(gi), _ends(gj)
        if _dz(ei, ej) > z_tolerance and _dz(ei, ej[::-1]) > z_tolerance:
            continue
        alive[j] = False
        removed += 1
        events.append({"kind": "duplicate_removed", "geometry": shapely.get_point(gj, 0)
                       if shapely.get_type_id(gj) != 0 else gj, "code": codes[j],
                       "detail": f"{ref(j)} duplicates {ref(i)}"})
    # 2. joins across the model edge
    joins = height_refused = 0
    while True:
        lines = [i for i in np.flatnonzero(alive) if _is_open_line(geoms[i])]
        if len(lines) < 2:
            break
        ends = np.array([_ends(geoms[i]) for i in lines])  # (L, 2, 3)
        pts = shapely.points(ends[:, :, :2].reshape(-1, 2))
        p, q = shapely.STRtree(pts).query(pts, predicate="dwithin", distance=xy_tolerance)
        best = None
        for u, v in zip(p, q, strict=True):
            i, j = lines[u // 2], lines[v // 2]
            if u >= v or i == j or model[i] == model[j] or codes[i] != codes[j]:
                continue
            eu, ev = ends[u // 2, u % 2], ends[v // 2, v % 2]
            gap = float(np.hypot(*(eu[:2] - ev[:2])))
            dz = abs(eu[2] - ev[2]) if np.isfinite(eu[2]) and np.isfinite(ev[2]) else 0.0
            if dz > z_tolerance:
                key = ("refused", i, j)
                if not any(e.get("key") == key for e in events):
                    height_refused += 1
                    events.append({"kind": "join_refused", "key": key, "code": codes[i],
                                   "geometry": shapely.Point(*eu), "detail":
                                   f"{ref(i)} and {ref(j)} meet in plan ({gap:.3f}) but differ "
                                   f"by {dz:.3f} in height (tolerance {z_tolerance:g})"})
                continue
            if best is None or gap < best[0]:
                best = (gap, u, v)
        if best is None:
            break
        gap, u, v = best
        i, j = lines[u // 2], lines[v // 2]
        ci = shapely.get_coordinates(geoms[i], include_z=True)
        cj = shapely.get_coordinates(geoms[j], include_z=True)
        if u % 2 == 0:
            ci = ci[::-1]  # i now ends at the meeting end
        if v % 2 == 1:
            cj = cj[::-1]  # j now starts at it
        meet = (ci[-1] + cj[0]) / 2
        joined = np.vstack([ci[:-1], meet, cj[1:]])
        geoms[i] = shapely.LineString(joined)
        alive[j] = False
        joins += 1
        events.append({"kind": "joined", "code": codes[i], "geometry": shapely.Point(*meet),
                       "detail": f"{ref(j)} joined to {ref(i)} (gap {gap:.3f})"})
    for e in events:
        e.pop("key", None)
    out = merged.copy()
    out = out.set_geometry(gpd.GeoSeries(list(geoms), crs=merged.crs))
    out = out[alive].reset_index(drop=True)
    stats = {"models": len(models), "entities_in": len(merged), "duplicates_removed": removed,
             "joins": joins, "joins_refused_height": height_refused, "entities_out": len(out)}
    return MergeResult(out, events, stats)


def events_frame(events: list[dict[str, Any]], crs: Any):
    """The ``merge`` report layer (points)."""
    import geopandas as gpd

    return gpd.GeoDataFrame({"kind": [e["kind"] for e in events],
                             "code": [e["code"] for e in events],
                             "detail": [e["detail"] for e in events]},
                            geometry=gpd.GeoSeries([e["geometry"] for e in events], crs=crs),
                            crs=crs)
