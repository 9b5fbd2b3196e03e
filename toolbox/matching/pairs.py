"""Which photo pairs to match.

With oriented photos and a mean terrain height, the pairs whose footprints (image format
projected on the plane ``Z = height``, :mod:`toolbox.photogrammetry.coverage`) overlap by at
least ``min_overlap`` percent of the smaller footprint. With approximate positions only (a GNSS
log, EXIF GPS, orientations without a terrain height), each photo's ``k`` nearest neighbours plus
the edges of the positions' Delaunay triangulation (which link strips even when the ``k``
nearest all lie along one strip). Without either every pair is a candidate; the caller then
matches thumbnails first and keeps the pairs that hold.
"""

from __future__ import annotations

from itertools import combinations


def footprint_pairs(photos: list, height: float, min_overlap: float = 5.0
                    ) -> list[tuple[int, int, float]]:
    """``(i, j, overlap percent of the smaller footprint)`` for oriented ``photos``, i < j."""
    from toolbox.photogrammetry.coverage import overlaps, photo_footprint

    footprints = [photo_footprint(p, None, height, points_per_side=4) for p in photos]
    index = {p.id: k for k, p in enumerate(photos)}
    result = []
    for ov in overlaps(footprints, set()):
        percent = max(ov.percent_of_a, ov.percent_of_b)
        if percent >= min_overlap:
            i, j = sorted((index[ov.a], index[ov.b]))
            result.append((i, j, percent))
    return sorted(result)


def neighbour_pairs(xy, k: int = 8) -> list[tuple[int, int, float | None]]:
    """Pairs ``(i, j, None)``, i < j, of planar positions ``xy`` (N, 2): each photo with its
    ``k`` nearest others, and the Delaunay edges no longer than 3 times their median (longer
    ones span the block's concave outline, not an overlap)."""
    import numpy as np
    from scipy.spatial import Delaunay, QhullError, cKDTree

    xy = np.asarray(xy, dtype="float64")
    n = len(xy)
    found: set[tuple[int, int]] = set()
    if n < 2:
        return []
    _, near = cKDTree(xy).query(xy, k=min(n, k + 1))
    for i, row in enumerate(np.atleast_2d(near)):
        found.update((min(i, j), max(i, j)) for j in row if j != i)
    if n >= 4:
        try:
            simplices = Delaunay(xy - xy.mean(axis=0)).simplices
        except QhullError:  # collinear (one strip) or repeated positions: neighbours only
            simplices = np.zeros((0, 3), int)
        edges = {(min(a, b), max(a, b)) for t in simplices for a, b in
                 ((t[0], t[1]), (t[1], t[2]), (t[0], t[2]))}
        if edges:
            length = {e: float(np.hypot(*(xy[e[0]] - xy[e[1]]))) for e in edges}
            limit = 3.0 * float(np.median(list(length.values())))
            found.update(e for e in edges if length[e] <= limit)
    return [(int(i), int(j), None) for i, j in sorted(found)]


def all_pairs(n: int) -> list[tuple[int, int, float | None]]:
    """Every pair i < j of ``n`` photos, overlap unknown."""
    return [(i, j, None) for i, j in combinations(range(n), 2)]
