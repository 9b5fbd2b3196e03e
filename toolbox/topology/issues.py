"""Topology issues: what the ``errors`` layer holds, one record per problem found or fixed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

#: severity of an issue: the operator must act / the algorithm changed the geometry / the
#: algorithm would change it (``topology:check`` reports, ``topology:build_areas`` fixes)
ERROR, FIXED, FIXABLE = "error", "fixed", "fixable"

#: issue type -> meaning (documented in docs/algorithms/topology.md)
ISSUE_TYPES: dict[str, str] = {
    "invalid_geometry": "input feature that is not a usable line/polygon (empty, NaN, one point, "
                        "wrong type); skipped",
    "near_miss": "line end within the snap tolerance of a node, vertex or segment it does not touch",
    "unclosed_line": "polyline with two free ends (closed when they miss by less than the closure "
                     "tolerance, otherwise left for the operator)",
    "crossing_without_node": "lines crossing where neither has a vertex",
    "self_intersection": "line or polygon crossing itself",
    "duplicate_line": "line or piece of line plotted more than once",
    "overshoot": "piece of line past a crossing, shorter than the minimum dangle length",
    "dangle": "chain of lines with a free end (removed when shorter than the minimum dangle "
              "length, otherwise kept)",
    "sliver": "area smaller than the minimum area (merged into its neighbour)",
    "unlabelled_area": "area without a label point",
    "conflicting_labels": "area whose labels (or closed coded lines) give different area codes, "
                          "or whose labels give different attribute values",
    "label_outside": "label point inside no area (outside the linework or on a boundary)",
}


@dataclass
class Issue:
    """One problem. Geometry is a shapely Point or LineString in the kernel's coordinates.

    ``lines`` are 0-based indices of input features (rows), ``area`` a face index of the kernel
    and ``label`` a 0-based label row; -1 where not applicable. The algorithms turn them into
    1-based feature numbers and final area ids.
    """

    type: str
    severity: str
    geometry: Any
    detail: str = ""
    lines: tuple[int, ...] = ()
    area: int = -1
    label: int = -1

    def __post_init__(self) -> None:
        if self.type not in ISSUE_TYPES:
            raise ValueError(f"unknown issue type {self.type!r}")
        if self.severity not in (ERROR, FIXED, FIXABLE):
            raise ValueError(f"unknown severity {self.severity!r}")
