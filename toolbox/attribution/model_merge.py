"""Model merge ("fusione", thesis S002 §2.2.3): restitution plotted model by model merged into
one set covering the sheet.

1. *Duplicates*: an entity of a later model with the same code as an entity of an earlier model
   and within the planimetric reattach tolerance of it everywhere (Hausdorff distance, XY) and
   within the altimetric tolerance in height (largest Z difference of the two ends) is the
   same object plotted twice in the models' overlap: it is removed (the earlier model's copy
   is kept: the order of the input files decides) and reported (:func:`duplicates_warning`).
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


def _dz(a: np.ndarray, b: np.ndarray) -> float:
    d = a[:, 2] - b[:, 2]
    d = d[np.isfinite(d)]
    return float(np.abs(d).max()) if len(d) else 0.0


def merge_snap_warning(models: list[Any], xy_tolerance: float) -> str | None:
    """The topology's warning (:func:`toolbox.topology.tolerances.large_snap_warning`) when
    SNAP_TOLERANCE exceeds a quarter of the median extent of the models' lines and areas:
    line ends and duplicates are then matched across features, not near misses."""
    from toolbox.topology.tolerances import large_snap_warning

    geoms = np.concatenate([np.asarray(m.geometry.values, dtype=object) for m in models])
    geoms = geoms[~shapely.is_missing(geoms)]
    lines = geoms[np.isin(shapely.get_type_id(geoms), (1, 2, 3, 5, 6))]
    return large_snap_warning(xy_tolerance, lines)


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
    joins, height_refused = _join_lines(geoms, alive, codes, model, xy_tolerance, z_tolerance,
                                        ref, events)
    out = merged.copy()
    out = out.set_geometry(gpd.GeoSeries(list(geoms), crs=merged.crs))
    out = out[alive].reset_index(drop=True)
    stats = {"models": len(models), "entities_in": len(merged), "duplicates_removed": removed,
             "joins": joins, "joins_refused_height": height_refused, "entities_out": len(out)}
    return MergeResult(out, events, stats)


def duplicates_warning(statistics: dict[str, Any]) -> str | None:
    """The warning naming how many duplicates :func:`merge_models` removed and which copy it
    kept (None when none): of two copies, the entity of the model given first (earlier in
    INPUT) is kept, whatever their precision."""
    n = int(statistics.get("duplicates_removed", 0))
    if not n:
        return None
    return (f"merge: {n} duplicate {'entity' if n == 1 else 'entities'} removed (the same code "
            "within SNAP_TOLERANCE in plan and HEIGHT_SNAP_TOLERANCE in height of an entity of "
            "another model): each time the copy of the model given first in INPUT was kept, the "
            "later one dropped; the 'merge' layer marks them (duplicate_removed)")


def _is_closed(coords: np.ndarray) -> bool:
    """First and last vertex the same point in plan (to 1e-9 CRS units: map coordinates are
    millions of metres, so no relative tolerance)."""
    return bool(np.all(np.abs(coords[0, :2] - coords[-1, :2]) <= 1e-9))


def _join_lines(geoms: np.ndarray, alive: np.ndarray, codes: np.ndarray, model: np.ndarray,
                xy_tolerance: float, z_tolerance: float, ref, events: list[dict[str, Any]]
                ) -> tuple[int, int]:
    """Join open lines of the same code from different models whose ends meet (in place on
    ``geoms`` and ``alive``); returns (joins, refused in height).

    Greedy, closest ends first, repeated until no ends meet: a joined line keeps the first
    line's number and model, and its ends are the far ends of the two (their coordinates do not
    change), so the candidate end pairs are found once (one STRtree query) and taken from a heap
    by gap; a pair whose lines were in the same model is set aside and looked at again when one
    of its ends passes to a line of another model by a join. Ends meeting in plan but not in
    height are reported once per pair of ends.
    """
    import heapq

    lines = np.array([i for i in np.flatnonzero(alive) if geoms[i] is not None
                      and shapely.get_type_id(geoms[i]) == 1
                      and len(c := shapely.get_coordinates(geoms[i])) >= 2
                      and not _is_closed(c)], dtype=np.int64)
    if len(lines) < 2:
        return 0, 0
    ends = np.array([_ends(geoms[i]) for i in lines])  # (L, 2, 3): end 2k first, 2k+1 last
    xyz = ends.reshape(-1, 3)
    pts = shapely.points(xyz[:, :2])
    p, q = shapely.STRtree(pts).query(pts, predicate="dwithin", distance=xy_tolerance)
    keep = (p < q) & (p // 2 != q // 2)
    p, q = p[keep], q[keep]
    keep = codes[lines[p // 2]] == codes[lines[q // 2]]
    p, q = p[keep], q[keep]
    gap = np.hypot(xyz[p, 0] - xyz[q, 0], xyz[p, 1] - xyz[q, 1])
    zp, zq = xyz[p, 2], xyz[q, 2]
    dz = np.where(np.isfinite(zp) & np.isfinite(zq), np.abs(zp - zq), 0.0)
    high = dz > z_tolerance
    refused: set[tuple[int, int]] = set()
    for u, v, g, d in zip(p[high], q[high], gap[high], dz[high], strict=True):
        i, j = lines[u // 2], lines[v // 2]
        if model[i] == model[j] or (i, j) in refused:
            continue
        refused.add((i, j))
        events.append({"kind": "join_refused", "code": codes[i],
                       "geometry": shapely.Point(*xyz[u]), "detail":
                       f"{ref(i)} and {ref(j)} meet in plan ({g:.3f}) but differ by {d:.3f} "
                       f"in height (tolerance {z_tolerance:g})"})
    p, q, gap = p[~high], q[~high], gap[~high]
    owner = np.repeat(lines, 2)  # the line each end belongs to now
    free = np.ones(len(owner), dtype=bool)  # still an end (not a joined vertex)
    first = {int(i): 2 * k for k, i in enumerate(lines)}  # line -> its first and last end
    last = {int(i): 2 * k + 1 for k, i in enumerate(lines)}
    heap = [(float(g), int(u), int(v)) for g, u, v in zip(gap, p, q, strict=True)]
    heapq.heapify(heap)
    parked: dict[int, list[tuple[float, int, int]]] = {}
    joins = 0
    while heap:
        g, u, v = heapq.heappop(heap)
        if not (free[u] and free[v]):
            continue  # an end already joined: never an end again
        i, j = int(owner[u]), int(owner[v])
        if i == j:
            continue  # both ends of one line: they stay on one line
        if model[i] == model[j]:
            for e in (u, v):  # looked at again if an end passes to another model's line
                parked.setdefault(e, []).append((g, u, v))
            continue
        if i > j:  # the joined line keeps the first line's number (the earlier model)
            i, j, u, v = j, i, v, u
        ci = shapely.get_coordinates(geoms[i], include_z=True)
        cj = shapely.get_coordinates(geoms[j], include_z=True)
        if first[i] == u:
            ci = ci[::-1]  # i now ends at the meeting end
        if last[j] == v:
            cj = cj[::-1]  # j now starts at it
        far_i = last[i] if first[i] == u else first[i]
        far_j = last[j] if first[j] == v else first[j]
        meet = (ci[-1] + cj[0]) / 2
        joined = np.vstack([ci[:-1], meet, cj[1:]])
        geoms[i] = shapely.LineString(joined)
        alive[j] = False
        free[u] = free[v] = False
        owner[far_j] = i
        first[i], last[i] = far_i, far_j
        joins += 1
        events.append({"kind": "joined", "code": codes[i], "geometry": shapely.Point(*meet),
                       "detail": f"{ref(j)} joined to {ref(i)} (gap {g:.3f})"})
        if _is_closed(joined):  # a closed line is no longer open: its ends join nothing
            free[far_i] = free[far_j] = False
        else:  # far_j now belongs to a line of another model
            for item in parked.pop(far_j, []):
                heapq.heappush(heap, item)
    return joins, len(refused)


def events_frame(events: list[dict[str, Any]], crs: Any):
    """The ``merge`` report layer (points)."""
    import geopandas as gpd

    return gpd.GeoDataFrame({"kind": [e["kind"] for e in events],
                             "code": [e["code"] for e in events],
                             "detail": [e["detail"] for e in events]},
                            geometry=gpd.GeoSeries([e["geometry"] for e in events], crs=crs),
                            crs=crs)
