"""Tracks: the same ground point seen on several photos, from pairwise matches by union-find.

A node is ``(photo index, feature index)``; every verified match joins two nodes. A track that
holds two different features of one photo is inconsistent (a wrong match somewhere in the chain)
and is dropped whole, never split by guesswork.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np


class UnionFind:
    """Disjoint sets over integer ids with path halving and union by size."""

    def __init__(self) -> None:
        self.parent: dict[int, int] = {}
        self.size: dict[int, int] = {}

    def find(self, x: int) -> int:
        parent = self.parent
        if x not in parent:
            parent[x] = x
            self.size[x] = 1
            return x
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    def union(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return
        if self.size[ra] < self.size[rb]:
            ra, rb = rb, ra
        self.parent[rb] = ra
        self.size[ra] += self.size[rb]


def build_tracks(pair_matches: Iterable[tuple[int, int, np.ndarray, np.ndarray]],
                 max_features: int) -> tuple[list[list[tuple[int, int]]], int]:
    """Tracks from ``(photo_a, photo_b, ia, ib)`` matches; feature indices must be below
    ``max_features``. Returns the consistent tracks (each a list of ``(photo, feature)`` sorted
    by photo, at least two photos) and the number of inconsistent tracks dropped."""
    uf = UnionFind()
    for pa, pb, ia, ib in pair_matches:
        for a, b in zip(ia.tolist(), ib.tolist(), strict=True):
            uf.union(pa * max_features + a, pb * max_features + b)
    groups: dict[int, list[int]] = {}
    for node in list(uf.parent):
        groups.setdefault(uf.find(node), []).append(node)
    tracks, dropped = [], 0
    for nodes in groups.values():
        obs = sorted((n // max_features, n % max_features) for n in nodes)
        photos = [p for p, _ in obs]
        if len(set(photos)) != len(photos):
            dropped += 1
            continue
        if len(obs) >= 2:
            tracks.append(obs)
    return tracks, dropped
