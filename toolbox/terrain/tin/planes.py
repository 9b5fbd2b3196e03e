"""Numba kernels behind :mod:`toolbox.terrain.tin.kernels`: the plane of each triangle (thesis eq.
[43]-[44]) evaluated at raster cell centres and at query points.

Each triangle is visited once. It scans the rows (of cells, or of point buckets) it spans, and
on each row only the span it covers; the candidates there are tested against its three edges.
An edge's orientation test is always evaluated from its lower to its higher vertex index, so
the two triangles sharing an edge agree bit for bit on which side a point lies: no point inside
the TIN falls into a crack between triangles.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _edge_fn(ia, ib, ua, va, ub, vb, u, v):
    """Orientation of (u, v) against the edge a-b, always evaluated from the lower to the higher
    vertex index, so both triangles sharing the edge get bit-identical values."""
    if ia < ib:
        return (ub - ua) * (v - va) - (vb - va) * (u - ua)
    return -((ua - ub) * (v - vb) - (va - vb) * (u - ub))


# duplicate-ok: rasterize and locate walk a triangle row by row the same way (edge spans,
# edge functions); numba kernels on the hot path of dem:tin_linear, kept written out (a shared
# inlined helper measured within noise but not clearly faster or equal)
@numba.njit(cache=True, nogil=True)
def _on_centre(u, snap):
    """``u`` (cell units), moved onto the cell centre (a whole number) within ``snap``."""
    k = np.floor(u + 0.5)
    return k if abs(u - k) <= snap else u


@numba.njit(cache=True, nogil=True)
def rasterize(xyz, triangles, x0, y0, cell_x, cell_y, width, height, out, snap=0.0):
    """Write into ``out`` (height, width) the plane value of each triangle at the cell centres
    it contains (see :func:`toolbox.terrain.tin.kernels.rasterize_tin`); a node within
    ``snap`` cells of a cell centre is taken on it."""
    for t in range(triangles.shape[0]):
        i0 = triangles[t, 0]
        i1 = triangles[t, 1]
        i2 = triangles[t, 2]
        # vertices in cell units: cell (r, c) centre is at (u, v) = (c, r)
        u0 = _on_centre((xyz[i0, 0] - x0) / cell_x - 0.5, snap)
        v0 = _on_centre((y0 - xyz[i0, 1]) / cell_y - 0.5, snap)
        u1 = _on_centre((xyz[i1, 0] - x0) / cell_x - 0.5, snap)
        v1 = _on_centre((y0 - xyz[i1, 1]) / cell_y - 0.5, snap)
        u2 = _on_centre((xyz[i2, 0] - x0) / cell_x - 0.5, snap)
        v2 = _on_centre((y0 - xyz[i2, 1]) / cell_y - 0.5, snap)
        vmin = min(v0, v1, v2)
        vmax = max(v0, v1, v2)
        rmin = max(int(np.ceil(vmin)), 0)
        rmax = min(int(np.floor(vmax)), height - 1)
        if rmin > rmax:
            continue
        umin = min(u0, u1, u2)
        umax = max(u0, u1, u2)
        if int(np.floor(umax)) < 0 or int(np.ceil(umin)) > width - 1:
            continue
        # plane (eq. 43-44) relative to vertex 0: z = z0 + gu * (u - u0) + gv * (v - v0)
        du1 = u1 - u0
        dv1 = v1 - v0
        du2 = u2 - u0
        dv2 = v2 - v0
        dz1 = xyz[i1, 2] - xyz[i0, 2]
        dz2 = xyz[i2, 2] - xyz[i0, 2]
        c = du1 * dv2 - du2 * dv1
        if c == 0.0:
            continue
        gu = -(dv1 * dz2 - dv2 * dz1) / c
        gv = -(dz1 * du2 - dz2 * du1) / c
        z0 = xyz[i0, 2]
        # sign of each edge function that means "inside" (the opposite vertex's side)
        s0 = _edge_fn(i1, i2, u1, v1, u2, v2, u0, v0) > 0.0
        s1 = _edge_fn(i2, i0, u2, v2, u0, v0, u1, v1) > 0.0
        s2 = _edge_fn(i0, i1, u0, v0, u1, v1, u2, v2) > 0.0
        for r in range(rmin, rmax + 1):
            fr = float(r)
            lo = np.inf
            hi = -np.inf
            # span of the triangle on this row, from its three edges
            for k in range(3):
                if k == 0:
                    pa, qa, pb, qb = u0, v0, u1, v1
                elif k == 1:
                    pa, qa, pb, qb = u1, v1, u2, v2
                else:
                    pa, qa, pb, qb = u2, v2, u0, v0
                if (qa <= fr <= qb) or (qb <= fr <= qa):
                    if qa == qb:
                        lo = min(lo, pa, pb)
                        hi = max(hi, pa, pb)
                    else:
                        p = pa + (fr - qa) * (pb - pa) / (qb - qa)
                        lo = min(lo, p)
                        hi = max(hi, p)
            if lo > hi:
                continue
            cmin = max(int(np.ceil(lo)) - 1, 0)
            cmax = min(int(np.floor(hi)) + 1, width - 1)
            for col in range(cmin, cmax + 1):
                fc = float(col)
                e0 = _edge_fn(i1, i2, u1, v1, u2, v2, fc, fr)
                if e0 != 0.0 and (e0 > 0.0) != s0:
                    continue
                e1 = _edge_fn(i2, i0, u2, v2, u0, v0, fc, fr)
                if e1 != 0.0 and (e1 > 0.0) != s1:
                    continue
                e2 = _edge_fn(i0, i1, u0, v0, u1, v1, fc, fr)
                if e2 != 0.0 and (e2 > 0.0) != s2:
                    continue
                out[r, col] = z0 + gu * (fc - u0) + gv * (fr - v0)


@numba.njit(cache=True, nogil=True)
def _bucket_points(u, v, nx, ny):
    """Sort points (in bucket units) into an nx x ny grid: (order, start) CSR arrays."""
    n = u.shape[0]
    key = np.empty(n, dtype=np.int64)
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    for i in range(n):
        bx = min(max(int(np.floor(u[i])), 0), nx - 1)
        by = min(max(int(np.floor(v[i])), 0), ny - 1)
        key[i] = by * nx + bx
        count[key[i] + 1] += 1
    for k in range(nx * ny):
        count[k + 1] += count[k]
    order = np.empty(n, dtype=np.int64)
    fill = count[:-1].copy()
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    return order, count


# duplicate-ok: the row-span walk of rasterize (see there)
@numba.njit(cache=True, nogil=True)
def locate(xyz, triangles, ox, oy, qx, qy, bu, bv, scale, nx, ny, start, out, found):
    """For each triangle, visit the point buckets its area overlaps, test the points there.

    The points ``qx, qy`` (local coordinates) are sorted by bucket: bucket ``b`` holds points
    ``start[b]:start[b + 1]``."""
    for t in range(triangles.shape[0]):
        i0 = triangles[t, 0]
        i1 = triangles[t, 1]
        i2 = triangles[t, 2]
        x0 = xyz[i0, 0] - ox
        y0 = xyz[i0, 1] - oy
        x1 = xyz[i1, 0] - ox
        y1 = xyz[i1, 1] - oy
        x2 = xyz[i2, 0] - ox
        y2 = xyz[i2, 1] - oy
        dx1 = x1 - x0
        dy1 = y1 - y0
        dx2 = x2 - x0
        dy2 = y2 - y0
        dz1 = xyz[i1, 2] - xyz[i0, 2]
        dz2 = xyz[i2, 2] - xyz[i0, 2]
        c = dx1 * dy2 - dx2 * dy1
        if c == 0.0:
            continue
        gx = -(dy1 * dz2 - dy2 * dz1) / c  # eq. 44: -a/c, with eq. 43's a, b, c
        gy = -(dz1 * dx2 - dz2 * dx1) / c  # -b/c
        z0 = xyz[i0, 2]
        s0 = _edge_fn(i1, i2, x1, y1, x2, y2, x0, y0) > 0.0
        s1 = _edge_fn(i2, i0, x2, y2, x0, y0, x1, y1) > 0.0
        s2 = _edge_fn(i0, i1, x0, y0, x1, y1, x2, y2) > 0.0
        # bucket rows spanned, and for each the columns spanned by the triangle in that band
        b0 = (y0 - bv) * scale
        b1 = (y1 - bv) * scale
        b2 = (y2 - bv) * scale
        a0 = (x0 - bu) * scale
        a1 = (x1 - bu) * scale
        a2 = (x2 - bu) * scale
        rlo = max(int(np.floor(min(b0, b1, b2))), 0)
        rhi = min(int(np.floor(max(b0, b1, b2))), ny - 1)
        for row in range(rlo, rhi + 1):
            band_lo = float(row)
            band_hi = float(row + 1)
            lo = np.inf
            hi = -np.inf
            for k in range(3):
                if k == 0:
                    pa, qa, pb, qb = a0, b0, a1, b1
                elif k == 1:
                    pa, qa, pb, qb = a1, b1, a2, b2
                else:
                    pa, qa, pb, qb = a2, b2, a0, b0
                if band_lo <= qa <= band_hi:
                    lo = min(lo, pa)
                    hi = max(hi, pa)
                if qa != qb:
                    for edge_v in (band_lo, band_hi):
                        if (qa <= edge_v <= qb) or (qb <= edge_v <= qa):
                            p = pa + (edge_v - qa) * (pb - pa) / (qb - qa)
                            lo = min(lo, p)
                            hi = max(hi, p)
            if lo > hi:
                continue
            clo = max(int(np.floor(lo)) - 1, 0)
            chi = min(int(np.floor(hi)) + 1, nx - 1)
            for col in range(clo, chi + 1):
                b = row * nx + col
                for i in range(start[b], start[b + 1]):
                    if found[i]:
                        continue
                    px = qx[i]
                    py = qy[i]
                    e0 = _edge_fn(i1, i2, x1, y1, x2, y2, px, py)
                    if e0 != 0.0 and (e0 > 0.0) != s0:
                        continue
                    e1 = _edge_fn(i2, i0, x2, y2, x0, y0, px, py)
                    if e1 != 0.0 and (e1 > 0.0) != s1:
                        continue
                    e2 = _edge_fn(i0, i1, x0, y0, x1, y1, px, py)
                    if e2 != 0.0 and (e2 > 0.0) != s2:
                        continue
                    out[i] = z0 + gx * (px - x0) + gy * (py - y0)
                    found[i] = True


@numba.njit(cache=True, nogil=True)
def snap_to_edges(xyz, edges, ox, oy, qx, qy, bu, bv, scale, nx, ny, start, tol, out, found):
    """Points within ``tol`` of a hull edge take the edge's linear value at the nearest point."""
    best = np.full(qx.shape[0], np.inf)
    for e in range(edges.shape[0]):
        ia = edges[e, 0]
        ib = edges[e, 1]
        xa = xyz[ia, 0] - ox
        ya = xyz[ia, 1] - oy
        xb = xyz[ib, 0] - ox
        yb = xyz[ib, 1] - oy
        dx = xb - xa
        dy = yb - ya
        len2 = dx * dx + dy * dy
        if len2 == 0.0:
            continue
        c0 = max(int(np.floor((min(xa, xb) - tol - bu) * scale)), 0)
        c1 = min(int(np.floor((max(xa, xb) + tol - bu) * scale)), nx - 1)
        r0 = max(int(np.floor((min(ya, yb) - tol - bv) * scale)), 0)
        r1 = min(int(np.floor((max(ya, yb) + tol - bv) * scale)), ny - 1)
        for row in range(r0, r1 + 1):
            for col in range(c0, c1 + 1):
                b = row * nx + col
                for i in range(start[b], start[b + 1]):
                    if found[i]:
                        continue
                    t = ((qx[i] - xa) * dx + (qy[i] - ya) * dy) / len2
                    t = min(max(t, 0.0), 1.0)
                    ex = xa + t * dx - qx[i]
                    ey = ya + t * dy - qy[i]
                    d = np.sqrt(ex * ex + ey * ey)
                    if d <= tol and d < best[i]:
                        best[i] = d
                        out[i] = xyz[ia, 2] + t * (xyz[ib, 2] - xyz[ia, 2])
    return best


