"""Cut and fill between a TIN and a reference (kernels of tin:volume).

Sign convention: ``h = z_TIN - z_reference``. Where the TIN is above the reference (h > 0) the
material is *cut* (to be removed to reach the reference); where it is below (h < 0) it is
*fill*. Volumes are positive numbers in map units x height units (m³ for metric CRSs); ``net =
cut - fill``.

Against a horizontal plane the result is exact: within a triangle h is linear, so the part above
the plane is a triangle or a quadrilateral cut by the straight zero line, and the integral of a
linear function over a polygon is its area times the value at the centroid. Triangles cut by the
mask polygon are clipped exactly (shapely/GEOS) before integrating.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolbox.counters import Counters


@dataclass
class CutFill(Counters):
    """Volumes (positive) and planimetric areas of cut (TIN above) and fill (TIN below), summed
    over triangle chunks with ``+=``."""

    cut_volume: float = 0.0  # CRS units³
    fill_volume: float = 0.0  # CRS units³
    cut_area: float = 0.0  # CRS units²
    fill_area: float = 0.0  # CRS units²
    area: float = 0.0  # planimetric area compared (cut + fill + where h = 0)

    @property
    def net_volume(self) -> float:
        return self.cut_volume - self.fill_volume

    def as_dict(self) -> dict:
        return super().as_dict() | {"net_volume": self.net_volume}


def positive_part(h: np.ndarray, area: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area where h > 0 and the integral of max(h, 0) over triangles with vertex values ``h``
    ``(T, 3)`` and planimetric ``area`` ``(T,)``; h is linear inside each triangle. Exact."""
    hs = np.sort(np.asarray(h, dtype="float64"), axis=1)
    a, b, c = hs[:, 0], hs[:, 1], hs[:, 2]
    area = np.asarray(area, dtype="float64")
    pos_area = np.zeros_like(area)
    pos_vol = np.zeros_like(area)
    full = (a >= 0) & (c > 0)
    pos_area[full] = area[full]
    pos_vol[full] = area[full] * (a[full] + b[full] + c[full]) / 3.0
    one = (b <= 0) & (c > 0) & (a < 0)  # only the highest vertex above: a small triangle
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = c[one] ** 2 / ((c[one] - a[one]) * (c[one] - b[one]))
    pos_area[one] = area[one] * frac
    pos_vol[one] = pos_area[one] * c[one] / 3.0
    two = (a < 0) & (b > 0)  # only the lowest vertex below: whole minus the small triangle
    with np.errstate(divide="ignore", invalid="ignore"):
        neg_frac = a[two] ** 2 / ((b[two] - a[two]) * (c[two] - a[two]))
    neg_area = area[two] * neg_frac
    pos_area[two] = area[two] - neg_area
    pos_vol[two] = area[two] * (a[two] + b[two] + c[two]) / 3.0 + neg_area * (-a[two]) / 3.0
    return pos_area, pos_vol


