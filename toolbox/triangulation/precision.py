"""Precision of an adjusted block from the inverse normal matrix, block by block.

With ``N = [[A, B], [Bᵀ, C]]`` and ``S = A - B·C⁻¹·Bᵀ`` (:mod:`toolbox.triangulation.solver`),
``E = S⁻¹`` (dense, nc x nc: the camera part only) gives

- the cofactors of the exterior and calibration parameters: ``Q_cc = E``;
- of each point: ``Q_pp = C_p⁻¹ + H_p·E·H_pᵀ`` with ``H_p = C_p⁻¹·B_pᵀ``;
- of each (weighted) observation row ``i``: ``q_i = g_i·E·g_iᵀ + j_i·C_p⁻¹·j_iᵀ`` where
  ``g_i = jc_i - j_i·H_p`` (jc, j: its camera and point Jacobian rows); its redundancy number
  ``r_i = 1 - q_i`` (Baarda; Σ r_i = redundancy).

The full ``(nc + 3P)²`` inverse is never formed; point blocks and rows are done in chunks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from toolbox.triangulation.solver import (
    Linearization,
    Normal,
    Problem,
    block_diagonal,
    reduced_system,
)

CHUNK = 4096


@dataclass
class Cofactors:
    camera: np.ndarray  # (nc, nc) E
    points: np.ndarray  # (P, 3, 3)
    rows: np.ndarray  # (rows,) q_i of the weighted observation rows


def cofactors(problem: Problem, lin: Linearization, normal: Normal) -> Cofactors:
    import scipy.linalg as la

    s, _, cinv = reduced_system(normal, 0.0, problem.block.point_ids)
    d = 1.0 / np.sqrt(s.diagonal())
    ss = (sp.diags(d) @ s @ sp.diags(d)).toarray()
    e = la.cho_solve(la.cho_factor(ss), np.eye(len(d))) * d[:, None] * d[None, :]
    ht = (block_diagonal(cinv) @ normal.b.T).tocsr()  # rows 3p..3p+2 = H_p
    n_pts = len(cinv)
    q_points = cinv.copy()
    for start in range(0, n_pts, CHUNK):
        stop = min(n_pts, start + CHUNK)
        h = ht[3 * start:3 * stop]
        he = np.asarray(h @ e).reshape(stop - start, 3, -1)
        hd = h.toarray().reshape(stop - start, 3, -1)
        q_points[start:stop] += np.einsum("pak,pbk->pab", he, hd)
    g = (lin.jc - normal.jp @ ht).tocsr()
    q_rows = np.zeros(len(lin.r))
    for start in range(0, len(lin.r), CHUNK):
        gi = g[start:start + CHUNK]
        q_rows[start:start + CHUNK] = np.einsum("ik,ik->i", np.asarray(gi @ e), gi.toarray())
    on = np.flatnonzero(lin.row_point >= 0)
    jr = lin.jp_rows[on]
    q_rows[on] += np.einsum("ia,iab,ib->i", jr, cinv[lin.row_point[on]], jr)
    return Cofactors(e, q_points, q_rows)
