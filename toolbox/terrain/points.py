"""Point-set helpers shared by TIN and DEM gridding: local origin, duplicate XY merging.

Projected coordinates are large (Siena: 1,688,000 / 4,799,500); triangulation and least squares
lose digits on them, so kernels work on coordinates shifted to a local origin.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

DUPLICATE_RULES = ("mean", "first", "min", "max", "error")


def local_origin(xy: np.ndarray) -> np.ndarray:
    """A round origin near the centre of the points' bounding box, shape (2,).

    Rounded to 1 m... 1 km so that shifted values stay exact in binary floating point.
    """
    xy = np.asarray(xy, dtype="float64")
    centre = (xy[:, :2].min(axis=0) + xy[:, :2].max(axis=0)) / 2.0
    span = float(np.ptp(xy[:, :2], axis=0).max()) if len(xy) else 0.0
    step = 10.0 ** max(0, min(3, int(np.floor(np.log10(span))) if span > 0 else 0))
    return np.round(centre / step) * step


@dataclass
class DuplicateReport:
    """What :func:`merge_duplicate_xy` did."""

    groups: int  # XY positions that had more than one point
    removed: int  # points removed by the merge
    max_z_spread: float  # largest max(z) - min(z) within a group (0 if none)
    rule: str

    def as_dict(self) -> dict:
        return {"duplicate_groups": self.groups, "duplicates_removed": self.removed,
                "max_z_spread": self.max_z_spread, "rule": self.rule}


def merge_duplicate_xy(xyz: np.ndarray, tolerance: float = 0.0,
                       rule: str = "mean") -> tuple[np.ndarray, DuplicateReport, np.ndarray]:
    """Merge points closer than ``tolerance`` in plan (exactly equal XY when 0).

    Parameters
    ----------
    xyz : (N, 3) float array
    tolerance : float
        Planimetric distance (CRS units) under which points are the same position. Groups are
        formed greedily by a kd-tree (connected components of the "closer than" relation).
    rule : {"mean", "first", "min", "max", "error"}
        Z of a merged position: mean of the group, the first point's, the lowest, the highest;
        ``"error"`` raises ``ValueError`` when a group has different Z values.

    Returns
    -------
    merged : (M, 3) array, in the order of each group's first point
    report : DuplicateReport
    keep_index : (M,) int array, index in ``xyz`` of each group's first point
    """
    if rule not in DUPLICATE_RULES:
        raise ValueError(f"rule must be one of {', '.join(DUPLICATE_RULES)}, got {rule!r}")
    xyz = np.asarray(xyz, dtype="float64")
    n = len(xyz)
    if n == 0:
        return xyz.copy(), DuplicateReport(0, 0, 0.0, rule), np.zeros(0, dtype=np.int64)
    if tolerance > 0:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        origin = local_origin(xyz)
        pairs = cKDTree(xyz[:, :2] - origin).query_pairs(tolerance, output_type="ndarray")
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        _, labels = connected_components(graph, directed=False)
    else:  # exact XY equality: sort by (x, y) and cut where either changes
        order_xy = np.lexsort((xyz[:, 1], xyz[:, 0]))
        sx, sy = xyz[order_xy, 0], xyz[order_xy, 1]
        new_group = np.ones(n, dtype=bool)
        new_group[1:] = (sx[1:] != sx[:-1]) | (sy[1:] != sy[:-1])
        labels = np.empty(n, dtype=np.int64)
        labels[order_xy] = np.cumsum(new_group) - 1
    # renumber groups by first occurrence so the output keeps the input order
    first_index = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(first_index, labels, np.arange(n))
    order = np.argsort(first_index, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    group = rank[labels]
    m = len(order)
    counts = np.bincount(group, minlength=m)
    zmin = np.full(m, np.inf)
    zmax = np.full(m, -np.inf)
    np.minimum.at(zmin, group, xyz[:, 2])
    np.maximum.at(zmax, group, xyz[:, 2])
    spread = zmax - zmin
    keep = first_index[order]
    merged = xyz[keep].copy()
    if rule == "error" and np.any(spread > 0):
        bad = np.flatnonzero(spread > 0)[0]
        raise ValueError(f"{int(np.sum(spread > 0))} positions have points with different Z, "
                         f"e.g. at x={merged[bad, 0]:.3f} y={merged[bad, 1]:.3f}: "
                         f"z from {zmin[bad]:.3f} to {zmax[bad]:.3f}")
    if rule == "mean":
        merged[:, 2] = np.bincount(group, weights=xyz[:, 2], minlength=m) / counts
        if tolerance > 0:  # merged position = mean XY of the group too
            merged[:, 0] = np.bincount(group, weights=xyz[:, 0], minlength=m) / counts
            merged[:, 1] = np.bincount(group, weights=xyz[:, 1], minlength=m) / counts
    elif rule == "min":
        merged[:, 2] = zmin
    elif rule == "max":
        merged[:, 2] = zmax
    dup = counts > 1
    report = DuplicateReport(int(dup.sum()), int(n - m),
                             float(spread[dup].max()) if dup.any() else 0.0, rule)
    return merged, report, keep


COLLINEAR_RELATIVE = 1e-7  # RMS distance from the best line / extent below this: collinear


class CollinearError(ValueError):
    """The points lie on one line (up to rounding): no surface through them."""


def check_not_collinear(xy: np.ndarray, what: str = "data points",
                        relative: float = COLLINEAR_RELATIVE) -> None:
    """Raise ``ValueError`` (callers wrap it) when the points lie on one line up to rounding:
    the one degeneracy test of point sets (surfaces, plane transforms, resection).

    The test is relative to the data's extent, not exact: the smallest singular value of the
    centred XY, divided by sqrt(N), is the RMS distance of the points from their best-fit line;
    below ``relative`` (default :data:`COLLINEAR_RELATIVE`) times the extent, the points are
    collinear for any surface (200 points on a line to 1e-10 m would give only slivers). A
    fit that needs a well-spread geometry passes a larger ``relative``.
    """
    xy = np.asarray(xy, dtype="float64")[:, :2]
    n = len(xy)
    if n < 3:
        raise ValueError(f"the {what} are too few: at least 3 points are needed, got {n}")
    centred = xy - xy.mean(axis=0)
    # column by column: the same numbers, 10 times faster than along axis 0 of (N, 2)
    extent = float(np.maximum(np.ptp(xy[:, 0]), np.ptp(xy[:, 1])))
    if extent == 0:
        raise ValueError(f"the {n} {what} all have the same XY (duplicate positions)")
    spread = float(np.linalg.svd(centred, compute_uv=False)[-1]) / np.sqrt(n)
    if spread < relative * extent:
        raise CollinearError(f"the {n} {what} are collinear: they lie within {spread:.3g} (RMS) "
                             f"of one line over an extent of {extent:.6g}; a surface needs "
                             "points spread in two directions")


def read_mass_points(source: Any, z_field: str | None = None, classes: Any = None,
                     returns: str | None = "all", crs: Any = None,
                     name: str = "INPUT") -> tuple[np.ndarray, dict | None]:
    """(N, 3) X, Y, Z of a point layer or a LAS/LAZ point cloud, and the cloud's read report.

    A point cloud (:class:`toolbox.io.pointcloud.PointCloudRef`) is streamed by chunks with
    the ``classes`` ("2,9") and ``returns`` ("all", "first", "last") filters; the report
    (points in the file, kept, class histogram) is None for a vector layer.
    """
    from toolbox.io.pointcloud import PointCloudRef, cloud_filter, read_xyz
    from toolbox.io.vector_points import read_points_xyz

    flt = cloud_filter(source, classes, returns, crs, name)
    if isinstance(source, PointCloudRef):
        xyz, report = read_xyz(source, flt, z_field, name)
        return xyz, report.as_dict()
    return read_points_xyz(source, z_field, name), None
