"""Independent-model block adjustment (004 sl. 5-16; 002 par. 1.5): models formed by relative
orientation are joined by their tie points (and projection centres) and brought onto the ground
control, all at once.

- ``planimetric``: per model a plane conformal transformation ``X = Xu + a·x - b·y``,
  ``Y = Yu + a·y + b·x`` (4 unknowns, linear; 004 sl. 9), per tie point X, Y; control X, Y are
  known (the slides' error-free control). Equations: 2 per point per model.
- ``spatial``: per model a 7-parameter similarity ``P = λ·R(ω, φ, κ)·p + T``
  (:mod:`toolbox.photogrammetry.absolute`'s convention), per tie point X, Y, Z; the known
  components of control points (XYZ, XY-only or Z-only: 002 par. 1.5.2 allows 2 XY + 3 Z) are
  fixed. Equations: 3 per point per model; solved by Levenberg-Marquardt (scipy, sparse
  Jacobian) from a chained closed-form start.

Points in one model only (isolated points, about 33 % less precise than tie points: 004 sl. 22)
are determined by their model's transformation alone (no redundancy). Residuals: transformed
model point minus the adjusted (or known) ground point (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from toolbox.errors import ConvergenceError, InputDataError, ParameterError


@dataclass
class ModelsRequest:
    """Model coordinates (one row per point per model) and ground control.

    model_ids (m,), point_ids (m,), xyz (m, 3) model coordinates; control_ids, control_xyz
    (c, 3) with NaN for unknown components; mode ``planimetric`` or ``spatial``."""

    model_ids: list[str]
    point_ids: list[str]
    xyz: np.ndarray
    control_ids: list[str]
    control_xyz: np.ndarray
    mode: str = "spatial"


@dataclass
class ModelsResult:
    models: list[str]
    parameters: np.ndarray  # (n, 4) Xu, Yu, a, b  or (n, 7) TX, TY, TZ, omega, phi, kappa, scale
    points: list[str]
    ground: np.ndarray  # (P, 2 or 3) adjusted ground coordinates
    unknowns: int
    equations: int
    redundancy: int
    sigma0_m: float
    residuals: np.ndarray  # (m, 2 or 3) per observation
    notes: list[str] = field(default_factory=list)


def _index(request: ModelsRequest, dims: int):
    if request.mode not in ("planimetric", "spatial"):
        raise ParameterError("MODE", f"must be planimetric or spatial, got {request.mode!r}")
    xyz = np.asarray(request.xyz, dtype=float).reshape(-1, 3)
    if not np.isfinite(xyz[:, :dims]).all():
        raise InputDataError("model coordinates must be finite numbers")
    seen = set()
    for m, p in zip(request.model_ids, request.point_ids, strict=True):
        if (m, p) in seen:
            raise InputDataError(f"point {p!r} is listed twice in model {m!r}")
        seen.add((m, p))
    models = list(dict.fromkeys(request.model_ids))
    points = list(dict.fromkeys(request.point_ids))
    mi = np.array([models.index(m) for m in request.model_ids])
    where = {p: k for k, p in enumerate(points)}
    pi = np.array([where[p] for p in request.point_ids])
    known = np.full((len(points), 3), np.nan)
    for cid, c in zip(request.control_ids, np.asarray(request.control_xyz, float).reshape(-1, 3),
                      strict=True):
        if cid in where:
            known[where[cid]] = c
    known = known[:, :dims]
    return xyz, models, points, mi, pi, known


def planimetric(request: ModelsRequest) -> ModelsResult:
    """The linear planimetric adjustment (see the module docstring)."""
    from scipy.sparse.linalg import spsolve

    xyz, models, points, mi, pi, known = _index(request, 2)
    n, m = len(models), len(mi)
    free = np.isnan(known).any(axis=1)
    col = np.full(len(points), -1)
    col[free] = 4 * n + 2 * np.arange(int(free.sum()))
    # solved centred (each model at its centroid, the control at theirs): with raw projected
    # coordinates the columns of Xu and a are nearly parallel and the normal equations lose
    # the millimetres (or look singular); the parameters are moved back below
    centre = np.array([xyz[mi == j, :2].mean(axis=0) for j in range(n)])
    ground0 = np.nanmean(known, axis=0) if (~free).any() else np.zeros(2)
    known = known - ground0
    x, y = xyz[:, 0] - centre[mi, 0], xyz[:, 1] - centre[mi, 1]
    rows, cols, vals = [], [], []
    rhs = np.zeros(2 * m)
    for k in range(m):
        base = 4 * mi[k]
        # vx = Xu + a·x - b·y - X ;  vy = Yu + a·y + b·x - Y
        for r, coefs in ((2 * k, (1.0, 0.0, x[k], -y[k])), (2 * k + 1, (0.0, 1.0, y[k], x[k]))):
            rows += [r] * 4
            cols += [base, base + 1, base + 2, base + 3]
            vals += list(coefs)
            axis = r - 2 * k
            if free[pi[k]]:
                rows.append(r)
                cols.append(col[pi[k]] + axis)
                vals.append(-1.0)
            else:
                rhs[r] = known[pi[k], axis]
    unknowns = 4 * n + 2 * int(free.sum())
    a = sp.csr_matrix((vals, (rows, cols)), shape=(2 * m, unknowns))
    redundancy = 2 * m - unknowns
    normal = (a.T @ a).tocsc()
    _check_datum(normal, "planimetric", redundancy)
    sol = spsolve(normal, a.T @ rhs)
    v = (a @ sol - rhs).reshape(m, 2)
    ground = known.copy()
    ground[free] = sol[4 * n:].reshape(-1, 2)
    sigma0 = math.sqrt(float((v ** 2).sum()) / redundancy) if redundancy > 0 else math.nan
    params = sol[:4 * n].reshape(n, 4).copy()
    a_, b_ = params[:, 2], params[:, 3]  # X = Xu' + a·(x - cx) - b·(y - cy) + X0
    params[:, 0] += ground0[0] - a_ * centre[:, 0] + b_ * centre[:, 1]
    params[:, 1] += ground0[1] - a_ * centre[:, 1] - b_ * centre[:, 0]
    return ModelsResult(models, params, points, ground + ground0, unknowns, 2 * m,
                        redundancy, sigma0, v)


def _check_datum(normal, mode: str, redundancy: int) -> None:
    """Refuse a negative redundancy and a singular normal matrix (eigenvalues of the scaled
    matrix up to 400 unknowns, a sparse LU factorisation above)."""
    from scipy.sparse.linalg import splu

    if redundancy < 0:
        raise InputDataError(f"the {mode} block has more unknowns than equations (redundancy "
                             f"{redundancy}): add control or tie points")
    d = 1.0 / np.sqrt(np.maximum(normal.diagonal(), 1e-300))
    scaled = (sp.diags(d) @ normal @ sp.diags(d)).tocsc()
    if scaled.shape[0] <= 400:
        vals = np.linalg.eigvalsh(scaled.toarray())
        singular = vals[0] < 1e-12 * vals[-1]
    else:
        try:
            lu = splu(scaled)
            pivots = np.abs(lu.U.diagonal())
            singular = pivots.min() < 1e-12 * pivots.max()
        except RuntimeError:
            singular = True
    if singular:
        raise InputDataError(f"the {mode} block is not determined (datum defect or models not "
                             "connected): add control points (planimetric: >= 2 XY; spatial: "
                             ">= 2 XY and >= 3 Z) or tie points between models")


def spatial(request: ModelsRequest) -> ModelsResult:
    """The 7-parameter spatial adjustment (see the module docstring)."""
    from scipy.optimize import least_squares

    from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

    xyz, models, points, mi, pi, known = _index(request, 3)
    n, m, p = len(models), len(mi), len(points)
    free = np.isnan(known)  # (P, 3) unknown components
    n_free = int(free.sum())
    unknowns = 7 * n + n_free
    redundancy = 3 * m - unknowns
    if redundancy < 0:
        raise InputDataError(f"the spatial block has more unknowns than equations (redundancy "
                             f"{redundancy}): add control or tie points")
    xy_known = int((~free[:, :2]).all(axis=1).sum())
    z_known = int((~free[:, 2]).sum())
    if xy_known < 2 or z_known < 3:
        raise InputDataError(f"datum defect: the spatial block needs >= 2 planimetric and >= 3 "
                             f"height control points; it has {xy_known} and {z_known}")
    origin = np.nanmean(known, axis=0)
    known_l = known - origin
    params, notes = _start(xyz, models, mi, pi, known_l, free)
    ground = np.full((p, 3), np.nan)
    rot0 = rotation_matrix(params[:, 3], params[:, 4], params[:, 5])
    est = params[mi, 6:7] * np.einsum("mij,mj->mi", rot0[mi], xyz) + params[mi, :3]
    for k in range(p):
        ground[k] = est[pi == k].mean(axis=0)
    ground = np.where(free, ground, known_l)
    free_idx = np.flatnonzero(free.ravel())

    def unpack(v):
        pars = v[:7 * n].reshape(n, 7)
        g = known_l.copy().ravel()
        g[free_idx] = v[7 * n:]
        return pars, g.reshape(p, 3)

    def fun(v):
        pars, g = unpack(v)
        rot = rotation_matrix(pars[:, 3], pars[:, 4], pars[:, 5])
        t = pars[mi]
        est = t[:, 6:7] * np.einsum("mij,mj->mi", rot[mi], xyz) + t[:, :3]
        return (est - g[pi]).ravel()

    rows_s, cols_s = [], []
    for k in range(m):
        for a in range(3):
            r = 3 * k + a
            rows_s += [r] * 7
            cols_s += list(range(7 * mi[k], 7 * mi[k] + 7))
            if free[pi[k], a]:
                rows_s.append(r)
                cols_s.append(7 * n + int(np.searchsorted(free_idx, 3 * pi[k] + a)))
    sparsity = sp.coo_matrix((np.ones(len(rows_s)), (rows_s, cols_s)), shape=(3 * m, unknowns))
    x0 = np.concatenate([params.ravel(), ground.ravel()[free_idx]])
    sol = least_squares(fun, x0, jac_sparsity=sparsity, method="trf", x_scale="jac",
                        xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=500,
                        tr_options={"atol": 1e-14, "btol": 1e-14})
    if not sol.success or not np.isfinite(sol.x).all():
        raise ConvergenceError(f"the spatial independent-model adjustment did not converge: "
                               f"{sol.message}")
    v = fun(sol.x).reshape(m, 3)
    pars, g = unpack(sol.x.copy())
    pars[:, :3] += origin
    pars[:, 3:6] = [angles_from_matrix(rotation_matrix(*a)) for a in pars[:, 3:6]]
    sigma0 = math.sqrt(float((v ** 2).sum()) / redundancy) if redundancy > 0 else math.nan
    return ModelsResult(models, pars, points, g + origin, unknowns, 3 * m, redundancy, sigma0, v,
                        notes)


def _start(xyz, models, mi, pi, known, free):
    """Start values (n, 7): models chained in a free frame (closed-form similarities on >= 3
    common points, seeded by the largest model), then the frame put on the ground: a spatial
    similarity on >= 3 full control points, else a plane similarity on the XY points and a
    height shift on the Z points (near-level models)."""
    from toolbox.photogrammetry.absolute import fit_similarity
    from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

    n, p = len(models), len(known)
    params = np.full((n, 7), np.nan)
    frame = np.full((p, 3), np.nan)
    seed = int(np.argmax(np.bincount(mi, minlength=n)))
    params[seed] = [0, 0, 0, 0, 0, 0, 1.0]
    rows = np.flatnonzero(mi == seed)
    frame[pi[rows]] = xyz[rows]
    placed = np.zeros(n, dtype=bool)
    placed[seed] = True
    for _ in range(n - 1):
        best, best_rows = -1, None
        for j in np.flatnonzero(~placed):
            rows = np.flatnonzero((mi == j) & np.isfinite(frame[pi]).all(axis=1))
            if len(rows) >= 3 and (best_rows is None or len(rows) > len(best_rows)):
                best, best_rows = j, rows
        if best < 0:
            break
        fit = fit_similarity(xyz[best_rows], frame[pi[best_rows]])
        params[best] = [*fit.translation, *fit.angles, fit.scale]
        placed[best] = True
        rows = np.flatnonzero(mi == best)
        est = fit.scale * xyz[rows] @ rotation_matrix(*fit.angles).T + fit.translation
        new = ~np.isfinite(frame[pi[rows]]).all(axis=1)
        frame[pi[rows[new]]] = est[new]
    if not placed.all():
        names = [models[j] for j in np.flatnonzero(~placed)]
        raise InputDataError(f"model(s) {', '.join(names[:5])} share fewer than 3 points with "
                             "the other models: the block is not connected")
    full = ~free.any(axis=1) & np.isfinite(frame).all(axis=1)
    if full.sum() >= 3:
        fit = fit_similarity(frame[full], known[full])
        lam, rot, t = fit.scale, rotation_matrix(*fit.angles), fit.translation
        how = f"spatial similarity on {int(full.sum())} full control points"
    else:
        xy = ~free[:, :2].any(axis=1)
        a = frame[xy, 0] + 1j * frame[xy, 1]
        b = known[xy, 0] + 1j * known[xy, 1]
        am, bm = a.mean(), b.mean()
        c = np.vdot(a - am, b - bm) / np.vdot(a - am, a - am)
        lam, kappa = abs(c), float(np.angle(c))
        rot = rotation_matrix(0.0, 0.0, kappa)
        txy = bm - c * am
        z = ~free[:, 2]
        t = np.array([txy.real, txy.imag, float(np.mean(known[z, 2] - lam * frame[z, 2]))])
        how = "plane similarity on the XY control and a height shift on the Z control"
    for j in range(n):
        r = rotation_matrix(*params[j, 3:6])
        params[j, :3] = lam * rot @ params[j, :3] + t
        params[j, 3:6] = angles_from_matrix(rot @ r)
        params[j, 6] *= lam
    return params, [f"start values: models chained in a free frame, then a {how}"]


def adjust_models(request: ModelsRequest) -> ModelsResult:
    return planimetric(request) if request.mode == "planimetric" else spatial(request)
