"""Sparse Gauss-Newton / Levenberg-Marquardt for the bundle, with the Schur complement on points.

Unknowns: 6 exterior parameters per photo and the free or weighted calibration parameters (the
"camera" part, ``nc`` unknowns) and 3 coordinates per point. The normal matrix

    N = [[A, B], [Bᵀ, C]]      (A: nc x nc sparse, B: nc x 3P sparse, C: 3 x 3 blocks per point)

is reduced on the points (each image observation touches one point, so C is block diagonal and
inverted block by block): ``S = A - B·C⁻¹·Bᵀ``, ``S·Δc = -(g_c - B·C⁻¹·g_p)``, then
``Δp = -C⁻¹·(g_p + Bᵀ·Δc)``. S is Jacobi-scaled and factorised densely (Cholesky) up to
:data:`DENSE_LIMIT` unknowns; above, by a banded Cholesky after a reverse Cuthill-McKee ordering
(a block's photos then form a band about two strips wide: 0.3 s for 1,000 photos, where SuperLU
took 10 s), by SuperLU when even the band would be too large. Levenberg-Marquardt damping multiplies the
diagonal of A and C by ``1 + λ``. Ground coordinates are shifted to the block's local origin.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from toolbox.errors import ConvergenceError, InputDataError
from toolbox.triangulation.block import FIXED, WEIGHTED, Block, Options
from toolbox.triangulation.model import (
    EXTERIOR_NAMES,
    observation_residuals,
    rotations,
)
from toolbox.triangulation.schur import coupling, inverse_blocks, pair_structure, photo_schur

DENSE_LIMIT = 3000
BAND_LIMIT = 50_000_000  # values of a banded factor (400 MB) before sparse LU is used instead
EIGEN_LIMIT = 400  # full eigen-analysis of the reduced matrix up to this size, pivots above
SINGULAR_RATIO = 1e-13  # smallest / largest eigenvalue of the scaled reduced normal matrix
WEAK_RATIO = 1e-7  # below it: a warning (a parameter barely determined)
KIND_IMAGE, KIND_GROUND, KIND_CENTRE, KIND_CALIB, KIND_ATTITUDE = 0, 1, 2, 3, 4


@dataclass
class State:
    """Current unknowns: exterior (n, 6) and points (P, 3) in local coordinates, calibration."""

    exterior: np.ndarray
    points: np.ndarray
    calibration: np.ndarray
    extra: np.ndarray = field(default_factory=lambda: np.zeros(0))  # GNSS shift/drift, boresight

    def copy(self) -> State:
        return State(self.exterior.copy(), self.points.copy(), self.calibration.copy(),
                     self.extra.copy())


@dataclass
class Linearization:
    """Weighted residuals and Jacobians (rows = scalar observations)."""

    r: np.ndarray  # (rows,) weighted residuals
    jc: sp.csr_matrix | None  # (rows, nc)
    jp_rows: np.ndarray | None  # (rows, 3) point part of each row
    row_point: np.ndarray  # (rows,) point of the row, -1 for none
    kind: np.ndarray  # (rows,) KIND_*
    index: np.ndarray  # (rows,) into the observation arrays of its kind
    component: np.ndarray  # (rows,)
    depth_ok: bool = True
    img_w: np.ndarray | None = None  # (m, 6, 3) Jc_iᵀ·Jp_i of each active image observation
    img_photo: np.ndarray | None = None  # (m,) its photo
    img_point: np.ndarray | None = None  # (m,) its point

    @property
    def cost(self) -> float:
        return float(self.r @ self.r) if self.depth_ok else np.inf


class Problem:
    """One block with its active observations and weight factors, linearised on demand."""

    def __init__(self, block: Block, origin: np.ndarray) -> None:
        self.block = block
        self.origin = np.asarray(origin, dtype=float)
        self.obs_active = np.ones(len(block.obs_photo), dtype=bool)
        self.ground_active = np.isfinite(block.ground_xyz)
        self.centre_active = np.isfinite(block.centre_xyz)
        self.attitude_active = np.ones(block.attitude_obs.shape, dtype=bool)
        self.obs_factor = np.ones((len(block.obs_photo), 2))  # robust weight factors
        self.ground_factor = np.ones_like(block.ground_xyz)
        self.centre_factor = np.ones_like(block.centre_xyz)
        n = block.n_photos
        self.calib_column = np.full(block.calibration.shape, -1, dtype=np.int64)
        unknown = np.argwhere(block.calibration_mode != FIXED)
        for k, (cam, par) in enumerate(unknown):
            self.calib_column[cam, par] = 6 * n + k
        # extra unknowns after the calibration: GNSS shift and drift per strip, boresight
        self.extra_start = nc = 6 * n + len(unknown)
        g = block.n_groups
        self.shift_column = np.full((g, 3), -1, dtype=np.int64)
        self.drift_column = np.full((g, 3), -1, dtype=np.int64)
        self.boresight_column = np.full(3, -1, dtype=np.int64)
        for on, cols in ((block.gnss_shift, self.shift_column),
                         (block.gnss_drift, self.drift_column)):
            if on:
                cols[:] = nc + np.arange(3 * g).reshape(g, 3)
                nc += 3 * g
        if block.boresight:
            self.boresight_column[:] = nc + np.arange(3)
            nc += 3
        self.nc = nc
        self.warnings: list[str] = []

    def extras(self, state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """GNSS shift (G, 3), drift (G, 3) and boresight (3,) of ``state`` (zeros when not
        estimated)."""
        out = []
        for cols in (self.shift_column, self.drift_column, self.boresight_column):
            vals = np.zeros(cols.shape)
            on = cols >= 0
            vals[on] = state.extra[cols[on] - self.extra_start]
            out.append(vals)
        return out[0], out[1], out[2]

    # -- labels ----------------------------------------------------------------------------------
    def column_label(self, col: int) -> str:
        n = self.block.n_photos
        if col < 6 * n:
            return f"photo {self.block.photo_ids[col // 6]!r} {EXTERIOR_NAMES[col % 6]}"
        for what, cols in (("GNSS shift", self.shift_column), ("GNSS drift", self.drift_column)):
            if (cols == col).any():
                g, k = np.argwhere(cols == col)[0]
                return f"{what} of strip {g + 1} {'XYZ'[k]}"
        if (self.boresight_column == col).any():
            return f"boresight {EXTERIOR_NAMES[3 + int(np.flatnonzero(self.boresight_column == col)[0])]}"
        cam, par = np.argwhere(self.calib_column == col)[0]
        return self.block.calibration_label(int(cam), int(par))

    # -- linearisation ---------------------------------------------------------------------------
    def linearize(self, state: State, jacobians: bool = True) -> Linearization:
        b = self.block
        sel = np.flatnonzero(self.obs_active)
        ph, pt = b.obs_photo[sel], b.obs_point[sel]
        cam, kind, aspect = b.observation_cameras(sel)
        calib = state.calibration[cam]
        r_photo, dr_photo = rotations(state.exterior[:, 3:])
        out = observation_residuals(b.obs_xy[sel], state.exterior[ph], state.points[pt], calib,
                                    kind, aspect, jacobians, (r_photo[ph], dr_photo[ph]),
                                    **b.model_arguments(cam))
        f, depth = out[0], out[1]
        wimg = self.obs_factor[sel] / b.obs_sigma[sel]
        m = len(sel)
        r_parts = [(f * wimg).ravel()]
        rp = [np.repeat(pt, 2)]
        kinds = [np.full(2 * m, KIND_IMAGE)]
        idx = [np.repeat(sel, 2)]
        comp = [np.tile([0, 1], m)]
        # ground control (pseudo-observations of point coordinates)
        gi, gc = np.nonzero(self.ground_active)
        gpt = b.ground_point[gi]
        wg = self.ground_factor[gi, gc] / b.ground_sigma[gi, gc]
        fg = state.points[gpt, gc] + self.origin[gc] - b.ground_xyz[gi, gc]
        r_parts.append(fg * wg)
        rp.append(gpt)
        kinds.append(np.full(len(gi), KIND_GROUND))
        idx.append(gi)
        comp.append(gc)
        # GNSS projection centres
        hi, hc = np.nonzero(self.centre_active)
        hph = b.centre_photo[hi]
        wh = self.centre_factor[hi, hc] / b.centre_sigma[hi, hc]
        lever = r_photo @ b.lever_arm  # (n, 3) antenna offset on the ground axes
        shift, drift, bore = self.extras(state)
        hg, ht = b.centre_group[hi], b.centre_time[hi]
        fh = state.exterior[hph, hc] + lever[hph, hc] + self.origin[hc] - b.centre_xyz[hi, hc] \
            + shift[hg, hc] + drift[hg, hc] * ht
        r_parts.append(fh * wh)
        rp.append(np.full(len(hi), -1))
        kinds.append(np.full(len(hi), KIND_CENTRE))
        idx.append(hi)
        comp.append(hc)
        # IMU attitudes: angles of R·R(boresight), analytic derivatives
        ai, ac = np.nonzero(self.attitude_active)
        wa = 1.0 / b.attitude_sigma[ai, ac]
        att = attitude_residuals(state.exterior[b.attitude_photo, 3:], bore, b.attitude_obs,
                                 jacobians)
        fa = (att[0] if jacobians else att)[ai, ac]
        # weighted calibration parameters
        wc_cam, wc_par = np.nonzero(b.calibration_mode == WEIGHTED)
        wcal = 1.0 / b.calibration_sigma[wc_cam, wc_par]
        fc = state.calibration[wc_cam, wc_par] - b.calibration[wc_cam, wc_par]
        r_parts.append(fc * wcal)
        rp.append(np.full(len(wc_cam), -1))
        kinds.append(np.full(len(wc_cam), KIND_CALIB))
        idx.append(wc_cam)
        comp.append(wc_par)
        r_parts.append(fa * wa)
        rp.append(np.full(len(ai), -1))
        kinds.append(np.full(len(ai), KIND_ATTITUDE))
        idx.append(ai)
        comp.append(ac)
        r = np.concatenate(r_parts)
        lin = Linearization(r, None, None, np.concatenate(rp), np.concatenate(kinds),
                            np.concatenate(idx), np.concatenate(comp),
                            bool((depth < 0).all()) and bool(np.isfinite(r).all()))
        if not jacobians:
            return lin
        je, jpt, jcal = out[2], out[3], out[4]
        rows_all = len(r)
        # camera part
        rows_i = np.arange(2 * m).reshape(m, 2)
        r_idx = [np.repeat(rows_i[:, :, None], 6, axis=2).ravel()]
        c_idx = [np.broadcast_to((6 * ph)[:, None, None] + np.arange(6), (m, 2, 6)).ravel()]
        vals = [(je * wimg[:, :, None]).ravel()]
        for cam_k, par in np.argwhere(self.calib_column >= 0):
            on = np.flatnonzero(cam == cam_k)
            r_idx.append(rows_i[on].ravel())
            c_idx.append(np.full(2 * len(on), self.calib_column[cam_k, par]))
            vals.append((jcal[on, :, par] * wimg[on]).ravel())
        base = 2 * m + len(gi)
        r_idx.append(base + np.arange(len(hi)))
        c_idx.append(6 * hph + hc)
        vals.append(wh)
        if b.lever_arm.any():  # d(R·e)/d(angle)
            d_lever = dr_photo @ b.lever_arm  # (n, 3 angles, 3)
            for t in range(3):
                r_idx.append(base + np.arange(len(hi)))
                c_idx.append(6 * hph + 3 + t)
                vals.append(wh * d_lever[hph, t, hc])
        for cols, factor in ((self.shift_column, 1.0), (self.drift_column, ht)):
            if (cols >= 0).any():
                r_idx.append(base + np.arange(len(hi)))
                c_idx.append(cols[hg, hc])
                vals.append(wh * factor)
        base += len(hi)
        r_idx.append(base + np.arange(len(wc_cam)))
        c_idx.append(self.calib_column[wc_cam, wc_par])
        vals.append(wcal)
        base += len(wc_cam)
        if len(ai):  # attitude rows: d(angles)/d(photo angles) and d/d(boresight)
            a_ph = b.attitude_photo[ai]
            for t in range(3):
                r_idx.append(base + np.arange(len(ai)))
                c_idx.append(6 * a_ph + 3 + t)
                vals.append(wa * att[1][ai, ac, t])
                if self.boresight_column[t] >= 0:
                    r_idx.append(base + np.arange(len(ai)))
                    c_idx.append(np.full(len(ai), self.boresight_column[t]))
                    vals.append(wa * att[2][ai, ac, t])
        lin.jc = sp.csr_matrix((np.concatenate(vals), (np.concatenate(r_idx),
                                                       np.concatenate(c_idx))),
                               shape=(rows_all, self.nc))
        jp_rows = np.zeros((rows_all, 3))
        jp_rows[:2 * m] = (jpt * wimg[:, :, None]).reshape(2 * m, 3)
        jp_rows[2 * m + np.arange(len(gi)), gc] = wg
        lin.jp_rows = jp_rows
        lin.img_w = coupling(je, jpt, wimg)
        lin.img_photo, lin.img_point = ph, pt
        return lin

    def point_jacobian(self, lin: Linearization) -> sp.csr_matrix:
        rows = np.flatnonzero(lin.row_point >= 0)
        p = lin.row_point[rows]
        return sp.csr_matrix((lin.jp_rows[rows].ravel(),
                              (np.repeat(rows, 3), (3 * p[:, None] + np.arange(3)).ravel())),
                             shape=(len(lin.r), 3 * self.block.n_points))


class Normal:
    """Blocks of the normal equations ``N = JᵀJ = [[A, B], [Bᵀ, C]]``, gradient ``g = Jᵀr``.

    B is kept by its parts: the photo rows as the per-observation ``W_i`` (6 x 3) of
    :mod:`toolbox.triangulation.schur`, the other camera-side rows (calibration; GNSS and IMU
    unknowns touch no point) as a sparse ``b_rest``; the full sparse B (:attr:`b`, for the
    precision) and the point Jacobian (:attr:`jp`) are made on demand."""

    def __init__(self, problem: Problem, lin: Linearization) -> None:
        n_pts = problem.block.n_points
        self.problem, self.lin = problem, lin
        self.n6 = 6 * problem.block.n_photos
        jc = lin.jc
        self.a = (jc.T @ jc).tocsr()
        rows = lin.row_point >= 0
        p = lin.row_point[rows]
        jr = lin.jp_rows[rows]
        outer = (jr[:, :, None] * jr[:, None, :]).reshape(-1, 9)
        c = np.stack([np.bincount(p, weights=outer[:, k], minlength=n_pts) for k in range(9)],
                     axis=1).reshape(n_pts, 3, 3)
        unobserved = np.bincount(p, minlength=n_pts) == 0
        c[unobserved] = np.eye(3)  # points whose observations were all rejected: kept as they are
        self.c = c
        self.gp = np.stack([np.bincount(p, weights=jr[:, k] * lin.r[rows], minlength=n_pts)
                            for k in range(3)], axis=1)
        self.gc = jc.T @ lin.r
        self.w, self.obs_photo, self.obs_point = lin.img_w, lin.img_photo, lin.img_point
        self.structure = pair_structure(self.obs_photo, self.obs_point, problem.block.n_photos)
        self.b_rest = None
        if problem.nc > self.n6:
            img = np.flatnonzero(lin.kind == KIND_IMAGE)
            rest = jc[img][:, self.n6:].tocsc()
            jp = sp.csr_matrix((lin.jp_rows[img].ravel(), (np.repeat(np.arange(len(img)), 3),
                                (3 * lin.row_point[img][:, None] + np.arange(3)).ravel())),
                               shape=(len(img), 3 * n_pts))
            self.b_rest = (rest.T @ jp).tocsr()
        self._b = self._jp = None

    @property
    def jp(self) -> sp.csr_matrix:
        if self._jp is None:
            self._jp = self.problem.point_jacobian(self.lin)
        return self._jp

    @property
    def b(self) -> sp.csr_matrix:
        if self._b is None:
            self._b = (self.lin.jc.T @ self.jp).tocsr()
        return self._b

    def b_times(self, v: np.ndarray) -> np.ndarray:
        """``B·v`` for point values ``v`` (P, 3) -> (nc,)."""
        out = np.zeros(self.problem.nc)
        wv = np.einsum("mij,mj->mi", self.w, v[self.obs_point])
        for k in range(6):
            out[k:self.n6:6] = np.bincount(self.obs_photo, weights=wv[:, k],
                                           minlength=self.n6 // 6)
        if self.b_rest is not None:
            out[self.n6:] = self.b_rest @ v.ravel()
        return out

    def bt_times(self, dc: np.ndarray) -> np.ndarray:
        """``Bᵀ·dc`` -> (P, 3)."""
        n_pts = len(self.c)
        wt = np.einsum("mij,mi->mj", self.w, dc[:self.n6].reshape(-1, 6)[self.obs_photo])
        out = np.stack([np.bincount(self.obs_point, weights=wt[:, k], minlength=n_pts)
                        for k in range(3)], axis=1)
        if self.b_rest is not None:
            out += (self.b_rest.T @ dc[self.n6:]).reshape(-1, 3)
        return out


def normal_equations(problem: Problem, lin: Linearization) -> Normal:
    return Normal(problem, lin)


def block_inverse(c: np.ndarray, point_ids: list[str]) -> np.ndarray:
    """Inverse of the 3 x 3 point blocks; a singular one (a point without geometry) raises."""
    inv, ok = inverse_blocks(np.ascontiguousarray(c), 1e14)  # compiled, both cores
    bad = np.flatnonzero(~ok)
    if len(bad):
        names = ", ".join(repr(point_ids[i]) for i in bad[:5])
        raise InputDataError(f"{len(bad)} point(s) are not determined by their rays (nearly "
                             f"parallel rays or too few observations): {names}")
    return inv


def block_diagonal(blocks: np.ndarray) -> sp.bsr_matrix:
    n = len(blocks)
    return sp.bsr_matrix((blocks, np.arange(n), np.arange(n + 1)), shape=(3 * n, 3 * n))


def reduced_system(normal: Normal, damping: float, point_ids: list[str]):
    """``S`` (sparse), ``rhs`` and ``C⁻¹`` (P, 3, 3) for the damping ``λ``."""
    a = normal.a
    c = normal.c
    if damping:
        a = a + sp.diags(damping * a.diagonal())
        c = c + damping * np.einsum("pii->pi", c)[:, :, None] * np.eye(3)
    cinv = block_inverse(c, point_ids)
    nc, n6 = normal.problem.nc, normal.n6
    rows, cols, vals = photo_schur(normal.w, cinv, normal.obs_point, normal.structure, n6 // 6)
    parts = [(rows, cols, vals)]
    keep = np.unique(normal.b_rest.nonzero()[0]) if normal.b_rest is not None else []
    if len(keep):  # calibration rows (GNSS/IMU rows of B are 0): B_r·C⁻¹·Bᵀ, sparse products
        br = normal.b_rest[keep]
        d = (br @ block_diagonal(cinv)).tocsr()  # (r, 3P)
        rr = (d @ br.T).tocoo()
        parts.append((n6 + keep[rr.row], n6 + keep[rr.col], rr.data))
        dd = d.toarray().reshape(len(keep), -1, 3)[:, normal.obs_point]  # (r, m, 3)
        x = np.einsum("rmk,mjk->rmj", dd, normal.w)  # (r, m, 6)
        cross = np.zeros((len(keep), n6))
        for j in range(6):
            cross[:, j::6] = np.stack([np.bincount(normal.obs_photo, weights=x[q, :, j],
                                                   minlength=n6 // 6)
                                       for q in range(len(keep))])
        rr_, cc_ = np.nonzero(cross)
        parts.append((n6 + keep[rr_], cc_, cross[rr_, cc_]))
        parts.append((cc_, n6 + keep[rr_], cross[rr_, cc_]))
    rows, cols, vals = (np.concatenate(v) for v in zip(*parts, strict=True))
    bcb = sp.csr_matrix((vals, (rows, cols)), shape=(nc, nc))
    s = (a - bcb).tocsr()
    rhs = -(normal.gc - normal.b_times(np.einsum("pij,pj->pi", cinv, normal.gp)))
    return s, rhs, cinv


class SingularError(InputDataError):
    pass


def _scaled(s: sp.csr_matrix, problem: Problem) -> tuple[np.ndarray, np.ndarray | sp.csc_matrix]:
    diag = s.diagonal()
    zero = np.flatnonzero(~(diag > 0))
    if len(zero):
        names = ", ".join(problem.column_label(int(i)) for i in zero[:5])
        raise SingularError(f"the normal matrix is singular: no observation determines "
                            f"{names}")
    d = 1.0 / np.sqrt(diag)
    return d, sp.diags(d) @ s @ sp.diags(d)


def diagnose(s: sp.csr_matrix, problem: Problem) -> None:
    """Raise :class:`SingularError` naming the parameters of a (nearly) singular direction:
    the smallest eigenvector of the Jacobi-scaled matrix (small systems) or the smallest
    Cholesky pivots (dense systems up to :data:`DENSE_LIMIT`)."""
    import scipy.linalg as la

    d, ss = _scaled(s, problem)
    if problem.nc > DENSE_LIMIT:
        return
    dense = ss.toarray()
    if problem.nc <= EIGEN_LIMIT:
        vals, vecs = np.linalg.eigh(dense)
        ratio, weak = vals[0] / vals[-1], np.argsort(-np.abs(vecs[:, 0]))[:4]
    else:
        try:
            pivots = np.diag(la.cholesky(dense, lower=True)) ** 2
        except la.LinAlgError:
            pivots = np.zeros(len(dense))
        ratio, weak = pivots.min() / pivots.max(), np.argsort(pivots)[:4]
    names = ", ".join(problem.column_label(int(i)) for i in weak)
    if ratio < SINGULAR_RATIO:
        raise SingularError(f"the normal matrix is near-singular (ratio {ratio:.1e}): weak "
                            f"geometry in {names}; add control, tie points or fix those "
                            "parameters")
    if ratio < WEAK_RATIO:
        problem.warnings.append(f"weak geometry (eigenvalue ratio {ratio:.1e}) in {names}: "
                                "check their standard deviations and correlations")


def banded_solve(s: sp.spmatrix, rhs: np.ndarray) -> np.ndarray | None:
    """Solve the symmetric positive definite ``s·x = rhs`` by a banded Cholesky factorisation
    (LAPACK ``pbtrf``) after a reverse Cuthill-McKee ordering, which brings a block's photos
    into a band about as wide as the photos of two strips; None when the band would not fit
    :data:`BAND_LIMIT` values (then sparse LU)."""
    import scipy.linalg as la
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    s = sp.csr_matrix(s)
    perm = reverse_cuthill_mckee(s, symmetric_mode=True)
    p = s[perm][:, perm].tocoo()
    upper = p.row <= p.col
    width = int((p.col - p.row)[upper].max(initial=0))
    n = s.shape[0]
    if (width + 1) * n > BAND_LIMIT:
        return None
    band = np.zeros((width + 1, n))
    band[width + p.row[upper] - p.col[upper], p.col[upper]] = p.data[upper]
    y = la.solveh_banded(band, rhs[perm], check_finite=False)
    x = np.empty_like(y)
    x[perm] = y
    return x


def solve_reduced(s: sp.csr_matrix, rhs: np.ndarray, problem: Problem) -> np.ndarray:
    import scipy.linalg as la
    from scipy.sparse.linalg import splu

    d, ss = _scaled(s, problem)
    try:
        if problem.nc <= DENSE_LIMIT:
            x = la.cho_solve(la.cho_factor(ss.toarray()), d * rhs)
        else:
            x = banded_solve(ss, d * rhs)
            if x is None:
                x = splu(ss.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(d * rhs)
    except (np.linalg.LinAlgError, la.LinAlgError, RuntimeError, ValueError):
        diagnose(s, problem)
        raise SingularError("the normal matrix is singular: the block's geometry or datum "
                            "is too weak") from None
    if not np.isfinite(x).all():
        raise SingularError("the normal matrix is singular: the block's geometry or datum "
                            "is too weak")
    return d * x


def apply_step(problem: Problem, state: State, dc: np.ndarray, dp: np.ndarray) -> State:
    new = state.copy()
    n = problem.block.n_photos
    new.exterior += dc[:6 * n].reshape(n, 6)
    cols = problem.calib_column
    on = cols >= 0
    new.calibration[on] += dc[cols[on]]
    new.extra = new.extra + dc[problem.extra_start:]
    new.points += dp.reshape(-1, 3)
    return new


def worst_observations(problem: Problem, lin: Linearization, count: int = 5) -> str:
    b = problem.block
    order = np.argsort(-np.abs(np.nan_to_num(lin.r, nan=np.inf)))[:count]
    parts = []
    for row in order:
        k, i = int(lin.kind[row]), int(lin.index[row])
        if k == KIND_IMAGE:
            what = f"point {b.point_ids[b.obs_point[i]]!r} on photo {b.photo_ids[b.obs_photo[i]]!r}"
        elif k == KIND_GROUND:
            what = f"control {b.point_ids[b.ground_point[i]]!r} {'XYZ'[lin.component[row]]}"
        elif k == KIND_CENTRE:
            what = f"GNSS centre of photo {b.photo_ids[b.centre_photo[i]]!r}"
        elif k == KIND_ATTITUDE:
            what = f"IMU {EXTERIOR_NAMES[3 + int(lin.component[row])]} of photo " \
                   f"{b.photo_ids[b.attitude_photo[i]]!r}"
        else:
            what = b.calibration_label(i, int(lin.component[row]))
        parts.append(f"{what} ({lin.r[row]:+.3g} sigma)")
    return "; ".join(parts)


def least_squares(problem: Problem, state: State, options: Options, check: bool = True
                  ) -> tuple[State, Linearization, int]:
    """Levenberg-Marquardt to convergence; returns the state, its linearisation, iterations."""
    lin = problem.linearize(state)
    if not lin.depth_ok:
        raise ConvergenceError("the start values put points behind their cameras; check the "
                               "approximate orientations (worst: "
                               f"{worst_observations(problem, lin)})")
    damping = 1e-6
    cost = lin.cost
    for iteration in range(1, options.max_iterations + 1):
        normal = normal_equations(problem, lin)
        if check and iteration == 1:
            diagnose(reduced_system(normal, 0.0, problem.block.point_ids)[0], problem)
        while True:
            s, rhs, cinv = reduced_system(normal, damping, problem.block.point_ids)
            dc = solve_reduced(s, rhs, problem)
            dp = -np.einsum("pij,pj->pi", cinv, normal.gp + normal.bt_times(dc))
            trial = apply_step(problem, state, dc, dp)
            trial_lin = problem.linearize(trial, jacobians=False)
            if trial_lin.cost <= cost:
                break
            damping *= 10.0
            if damping > 1e12:
                raise ConvergenceError(
                    f"bundle adjustment diverged at iteration {iteration} (weighted sum of "
                    f"squares {cost:.6g} cannot be decreased); worst observations: "
                    f"{worst_observations(problem, lin)}")
        decrease = cost - trial_lin.cost
        state, cost = trial, trial_lin.cost
        lin = problem.linearize(state)
        damping = max(damping / 10.0, 1e-12)
        small_step = np.abs(dp).max(initial=0.0) < 1e-9 and np.abs(dc).max(initial=0.0) < 1e-9
        if decrease <= options.tolerance * max(cost, 1e-30) or small_step:
            return state, lin, iteration
    raise ConvergenceError(f"bundle adjustment did not converge in {options.max_iterations} "
                           f"iterations (weighted sum of squares {cost:.6g}); worst "
                           f"observations: {worst_observations(problem, lin)}")


def attitude_residuals(angles: np.ndarray, boresight: np.ndarray, observed: np.ndarray,
                       jacobians: bool = False):
    """Angles (omega, phi, kappa) of ``M = R(angles)·R(boresight)`` minus ``observed`` (a, 3),
    rad, wrapped to (-π, π]; ``R = Rx(ω)·Ry(φ)·Rz(κ)`` as
    :func:`~toolbox.triangulation.model.rotations`. With ``jacobians`` also their derivatives
    (a, 3, 3) by the photo's angles and by the boresight angles (analytic: ``ω = atan2(-M₁₂,
    M₂₂)``, ``φ = asin(M₀₂)``, ``κ = atan2(-M₀₁, M₀₀)`` differentiated through ``dM``)."""
    r, dr = rotations(angles)
    rb, drb = rotations(np.asarray(boresight, dtype=float).reshape(1, 3))
    m = r @ rb[0]
    omega = np.arctan2(-m[:, 1, 2], m[:, 2, 2])
    phi = np.arcsin(np.clip(m[:, 0, 2], -1.0, 1.0))
    kappa = np.arctan2(-m[:, 0, 1], m[:, 0, 0])
    diff = np.column_stack([omega, phi, kappa]) - observed
    res = (diff + np.pi) % (2 * np.pi) - np.pi
    if not jacobians:
        return res

    def d_angles(dm: np.ndarray) -> np.ndarray:  # dm (a, 3 params, 3, 3) -> (a, 3 angles, 3)
        out = np.empty((len(m), 3, 3))
        n_om = m[:, 1, 2] ** 2 + m[:, 2, 2] ** 2
        n_ka = m[:, 0, 1] ** 2 + m[:, 0, 0] ** 2
        out[:, 0] = (-m[:, 2, 2, None] * dm[:, :, 1, 2] + m[:, 1, 2, None] * dm[:, :, 2, 2]) \
            / n_om[:, None]
        out[:, 1] = dm[:, :, 0, 2] / np.sqrt(np.maximum(1.0 - m[:, 0, 2] ** 2, 1e-300))[:, None]
        out[:, 2] = (-m[:, 0, 0, None] * dm[:, :, 0, 1] + m[:, 0, 1, None] * dm[:, :, 0, 0]) \
            / n_ka[:, None]
        return out

    return res, d_angles(dr @ rb[0]), d_angles(np.einsum("aij,tjk->atik", r, drb[0]))
