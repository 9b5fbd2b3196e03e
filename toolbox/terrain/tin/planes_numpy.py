"""numpy twin of :func:`toolbox.terrain.tin.planes.rasterize` for small rasters: the same plane
of the containing triangle (thesis eq. [43]-[44]) at each cell centre, with the same arithmetic,
and no numba import (a small run would spend more on numba's import and kernel-cache load,
about 1 s, than on its work).

Vectorised over triangles, not looped (``np.repeat`` expands triangles to their rows, rows to
their cells): each triangle's rows of cell centres, on each row the span between its edges
(widened by :data:`SPAN_SLACK` for rounding), and each centre there tested against the three
edges with the compiled kernel's edge functions, evaluated from the lower to the higher vertex
index so that two triangles sharing an edge agree bit for bit on which side a centre lies (no
centre is lost in a crack). A centre inside takes the kernel's plane value; later triangles
overwrite earlier ones, as in the kernel (on a shared edge both values agree up to rounding).
"""

from __future__ import annotations

import numpy as np

#: cells tested beyond a row's computed span (cell units): far above the span's rounding error
#: (about 1e-13), far below a cell, so exactly the centres the edge tests accept are tested
SPAN_SLACK = 1e-9
#: triangles per vectorised batch (its arrays stay in the CPU caches: measured fastest), and
#: at most this many (triangle, row) pairs per batch: memory stays bounded for long slivers
#: (the cells of a batch are at most the raster's plus one per pair: triangles do not overlap)
BATCH = 8192
BATCH_ROWS = 1 << 16


def rasterize(xyz: np.ndarray, triangles: np.ndarray, x0: float, y0: float, cell_x: float,
              cell_y: float, width: int, height: int, out: np.ndarray, snap: float = 0.0) -> None:
    """Write into ``out`` (height, width) the plane value of each triangle at the cell centres
    it contains (arguments as :func:`toolbox.terrain.tin.planes.rasterize`)."""
    # vertices in cell units: cell (r, c) centre is at (u, v) = (c, r); on one within ``snap``
    u_node = (xyz[:, 0] - x0) / cell_x - 0.5
    v_node = (y0 - xyz[:, 1]) / cell_y - 0.5
    for a in (u_node, v_node):
        k = np.floor(a + 0.5)
        np.copyto(a, k, where=np.abs(a - k) <= snap)
    z_node = np.ascontiguousarray(xyz[:, 2])
    target = out if out.flags.c_contiguous else np.ascontiguousarray(out)
    flat_out = target.reshape(-1)  # a view: cells are written by flat index
    tri = np.asarray(triangles, dtype=np.int64)
    v = [v_node[tri[:, j]] for j in range(3)]
    n_rows = np.minimum(np.floor(np.maximum(np.maximum(v[0], v[1]), v[2])), height - 1.0) \
        - np.maximum(np.ceil(np.minimum(np.minimum(v[0], v[1]), v[2])), 0.0) + 1.0
    rows_before = np.concatenate([[0.0], np.cumsum(np.maximum(n_rows, 0.0))])
    first = 0
    while first < len(tri):
        last = np.searchsorted(rows_before, rows_before[first] + BATCH_ROWS, side="right") - 1
        last = min(first + BATCH, max(first + 1, int(last)))
        _batch(tri[first:last], u_node, v_node, z_node, width, height, flat_out)
        first = last
    if target is not out:
        out[...] = target