class PointBuckets:
    """Points sorted into a regular grid of square buckets covering a box (CSR layout):
    ``x[start[b]:start[b + 1]]`` are bucket ``b``'s points, ``order`` maps back to the input."""

    def __init__(self, x: np.ndarray, y: np.ndarray, xmin: float, ymin: float, xmax: float,
                 ymax: float, size: float):
        self.bu, self.bv = xmin, ymin
        self.scale = 1.0 / size
        self.nx = int(np.floor((xmax - xmin) * self.scale)) + 1
        self.ny = int(np.floor((ymax - ymin) * self.scale)) + 1
        self.order, self.start = _bucket_points((x - xmin) * self.scale, (y - ymin) * self.scale,
                                                self.nx, self.ny)
        self.x = np.ascontiguousarray(x[self.order])
        self.y = np.ascontiguousarray(y[self.order])


# -- tiles of a raster (toolbox.terrain.gridding.tin_raster) -----------------------------------
@numba.njit(cache=True, nogil=True)
def _mark_nodes(triangles, ids, slot):
    """The nodes of triangles ``ids`` (each once), marked in ``slot`` (scratch, one per node,
    all -1 before)."""
    used = np.empty(3 * len(ids), dtype=np.int64)
    m = 0
    for k in range(len(ids)):
        for j in range(3):
            v = triangles[ids[k], j]
            if slot[v] < 0:
                slot[v] = 0
                used[m] = v
                m += 1
    return used[:m]


