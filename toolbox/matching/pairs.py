"""Which photo pairs to match.

With oriented photos and a mean terrain height, the pairs whose footprints (image format
projected on the plane ``Z = height``, :mod:`toolbox.photogrammetry.coverage`) overlap by at
least ``min_overlap`` percent of the smaller footprint. Without orientations every pair is a
candidate; the caller then matches thumbnails first and keeps the pairs that hold.
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


def all_pairs(n: int) -> list[tuple[int, int, float | None]]:
    """Every pair i < j of ``n`` photos, overlap unknown."""
    return [(i, j, None) for i, j in combinations(range(n), 2)]