def _batch(tri, u_node, v_node, z_node, width, height, flat_out):
    i = [np.ascontiguousarray(tri[:, j]) for j in range(3)]
    u = [u_node[ij] for ij in i]
    v = [v_node[ij] for ij in i]
    r_lo = np.maximum(np.ceil(np.minimum(np.minimum(v[0], v[1]), v[2])), 0.0)
    r_hi = np.minimum(np.floor(np.maximum(np.maximum(v[0], v[1]), v[2])), height - 1.0)
    du1, dv1, du2, dv2 = u[1] - u[0], v[1] - v[0], u[2] - u[0], v[2] - v[0]
    c = du1 * dv2 - du2 * dv1
    keep = np.flatnonzero((r_lo <= r_hi) & (c != 0.0))
    if not len(keep):
        return
    i, u, v = [a[keep] for a in i], [a[keep] for a in u], [a[keep] for a in v]
    du1, dv1, du2, dv2, c = du1[keep], dv1[keep], du2[keep], dv2[keep], c[keep]
    z0 = z_node[i[0]]
    dz1, dz2 = z_node[i[1]] - z0, z_node[i[2]] - z0
    # plane (eq. 43-44) relative to vertex 0: z = z0 + gu * (u - u0) + gv * (v - v0)
    gu = -(dv1 * dz2 - dv2 * dz1) / c
    gv = -(dz1 * du2 - dz2 * du1) / c
    # the edges as the compiled kernel evaluates them: from the lower vertex index (start ua,
    # va, direction du, dv); a centre is inside when each value is 0 or has the sign of the
    # opposite vertex's (``inside``: that sign is +, the sign flips where the edge is reversed)
    edges = []
    for a, b, opposite in ((1, 2, 0), (2, 0, 1), (0, 1, 2)):
        flip = i[a] > i[b]
        ua, va = np.where(flip, u[b], u[a]), np.where(flip, v[b], v[a])
        du, dv = np.where(flip, u[a], u[b]) - ua, np.where(flip, v[a], v[b]) - va
        e = du * (v[opposite] - va) - dv * (u[opposite] - ua)
        inside = (np.where(flip, -e, e) > 0.0) != flip
        # on a row, the edge bounds the span from below where the inside is towards +u
        slope = du / np.where(dv != 0.0, dv, 1.0)  # level edges (dv = 0) bound no span
        lower = (dv < 0.0) == inside
        edges.append((ua, va, du, dv, inside, slope, dv != 0.0, lower))
    # rows: (triangle, row) pairs, on each the span the edges leave (SPAN_SLACK wider)
    r_lo = r_lo[keep].astype(np.int64)
    n_rows = r_hi[keep].astype(np.int64) - r_lo + 1
    t = np.repeat(np.arange(len(keep)), n_rows)
    row = r_lo[t] + (np.arange(len(t)) - (np.cumsum(n_rows) - n_rows)[t])
    fr = row.astype(np.float64)
    lo = np.full(len(t), -np.inf)
    hi = np.full(len(t), np.inf)
    for ua, va, _, _, _, slope, slanted, lower in edges:
        bound = np.where(slanted[t], ua[t] + (fr - va[t]) * slope[t], np.nan)
        below = lower[t]
        lo = np.fmax(lo, np.where(below, bound, np.nan))
        hi = np.fmin(hi, np.where(below, np.nan, bound))
    c_lo = np.maximum(np.ceil(lo - SPAN_SLACK), 0.0)
    c_hi = np.minimum(np.floor(hi + SPAN_SLACK), width - 1.0)
    n_cols = np.where(c_lo <= c_hi, c_hi - c_lo + 1.0, 0.0).astype(np.int64)
    # cells: (row pair, column), tested against the three edges as the compiled kernel does
    pair = np.repeat(np.arange(len(t)), n_cols)
    col = c_lo.astype(np.int64)[pair] + (np.arange(len(pair)) - (np.cumsum(n_cols) - n_cols)[pair])
    k = t[pair]
    fr, fc = fr[pair], col.astype(np.float64)
    ok = np.ones(len(k), dtype=bool)
    for ua, va, du, dv, inside, *_ in edges:
        e = du[k] * (fr - va[k]) - dv[k] * (fc - ua[k])
        ok &= (e == 0.0) | ((e > 0.0) == inside[k])
    k, fr, fc = k[ok], fr[ok], fc[ok]
    flat_out[row[pair[ok]] * width + col[ok]] = \
        z0[k] + gu[k] * (fc - u[0][k]) + gv[k] * (fr - v[0][k])