@numba.njit(cache=True, nogil=True)
def _renumber(nodes, triangles, ids, used, slot):
    """``nodes[used]`` and triangles ``ids`` renumbered to them; ``slot`` is left all -1."""
    m = len(used)
    out = np.empty((m, 3), dtype=np.float64)
    for i in range(m):
        v = used[i]
        slot[v] = i
        out[i, 0] = nodes[v, 0]
        out[i, 1] = nodes[v, 1]
        out[i, 2] = nodes[v, 2]
    local = np.empty((len(ids), 3), dtype=np.int64)
    for k in range(len(ids)):
        for j in range(3):
            local[k, j] = slot[triangles[ids[k], j]]
    for i in range(m):
        slot[used[i]] = -1
    return out, local


@numba.njit(cache=True, nogil=True)
def _tile_range(xy, tri, k, x0, y0, cell_x, cell_y, width, height, tile):
    """Tile columns and rows (inclusive) whose cells triangle ``k``'s box may cover (one cell of
    margin: cell centres are what count); tx1 < tx0 when it covers none."""
    a, b, c = tri[k, 0], tri[k, 1], tri[k, 2]
    xmin = min(xy[a, 0], xy[b, 0], xy[c, 0])
    xmax = max(xy[a, 0], xy[b, 0], xy[c, 0])
    ymin = min(xy[a, 1], xy[b, 1], xy[c, 1])
    ymax = max(xy[a, 1], xy[b, 1], xy[c, 1])
    c_lo = np.floor((xmin - x0) / cell_x - 0.5)
    c_hi = np.ceil((xmax - x0) / cell_x - 0.5)
    r_lo = np.floor((y0 - ymax) / cell_y - 0.5)
    r_hi = np.ceil((y0 - ymin) / cell_y - 0.5)
    if c_hi < 0 or c_lo > width - 1 or r_hi < 0 or r_lo > height - 1:
        return 0, -1, 0, -1
    tx0 = int(max(c_lo, 0.0)) // tile
    tx1 = int(min(c_hi, width - 1.0)) // tile
    ty0 = int(max(r_lo, 0.0)) // tile
    ty1 = int(min(r_hi, height - 1.0)) // tile
    return tx0, tx1, ty0, ty1


@numba.njit(cache=True, nogil=True)
def _group(xy, tri, x0, y0, cell_x, cell_y, width, height, tile, ntx, nty):
    start = np.zeros(ntx * nty + 1, dtype=np.int64)
    for k in range(tri.shape[0]):  # pass 1: triangles per tile
        tx0, tx1, ty0, ty1 = _tile_range(xy, tri, k, x0, y0, cell_x, cell_y, width, height,
                                         tile)
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                start[ty * ntx + tx + 1] += 1
    for i in range(ntx * nty):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    order = np.empty(start[-1], dtype=np.int32)
    for k in range(tri.shape[0]):  # pass 2: in triangle order within each tile
        tx0, tx1, ty0, ty1 = _tile_range(xy, tri, k, x0, y0, cell_x, cell_y, width, height,
                                         tile)
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                key = ty * ntx + tx
                order[fill[key]] = k
                fill[key] += 1
    return order, start
