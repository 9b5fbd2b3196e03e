"""Input data of the DEM gridding algorithms: points, line vertices and breaklines, read with
their CRS checked, NaN/inf refused and duplicate XY merged by a stated rule.

Duplicate XY rule (``PointSources.duplicates``): points at the same plan position (within
``duplicate_tolerance``, default: identical coordinates) become one point whose height is the
``mean`` (default), the ``first`` (input order: INPUT, LINES, BREAKLINES), the ``min`` or the
``max`` of theirs, or the run stops (``error``); see
:func:`toolbox.terrain.points.merge_duplicate_xy`. What was merged is reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.terrain.gridding.request import PointSources
from toolbox.terrain.points import DuplicateReport, local_origin, merge_duplicate_xy

#: the inputs' names in messages (the algorithms' parameter names)
UI_NAMES = {"points": "INPUT", "lines": "LINES", "breaklines": "BREAKLINES"}


# -- input data -----------------------------------------------------------------------------------
@dataclass
class GriddingData:
    """The merged data points of a run.

    Attributes
    ----------
    xyz : (n, 3) float64
        Distinct points (map coordinates), INPUT first, then LINES and BREAKLINES vertices.
    origin : (2,) float64
        Local origin; kernels get ``xyz - (origin, 0)``.
    segments : (s, 2) int64
        Breakline edges as index pairs into ``xyz`` (zero-length edges dropped).
    crs : pyproj.CRS or None
    counts : dict
        Points read per source.
    duplicates : DuplicateReport
    """

    xyz: np.ndarray
    origin: np.ndarray
    segments: np.ndarray
    crs: Any
    counts: dict
    duplicates: DuplicateReport
    _local: np.ndarray | None = field(default=None, repr=False)
    _bins: Any = field(default=None, repr=False)

    @property
    def local(self) -> np.ndarray:
        """``xyz`` shifted to the local origin (computed once; do not modify)."""
        if self._local is None:
            self._local = _shift(self.xyz, self.origin)
        return self._local

    @property
    def bins(self):
        """Neighbour index (:class:`~toolbox.terrain.gridding.neighbours.PointBins`) of the
        local points (built once)."""
        from toolbox.terrain.gridding.neighbours import PointBins

        if self._bins is None:
            self._bins = PointBins.build(self.local[:, :2])
        return self._bins

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        lo = self.xyz[:, :2].min(axis=0)
        hi = self.xyz[:, :2].max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


#: the largest height a DEM's float32 cell holds
FLOAT32_MAX = float(np.finfo(np.float32).max)


def check_heights_fit(z: np.ndarray, name: str) -> None:
    """InputDataError when a height of ``name`` is beyond what a float32 DEM cell holds (it
    would be written as inf)."""
    if len(z) and float(np.abs(z).max()) > FLOAT32_MAX:
        worst = float(z[np.abs(z).argmax()])
        raise InputDataError(f"{name}: a height of {worst:.6g} is beyond what the DEM's float32 "
                             f"cells hold (|Z| <= {FLOAT32_MAX:.4g}): check Z_FIELD and the "
                             "heights' unit")


def read_sources(sources: PointSources, feedback: Feedback,
                 other_crs: dict[str, Any] | None = None) -> GriddingData:
    """Read the points and line vertices, check CRSs, merge duplicate XY.

    ``other_crs``: the CRS of the run's other inputs by name (TEMPLATE, EXTENT, MASK), which
    must agree with the data's.
    """
    import shapely

    from toolbox.io.crs import common_crs
    from toolbox.io.vector import read_vector
    from toolbox.io.vector_points import skip_no_geometry, vertices_xyz
    from toolbox.terrain.points import read_mass_points

    named = {UI_NAMES[role]: layer.crs for role, layer in sources.layers().items()}
    named |= {name: crs for name, crs in (other_crs or {}).items() if crs is not None}
    crs = common_crs(named, sources.crs)
    if crs is None:
        feedback.push_warning("no input has a CRS and CRS is not given: the DEM has no CRS")
    parts, counts = [], {}
    segments: list[np.ndarray] = []
    offset = 0
    with feedback.timed("read"):
        if sources.points is not None:
            xyz, cloud = read_mass_points(sources.points, sources.z_field, sources.classes,
                                          sources.returns, sources.crs)
            check_heights_fit(xyz[:, 2], UI_NAMES["points"])
            parts.append(xyz)
            counts["points"] = len(xyz)
            if cloud is not None:
                counts["point_cloud"] = cloud
            offset += len(xyz)
        for role in ("lines", "breaklines"):
            layer, name = getattr(sources, role), UI_NAMES[role]
            if layer is None:
                continue
            frame = read_vector(layer, name=name)
            frame = skip_no_geometry(frame, name)
            if len(frame) == 0:
                raise InputDataError(f"{name} has no features with a geometry")
            frame = frame.explode(index_parts=False)  # index: the input row, for messages
            if not set(shapely.get_type_id(frame.geometry.values).tolist()) <= {1, 2}:
                raise InputDataError(f"{name} must contain lines, found other geometry types")
            xyz, part = vertices_xyz(frame, getattr(sources, f"{role}_z_field"), name)
            check_heights_fit(xyz[:, 2], name)
            parts.append(xyz)
            counts[f"{role}_vertices"] = len(xyz)
            if role == "breaklines" and len(xyz) > 1:
                same = part[1:] == part[:-1]
                first = np.flatnonzero(same) + offset
                segments.append(np.column_stack([first, first + 1]))
            offset += len(xyz)
    if not parts or offset == 0:
        raise InputDataError("no data points: the inputs are empty")
    xyz = parts[0] if len(parts) == 1 else np.vstack(parts)
    seg = np.vstack(segments) if segments else np.zeros((0, 2), dtype=np.int64)
    return merge_points(xyz, seg, crs, counts, sources.duplicates or "mean",
                        float(sources.duplicate_tolerance or 0.0), feedback)


def merge_points(xyz: np.ndarray, seg: np.ndarray, crs: Any, counts: dict, rule: str,
                 tolerance: float, feedback: Feedback) -> GriddingData:
    """:class:`GriddingData` of points already read (map coordinates, ``seg`` breakline index
    pairs): duplicate XY merged by ``rule`` within ``tolerance``, local origin, bins."""
    from toolbox.terrain.gridding.neighbours import PointBins

    with feedback.timed("duplicates"):
        origin = local_origin(xyz)
        local = _shift(xyz, origin)
        bins = PointBins.build(local[:, :2]) if tolerance == 0 else None
        if bins is not None and not bins.has_duplicates():  # the common case, O(n)
            merged, report = xyz, DuplicateReport(0, 0, 0.0, rule)
        else:
            local = bins = None
            try:
                merged, report, _ = merge_duplicate_xy(xyz, tolerance, rule)
            except ValueError as exc:
                raise InputDataError(f"DUPLICATES is 'error' and {exc}") from None
        if len(seg) and report.removed:
            seg = _remap(xyz[:, :2], merged[:, :2], seg)
        seg = seg[seg[:, 0] != seg[:, 1]]
        if len(seg):
            seg = np.unique(np.sort(seg, axis=1), axis=0)
    if report.groups:
        text = (f"{report.groups} XY positions had several points ({report.removed} removed); "
                f"rule '{rule}', largest Z spread {report.max_z_spread:.3f}")
        if report.max_z_spread > 0:
            feedback.push_warning(text)
        else:
            feedback.push_info(text)
    if local is None:
        origin = local_origin(merged)
    return GriddingData(merged, origin, seg.astype(np.int64), crs, counts, report, local, bins)


def _shift(xyz: np.ndarray, origin: np.ndarray) -> np.ndarray:
    out = np.array(xyz, dtype="float64")
    out[:, :2] -= origin
    return out


def has_duplicate_xy(xyz: np.ndarray) -> bool:
    """True when two points have exactly the same X and Y (binned, O(n))."""
    from toolbox.terrain.gridding.neighbours import PointBins

    return PointBins.build(np.asarray(xyz, dtype="float64")[:, :2]).has_duplicates()


def _remap(xy_all: np.ndarray, xy_merged: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Indices into the merged points of the segment ends (the merged point nearest each end)."""
    from scipy.spatial import cKDTree

    ends = np.unique(segments.ravel())
    origin = local_origin(xy_merged)
    _, nearest = cKDTree(xy_merged - origin).query(xy_all[ends] - origin, k=1)
    lookup = np.full(len(xy_all), -1, dtype=np.int64)
    lookup[ends] = nearest
    return lookup[segments]


def require_points(data: GriddingData, needed: int, method: str) -> None:
    """InputDataError when there are fewer distinct points than ``method`` needs."""
    n = len(data.xyz)
    if n < needed:
        raise InputDataError(f"{method} needs at least {needed} distinct data points, got {n} "
                             f"(after merging duplicate XY)")
