"""Predicted precision of a planned block (004 sl. 17-25, 29) by covariance analysis.

The planned block is adjusted on paper by independent models in space (004 sl. 14-16): per model
a 7-parameter similarity (linearised at the plan: unit scale, no rotation), per point X, Y, Z;
tie points at the photo nadirs and on the side-overlap lines (the Gruber positions, shared with
the neighbouring strip), the projection centres as tie points between consecutive models of a
strip (sl. 15), control points with their known components exact (the slides' control). A point
belongs to every model whose stereo area holds it. Model coordinates have the sigma
``s_M = m_b·σ`` in X, Y (σ: image measurement sigma) and ``m_b·(H/B)·√2·σ`` in height (parallax
precision, domain.md section 7). The inverse normal matrix gives each point's sigma X, Y, Z; all
sigmas are proportional to σ, so the analysis is done once for σ = 1.

Rules applied to the result (004): isolated points (in one model) about 33 % worse than tie
points (sl. 22); a bundle adjustment follows the same rules with s_M halved (sl. 29).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from toolbox.errors import InputDataError
from toolbox.triangulation.flightplan import FlightPlan

ISOLATED_FACTOR = 4.0 / 3.0  # 004 sl. 22: "inferiore di circa il 33 %"
BUNDLE_FACTOR = 0.5  # 004 sl. 29: "si dimezzano i valori di sM"
MAX_MODEL_UNKNOWNS = 5000  # 7 per model: the reduced matrix is inverted densely
CHUNK = 2048  # point rows per product with the dense inverse


@dataclass
class BlockPoints:
    """Points of the analysis (flight frame u, v; z above the terrain) and their models."""

    uvz: np.ndarray  # (P, 3)
    kind: np.ndarray  # (P,) 0 tie, 1 projection centre, 2 control, 3 tie outside the area
    known: np.ndarray  # (P, 3) bool: component fixed (control)
    obs_point: np.ndarray  # (m,)
    obs_model: np.ndarray  # (m,)


@dataclass
class Prediction:
    """Sigmas (m) of the points for an image sigma of 1 mm (multiply by σ in mm)."""

    points: BlockPoints
    sigma: np.ndarray  # (P, 3) X, Y, Z (flight frame: along, across, height)
    unknowns: int
    equations: int

    def tie(self) -> np.ndarray:
        return self.points.kind == 0


def block_points(plan: FlightPlan) -> BlockPoints:
    """Tie points, projection centres and control of the plan, with the models holding them."""
    a, (across, along) = plan.spacing, plan.ground_side
    uv = plan.photo_uv
    pts: dict[tuple[float, float, float], int] = {}
    kind, known = [], []

    def add(u: float, v: float, z: float, k: int, fixed=(False, False, False)) -> int:
        key = (round(u, 2), round(v, 2), round(z, 2))
        if key not in pts:
            pts[key] = len(kind)
            kind.append(k)
            known.append(list(fixed))
        elif k == 2:
            j = pts[key]
            kind[j] = 2
            known[j] = [x or y for x, y in zip(known[j], fixed, strict=True)]
        return pts[key]

    band = across - a  # width of the side overlap
    for u, v in uv:
        for dv in (-a / 2 - band / 4, -a / 2 + band / 4, 0.0, a / 2 - band / 4, a / 2 + band / 4):
            add(u, v + dv, 0.0, 0)
    for (u, v), ck in zip(plan.control_uv, plan.control_kind, strict=True):
        add(u, v, 0.0, 2, ("X" in ck, "Y" in ck, "Z" in ck))
    centre = [add(u, v, plan.flying_height, 1) for u, v in uv]
    keys = np.array(list(pts.keys()))
    kind = np.array(kind)
    if plan.area_uv is not None:  # tie points beyond the area are adjusted, not reported
        import shapely

        outside = ~shapely.contains_xy(plan.area_uv.buffer(1e-6 * plan.base), keys[:, 0],
                                       keys[:, 1])
        kind[(kind == 0) & outside] = 3
    obs_p, obs_m = [], []
    for m, (i, j) in enumerate(plan.models):
        lo, hi = sorted((uv[i, 0], uv[j, 0]))
        v = uv[i, 1]
        ground = np.flatnonzero((keys[:, 2] == 0.0)
                                & (keys[:, 0] >= hi - along / 2 - 1e-6)
                                & (keys[:, 0] <= lo + along / 2 + 1e-6)
                                & (np.abs(keys[:, 1] - v) <= across / 2 - 1e-6))
        inside = [p for p in ground] + [centre[i], centre[j]]
        obs_p += inside
        obs_m += [m] * len(inside)
    return BlockPoints(keys, kind, np.array(known, dtype=bool), np.array(obs_p),
                       np.array(obs_m))


def predict(plan: FlightPlan, points: BlockPoints | None = None) -> Prediction:
    """Covariance analysis of the planned block for an image sigma of 1 mm: X, Y from the
    planimetric adjustment (4 parameters per model, 004 sl. 9; planimetry does not depend on the
    heights, sl. 17), Z from the spatial one (7 parameters per model, projection centres)."""
    pts = points or block_points(plan)
    if not plan.models:
        raise InputDataError("the plan has no stereo model (a strip needs >= 2 photos)")
    s_xy = plan.spec.photo_scale / 1000.0  # model-coordinate sigma X, Y for σ = 1 mm, m
    s_z = s_xy * plan.flying_height / plan.base * math.sqrt(2.0)
    uv = plan.photo_uv
    centres = np.array([[(uv[i, 0] + uv[j, 0]) / 2, uv[i, 1], 0.0] for i, j in plan.models])
    sigma = np.zeros(pts.known.shape)
    ground = np.flatnonzero(pts.kind[pts.obs_point] != 1)
    plane = _covariance(pts.obs_point[ground], pts.obs_model[ground],
                        pts.uvz[pts.obs_point[ground]] - centres[pts.obs_model[ground]],
                        pts.known[:, :2] | (pts.kind == 1)[:, None], len(plan.models), "plane",
                        (s_xy, s_xy))
    space = _covariance(pts.obs_point, pts.obs_model, pts.uvz[pts.obs_point]
                        - centres[pts.obs_model], pts.known, len(plan.models), "space",
                        (s_xy, s_xy, s_z))
    sigma[:, :2] = plane[0]
    sigma[:, 2] = space[0][:, 2]
    return Prediction(pts, sigma, plane[1] + space[1], plane[2] + space[2])


def _covariance(obs_point: np.ndarray, obs_model: np.ndarray, x: np.ndarray, known: np.ndarray,
                n_models: int, mode: str, sig: tuple[float, ...]) -> tuple[np.ndarray, int, int]:
    """Sigmas (P, dims) of the points, unknowns, equations; ``x`` (m, 3) model coordinates."""
    npar = 4 if mode == "plane" else 7
    free = ~known
    col = np.full(known.shape, -1)
    col[free] = npar * n_models + np.arange(int(free.sum()))
    nu = npar * n_models + int(free.sum())
    if npar * n_models > MAX_MODEL_UNKNOWNS:
        raise InputDataError(f"the precision analysis of {n_models} models is too large (at "
                             f"most {MAX_MODEL_UNKNOWNS // 7} models): plan the block in parts")
    m = len(x)
    zero, one = np.zeros(m), np.ones(m)
    if mode == "plane":  # Tu Tv a b: X = Tu + a·x - b·y, Y = Tv + a·y + b·x
        coefs = [(one, zero, x[:, 0], -x[:, 1]), (zero, one, x[:, 1], x[:, 0])]
    else:  # T1 T2 T3 scale omega phi kappa (small rotations about the u, v, z axes)
        coefs = [(one, zero, zero, x[:, 0], zero, x[:, 2], -x[:, 1]),
                 (zero, one, zero, x[:, 1], -x[:, 2], zero, x[:, 0]),
                 (zero, zero, one, x[:, 2], x[:, 1], -x[:, 0], zero)]
    dims = len(coefs)
    rows, cols, vals = [], [], []
    for comp, terms in enumerate(coefs):
        w = 1.0 / sig[comp]
        r = dims * np.arange(m) + comp
        for t, term in enumerate(terms):
            rows.append(r)
            cols.append(npar * obs_model + t)
            vals.append(term * w)
        c = col[obs_point, comp]
        on = c >= 0
        rows.append(r[on])
        cols.append(c[on])
        vals.append(np.full(int(on.sum()), -w))
    a = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(dims * m, nu))
    normal = (a.T @ a).tocsr()
    return _point_sigmas(normal, npar * n_models, col, free, mode), nu, dims * m


def _point_sigmas(normal: sp.csr_matrix, nc: int, col: np.ndarray, free: np.ndarray,
                  mode: str) -> np.ndarray:
    """Sigmas (P, dims) of the points from ``N⁻¹``: points eliminated block by block (each point
    touches only its own columns), ``S = A - B·C⁻¹·Bᵀ`` inverted densely, then
    ``Q_pp = C_p⁻¹ + H_p·S⁻¹·H_pᵀ`` with ``H = C⁻¹·Bᵀ`` (diagonals only)."""
    import scipy.linalg as la

    n_pts, dims = free.shape
    need = "2 planimetric" if mode == "plane" else "3 height"
    error = InputDataError(f"the planned block is not determined ({mode}: too little control "
                           f"or tie points; it needs at least {need} control points)")
    blocks = np.tile(np.eye(dims), (n_pts, 1, 1))
    cn = normal[nc:, nc:].tocoo()
    owner = np.full(normal.shape[0] - nc, -1)
    comp = np.full(normal.shape[0] - nc, -1)
    owner[col[free] - nc], comp[col[free] - nc] = np.nonzero(free)
    if (owner[cn.row] != owner[cn.col]).any():
        raise AssertionError("points must not share normal-matrix entries")
    blocks[owner[cn.row], comp[cn.row], comp[cn.col]] = cn.data
    for k in range(dims):  # fixed components: an identity row and column (never used)
        blocks[~free[:, k], k, :] = 0.0
        blocks[~free[:, k], :, k] = 0.0
        blocks[~free[:, k], k, k] = 1.0
    eig = np.linalg.eigvalsh(blocks)
    if not (eig[:, 0] > 1e-12 * eig[:, -1]).all():
        raise error
    cinv = np.linalg.inv(blocks)
    # H = C⁻¹·Bᵀ as a sparse matrix over the point columns
    r_idx, c_idx, vals = [], [], []
    for i in range(dims):
        for j in range(dims):
            on = free[:, i] & free[:, j]
            r_idx.append(col[on, i] - nc)
            c_idx.append(col[on, j] - nc)
            vals.append(cinv[on, i, j])
    cinv_sp = sp.csr_matrix((np.concatenate(vals), (np.concatenate(r_idx),
                                                    np.concatenate(c_idx))),
                            shape=(normal.shape[0] - nc,) * 2)
    b = normal[:nc, nc:]
    h = (cinv_sp @ b.T).tocsr()
    s = normal[:nc, :nc].toarray() - (b @ h).toarray()
    d = 1.0 / np.sqrt(np.maximum(np.diag(s), 1e-300))
    try:
        factor = la.cho_factor(s * d[:, None] * d[None, :])
    except la.LinAlgError:
        raise error from None
    if np.abs(np.diag(factor[0])).min() ** 2 < 1e-13:
        raise error
    e = la.cho_solve(factor, np.eye(nc)) * d[:, None] * d[None, :]
    diag = cinv_sp.diagonal()
    for start in range(0, h.shape[0], CHUNK):  # diag(H·E·Hᵀ), a block of rows at a time
        hc = h[start:start + CHUNK]
        diag[start:start + CHUNK] += np.asarray(hc.multiply(hc @ e).sum(axis=1)).ravel()
    var = np.zeros(free.shape)
    var[free] = diag[col[free] - nc]
    return np.sqrt(np.maximum(var, 0.0))


def summary(pred: Prediction, sigma_mm: float, method: str = "bundle") -> dict:
    """Mean (RMS) and largest sigmas (m) of the tie points per coordinate: XY = √((σu² + σv²)/2),
    Z; isolated points ×4/3; a bundle ×1/2 (see the module docstring)."""
    factor = sigma_mm * (BUNDLE_FACTOR if method == "bundle" else 1.0)
    tie = pred.tie()
    sxy = np.sqrt((pred.sigma[tie, 0] ** 2 + pred.sigma[tie, 1] ** 2) / 2) * factor
    sz = pred.sigma[tie, 2] * factor
    worst = int(np.argmax(sxy))
    out = {"method": method, "image_sigma_um": 1000.0 * sigma_mm,
           "tie_points": int(tie.sum()),
           "sigma_xy_mean_m": float(np.sqrt((sxy ** 2).mean())), "sigma_xy_max_m": float(sxy.max()),
           "sigma_z_mean_m": float(np.sqrt((sz ** 2).mean())), "sigma_z_max_m": float(sz.max()),
           "worst_xy_point_uv": pred.points.uvz[np.flatnonzero(tie)[worst], :2].tolist()}
    out["isolated_sigma_xy_max_m"] = out["sigma_xy_max_m"] * ISOLATED_FACTOR
    out["isolated_sigma_z_max_m"] = out["sigma_z_max_m"] * ISOLATED_FACTOR
    return out


def verdict(stats: dict, max_xy: float | None, max_z: float | None) -> dict:
    """The tender check: the worst isolated-point sigmas against the required maxima (m)."""
    checks = {}
    for key, limit, value in (("xy", max_xy, stats["isolated_sigma_xy_max_m"]),
                              ("z", max_z, stats["isolated_sigma_z_max_m"])):
        if limit is not None:
            checks[key] = {"required_max_m": limit, "predicted_m": value,
                           "pass": bool(value <= limit)}
    ok = all(c["pass"] for c in checks.values()) if checks else None
    return {"checks": checks, "verdict": None if ok is None else ("pass" if ok else "fail")}