def _clip_positive(p: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Polygon (k, 2) of the part of triangle ``p`` (3, 2) where the linear ``h`` is >= 0."""
    out = []
    for i in range(3):
        j = (i + 1) % 3
        if h[i] >= 0:
            out.append(p[i])
        if (h[i] > 0 > h[j]) or (h[i] < 0 < h[j]):
            t = h[i] / (h[i] - h[j])
            out.append(p[i] + t * (p[j] - p[i]))
    return np.array(out)


def plane_cut_fill(xyz: np.ndarray, triangles: np.ndarray, z_ref: float,
                   mask=None) -> CutFill:
    """Cut and fill between the TIN and the horizontal plane ``z = z_ref``, exactly.

    Parameters
    ----------
    xyz, triangles
        The TIN (nodes, counter-clockwise triangles).
    z_ref : float
        Reference elevation.
    mask : shapely Polygon or MultiPolygon, optional
        Only the part of the TIN inside it counts (triangles are clipped exactly).
    """
    import shapely

    from toolbox.terrain.points import local_origin

    xyz = np.asarray(xyz, dtype="float64")
    tri = np.asarray(triangles, dtype=np.int64)
    # areas and centroids at a local origin: GEOS keeps every digit there
    origin = local_origin(xyz)
    p = xyz[tri] - [origin[0], origin[1], 0.0]
    if mask is not None:
        mask = shapely.transform(mask, lambda c: c - origin)
    area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    h = p[:, :, 2] - z_ref
    whole = np.ones(len(tri), dtype=bool)
    result = CutFill()
    if mask is not None:
        lo, hi = p[:, :, :2].min(axis=1), p[:, :, :2].max(axis=1)
        mx0, my0, mx1, my1 = shapely.bounds(mask)
        near = np.flatnonzero((hi[:, 0] >= mx0) & (lo[:, 0] <= mx1) & (hi[:, 1] >= my0)
                              & (lo[:, 1] <= my1))
        polys = shapely.polygons(np.concatenate([p[near, :, :2], p[near, :1, :2]], axis=1))
        shapely.prepare(mask)
        inside = shapely.contains_properly(mask, polys)
        crossing = near[~inside & shapely.intersects(mask, polys)]
        whole[:] = False
        whole[near[inside]] = True
        result += _clipped(p[crossing], h[crossing], mask)
    cut_area, cut_vol = positive_part(h[whole], area[whole])
    fill_area, fill_vol = positive_part(-h[whole], area[whole])
    result += CutFill(float(cut_vol.sum()), float(fill_vol.sum()), float(cut_area.sum()),
                      float(fill_area.sum()), float(area[whole].sum()))
    return result


def _clipped(p: np.ndarray, h: np.ndarray, mask) -> CutFill:
    """Cut/fill of triangles ``p`` (K, 3, 3) crossing the mask edge: each triangle's part above
    and below the plane is clipped by the mask; integral = area x h(centroid)."""
    import shapely

    if len(p) == 0:
        return CutFill()
    out = CutFill()
    xy = p[:, :, :2]
    # plane of h in each triangle: h = h0 + g . (q - p0)
    d1, d2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    dh1, dh2 = h[:, 1] - h[:, 0], h[:, 2] - h[:, 0]
    gx = (dh1 * d2[:, 1] - dh2 * d1[:, 1]) / det
    gy = (dh2 * d1[:, 0] - dh1 * d2[:, 0]) / det
    tri_polys = shapely.polygons(np.concatenate([xy, xy[:, :1]], axis=1))
    out.area = float(shapely.area(shapely.intersection(tri_polys, mask)).sum())
    for sign in (1.0, -1.0):
        pieces = []
        for k in range(len(p)):
            # a triangle with no vertex strictly on this side has no part of it (a flat
            # triangle at the reference, h = 0, would else be the whole ring on both sides)
            ring = _clip_positive(xy[k], sign * h[k]) if (sign * h[k]).max() > 0 else ()
            pieces.append(shapely.Polygon(ring) if len(ring) >= 3 else shapely.Polygon())
        clipped = shapely.intersection(np.array(pieces, dtype=object), mask)
        a = shapely.area(clipped)
        ok = np.flatnonzero(a > 0)
        centre = shapely.centroid(clipped[ok])
        cx, cy = shapely.get_x(centre), shapely.get_y(centre)
        value = sign * (h[ok, 0] + gx[ok] * (cx - xy[ok, 0, 0]) + gy[ok] * (cy - xy[ok, 0, 1]))
        vol = float(np.sum(a[ok] * np.maximum(value, 0.0)))
        if sign > 0:
            out.cut_volume, out.cut_area = vol, float(a.sum())
        else:
            out.fill_volume, out.fill_area = vol, float(a.sum())
    return out


def grid_cut_fill(tin_z: np.ndarray, ref_z: np.ndarray, cell_area: float,
                  inside: np.ndarray | None = None) -> CutFill:
    """Cut and fill on a grid: each cell with both heights counts ``cell_area`` x (TIN - ref) at
    its centre (midpoint rule). NaN in either surface, or ``inside`` False, leaves a cell out."""
    h = np.asarray(tin_z, dtype="float64") - np.asarray(ref_z, dtype="float64")
    valid = np.isfinite(h) if inside is None else np.isfinite(h) & inside
    hv = h[valid]
    pos, neg = hv > 0, hv < 0
    return CutFill(float(hv[pos].sum() * cell_area), float(-hv[neg].sum() * cell_area),
                   float(pos.sum() * cell_area), float(neg.sum() * cell_area),
                   float(valid.sum() * cell_area))
