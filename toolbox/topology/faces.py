"""Faces of the cleaned network: polygonize, the area on each side of a line, slivers.

Left and right are found topologically, not by probing points beside the line (which fails on
thin areas): GEOS polygonize builds the faces from the edges' own coordinates, so each directed
segment of a face ring, with the ring oriented to keep the face on its left (exterior
counter-clockwise, holes clockwise), matches exactly one edge's first segment, forward (the face is
on the edge's left) or backward (on its right).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import shapely

from toolbox.topology.noding import grid_keys, points_along
from toolbox.topology.snap import line_ends

OUTSIDE = -1


def polygonize_edges(edges: np.ndarray) -> np.ndarray:
    """Faces (Polygons) bounded by ``edges`` (noded, meeting only at their ends), GEOS order.

    Each face is in a canonical form (GEOS ``normalize``: fixed start vertex and ring order), with
    its exterior counter-clockwise and holes clockwise (the OGC/GeoJSON convention), so equal
    areas are equal coordinate by coordinate whatever the order of the edges.
    """
    if len(edges) == 0:
        return np.zeros(0, dtype=object)
    faces = shapely.get_parts(shapely.polygonize(edges))
    faces = faces[shapely.area(faces) > 0]
    return shapely.orient_polygons(shapely.normalize(faces), exterior_cw=False)


def face_sides(lines: np.ndarray, faces: np.ndarray, precision: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Face index on the left and on the right of each line (``OUTSIDE`` = -1 where none).

    ``lines`` must be made of the faces' edges (same coordinates). Lines that bound no face (a
    dangle, a bridge between two rings) get the face that contains them on both sides.
    """
    n = len(lines)
    left = np.full(n, OUTSIDE, dtype=np.int64)
    right = np.full(n, OUTSIDE, dtype=np.int64)
    if n == 0:
        return left, right
    if len(faces):
        oriented = shapely.orient_polygons(faces, exterior_cw=False)
        rings, ring_face = shapely.get_rings(oriented, return_index=True)
        rc, ring_of = shapely.get_coordinates(rings, return_index=True)
        keys = grid_keys(rc, precision)
        same_ring = ring_of[:-1] == ring_of[1:]
        seg = pd.DataFrame({"x0": keys[:-1, 0][same_ring], "y0": keys[:-1, 1][same_ring],
                            "x1": keys[1:, 0][same_ring], "y1": keys[1:, 1][same_ring],
                            "face": ring_face[ring_of[:-1][same_ring]]})
        coords, _, first, _ = line_ends(lines)
        a = grid_keys(coords[first], precision)
        b = grid_keys(coords[first + 1], precision)
        fwd = pd.DataFrame({"x0": a[:, 0], "y0": a[:, 1], "x1": b[:, 0], "y1": b[:, 1],
                            "line": np.arange(n)})
        bwd = pd.DataFrame({"x0": b[:, 0], "y0": b[:, 1], "x1": a[:, 0], "y1": a[:, 1],
                            "line": np.arange(n)})
        on = ["x0", "y0", "x1", "y1"]
        hit = fwd.merge(seg, on=on, how="inner")
        left[hit["line"].to_numpy()] = hit["face"].to_numpy()
        hit = bwd.merge(seg, on=on, how="inner")
        right[hit["line"].to_numpy()] = hit["face"].to_numpy()
    inner = (left == OUTSIDE) & (right == OUTSIDE)
    if inner.any() and len(faces):
        containing = containing_face(lines[inner], faces)
        left[inner] = containing
        right[inner] = containing
    return left, right


def containing_face(lines: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Face whose interior holds each line's midpoint (-1 when none)."""
    out = np.full(len(lines), OUTSIDE, dtype=np.int64)
    if len(lines) == 0 or len(faces) == 0:
        return out
    mids = shapely.points(points_along(lines, 0.5))
    li, fi = shapely.STRtree(faces).query(mids, predicate="within")
    out[li] = fi
    return out


@dataclass
class SliverMerge:
    """One sliver: its face index, polygon, area, and the neighbour face it was merged into
    (-1: it had only the outside as neighbour and was dropped)."""

    face: int
    polygon: shapely.Geometry
    area: float
    into: int


def sliver_edges(faces: np.ndarray, edges: np.ndarray, left: np.ndarray, right: np.ndarray,
                 min_area: float) -> tuple[np.ndarray, list[SliverMerge]]:
    """Edges to remove so that every face smaller than ``min_area`` joins a neighbour.

    Each sliver joins the neighbouring face with which it shares the longest boundary (as GRASS
    ``v.clean tool=rmarea``); the shared edges are removed. A sliver bordering only the outside is
    dropped (its edges with the outside removed). Ties go to the lower face index.

    Returns
    -------
    remove : (E,) bool mask of edges to remove
    merges : list of SliverMerge
    """
    remove = np.zeros(len(edges), dtype=bool)
    merges: list[SliverMerge] = []
    if min_area <= 0 or len(faces) == 0:
        return remove, merges
    areas = shapely.area(faces)
    lengths = shapely.length(edges)
    small = np.flatnonzero(areas < min_area)
    if len(small) == 0:
        return remove, merges
    # edges bounding each face (CSR), with the face on their other side
    boundary = left != right
    e = np.flatnonzero(boundary)
    face_of = np.concatenate([left[e], right[e]])
    edge_of = np.concatenate([e, e])
    other_of = np.concatenate([right[e], left[e]])
    keep = face_of >= 0
    face_of, edge_of, other_of = face_of[keep], edge_of[keep], other_of[keep]
    order = np.argsort(face_of, kind="stable")
    face_of, edge_of, other_of = face_of[order], edge_of[order], other_of[order]
    bounds = np.searchsorted(face_of, np.arange(len(faces) + 1))
    for f in small[np.lexsort((small, areas[small]))]:
        mine = edge_of[bounds[f]:bounds[f + 1]]
        other = other_of[bounds[f]:bounds[f + 1]]
        if len(mine) == 0:
            continue
        neighbours = np.unique(other)
        shared = np.array([lengths[mine[other == g]].sum() for g in neighbours])
        real = neighbours != OUTSIDE
        pool = real if real.any() else np.ones(len(neighbours), dtype=bool)
        cand = neighbours[pool]
        best = cand[np.lexsort((cand, -shared[pool]))[0]]
        remove[mine[other == best]] = True
        merges.append(SliverMerge(int(f), faces[f], float(areas[f]), int(best)))
    return remove, merges
