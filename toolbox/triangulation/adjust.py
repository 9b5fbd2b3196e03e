"""The bundle block adjustment: checks, datum, robust stage, least squares, data snooping,
precision (Baarda's reliability theory, domain: 004 sl. 26-29).

Sequence: validate the block (one-line errors), check the datum, optionally a Huber IRLS stage
(weights ``min(1, k/|e|)`` on the standardised residuals ``e``) to get near the blunder-free
solution, then plain least squares and data snooping: the w-test ``w_i = v_i / (σ_i·√r_i)``
(a priori σ0 = 1, redundancy numbers ``r_i`` from :mod:`toolbox.triangulation.precision`) of
every image, control, GNSS and IMU observation; the largest ``|w| > critical_w`` is rejected and the
adjustment repeated, one observation at a time, until none is left (or ``max_rejections``).
A tie point with only two rays cannot say which ray is wrong: both go.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from toolbox.errors import InputDataError
from toolbox.triangulation.block import WEIGHTED, Block, Options, Rejection, Solution
from toolbox.triangulation.model import observation_residuals, rotations
from toolbox.triangulation.precision import cofactors
from toolbox.triangulation.solver import (
    KIND_ATTITUDE,
    KIND_CALIB,
    KIND_GROUND,
    KIND_IMAGE,
    Problem,
    State,
    attitude_residuals,
    least_squares,
    normal_equations,
)


class DatumError(InputDataError):
    """The control does not fix the block's position, scale and orientation."""


def validate(block: Block) -> None:
    """One-line errors for observations the adjustment cannot use."""
    b = block
    n, p, m = b.n_photos, b.n_points, len(b.obs_photo)
    if m == 0:
        raise InputDataError("the block has no image observations")
    for name, idx, size in (("photo", b.obs_photo, n), ("point", b.obs_point, p),
                            ("control point", b.ground_point, p),
                            ("GNSS photo", b.centre_photo, n)):
        if len(idx) and (idx.min() < 0 or idx.max() >= size):
            raise InputDataError(f"a {name} index is outside 0..{size - 1}")
    if not (np.isfinite(b.obs_xy).all()):
        raise InputDataError("image observations must be finite numbers")
    bad = np.flatnonzero(~(b.obs_sigma > 0).all(axis=1))
    if len(bad):
        i = bad[0]
        raise InputDataError(f"image sigma of point {b.point_ids[b.obs_point[i]]!r} on photo "
                             f"{b.photo_ids[b.obs_photo[i]]!r} must be > 0, got "
                             f"{b.obs_sigma[i].tolist()}")
    for what, xyz, sig, ids in (("control point", b.ground_xyz, b.ground_sigma,
                                 [b.point_ids[i] for i in b.ground_point]),
                                ("GNSS centre of photo", b.centre_xyz, b.centre_sigma,
                                 [b.photo_ids[i] for i in b.centre_photo])):
        wrong = np.isfinite(xyz) & ~(sig > 0)
        if wrong.any():
            i, k = np.argwhere(wrong)[0]
            raise InputDataError(f"{what} {ids[i]!r}: sigma {'XYZ'[k]} must be > 0, got "
                                 f"{sig[i, k]!r}")
    if len(b.centre_photo) and not len(b.centre_group) and not len(b.centre_time):
        # centres set after construction: one strip, time zero (as Block's defaults)
        b.centre_group = np.zeros(len(b.centre_photo), dtype=np.int64)
        b.centre_time = np.zeros(len(b.centre_photo))
    if len(b.centre_group) != len(b.centre_photo) or len(b.centre_time) != len(b.centre_photo) \
            or (len(b.centre_group) and b.centre_group.min() < 0):
        raise InputDataError("every GNSS centre needs a strip (>= 0) and a time")
    if len(b.attitude_photo) and (b.attitude_photo.min() < 0 or b.attitude_photo.max() >= n):
        raise InputDataError(f"an IMU photo index is outside 0..{n - 1}")
    if len(b.attitude_photo) and not (np.isfinite(b.attitude_obs).all()
                                      and (b.attitude_sigma > 0).all()):
        i = int(np.argwhere(~(np.isfinite(b.attitude_obs) & (b.attitude_sigma > 0)))[0, 0])
        raise InputDataError(f"IMU attitude of photo {b.photo_ids[b.attitude_photo[i]]!r}: "
                             f"angles must be finite and sigmas > 0, got "
                             f"{b.attitude_obs[i].tolist()} / {b.attitude_sigma[i].tolist()}")
    if b.boresight and not len(b.attitude_photo):
        raise InputDataError("boresight angles can be estimated only with IMU attitudes")
    weighted = (b.calibration_mode == WEIGHTED) & ~(b.calibration_sigma > 0)
    if weighted.any():
        cam, par = np.argwhere(weighted)[0]
        raise InputDataError(f"{b.calibration_label(cam, par)} is weighted: its sigma must be "
                             f"> 0, got {b.calibration_sigma[cam, par]!r}")
    pairs = Counter(zip(b.obs_photo.tolist(), b.obs_point.tolist(), strict=True))
    dup = [k for k, v in pairs.items() if v > 1]
    if dup:
        ph, pt = dup[0]
        raise InputDataError(f"point {b.point_ids[pt]!r} is measured {pairs[dup[0]]} times on "
                             f"photo {b.photo_ids[ph]!r} (duplicate measurements; "
                             f"{len(dup)} such pair(s))")
    rays = np.bincount(b.obs_point, minlength=p)
    full = np.zeros(p, dtype=bool)
    full[b.ground_point[np.isfinite(b.ground_xyz).all(axis=1)]] = True
    once = np.flatnonzero((rays < 2) & ~full)
    if len(once):
        names = ", ".join(repr(b.point_ids[i]) for i in once[:5])
        raise InputDataError(f"{len(once)} point(s) are measured on fewer than 2 photos and are "
                             f"not full (XYZ) control, so they cannot be intersected: {names}")
    lonely = np.flatnonzero(np.bincount(b.obs_photo, minlength=n) == 0)
    if len(lonely):
        raise InputDataError(f"photo(s) {', '.join(repr(b.photo_ids[i]) for i in lonely[:5])} "
                             "have no image observations")


def check_datum(block: Block) -> None:
    """At least 2 planimetric and 3 height control points (e.g. 2 full + 1 height), or GNSS
    projection centres on >= 3 photos; otherwise :class:`DatumError` naming what is missing."""
    b = block
    known = np.isfinite(b.ground_xyz)
    xy = sorted({b.point_ids[i] for i in b.ground_point[known[:, 0] & known[:, 1]]})
    z = sorted({b.point_ids[i] for i in b.ground_point[known[:, 2]]})
    centres = {int(i) for i in b.centre_photo[np.isfinite(b.centre_xyz).all(axis=1)]}
    full = len(set(xy) & set(z))
    if len(xy) >= 2 and len(z) >= 3:
        return
    # GNSS with an unknown shift per strip gives the scale, the azimuth and the pitch of the
    # block but neither its position nor its roll about the strips (each strip's centres move
    # freely along their own line): a full control point and a second height point besides
    if len(centres) >= 3 and (not (b.gnss_shift or b.gnss_drift) or (full >= 1 and len(z) >= 2)):
        return
    if len(centres) >= 3:
        raise DatumError("datum defect: GNSS centres with an unknown shift or drift per strip "
                         "fix neither the block's position nor its roll; add at least 1 full "
                         f"(XYZ) and 1 more height control point (it has {full} full, {len(z)} "
                         "height)")
    missing = []
    if len(xy) < 2:
        missing.append(f"{2 - len(xy)} more planimetric (X, Y) control point(s)")
    if len(z) < 3:
        missing.append(f"{3 - len(z)} more height (Z) control point(s)")
    raise DatumError(f"datum defect: the block needs at least 2 planimetric and 3 height control "
                     f"points (e.g. 2 full XYZ + 1 Z) or GNSS projection centres on >= 3 photos; "
                     f"it has {len(xy)} planimetric ({', '.join(xy) or 'none'}), {len(z)} height "
                     f"({', '.join(z) or 'none'}) and {len(centres)} GNSS centre(s): add "
                     f"{' and '.join(missing)}")


def _huber(problem: Problem, state: State, options: Options) -> State:
    b = problem.block
    for _ in range(5):
        state, lin, _ = least_squares(problem, state, options)
        cam, kind, aspect = b.observation_cameras()
        f, _ = observation_residuals(b.obs_xy, state.exterior[b.obs_photo],
                                     state.points[b.obs_point], state.calibration[cam], kind,
                                     aspect, jacobians=False, **b.model_arguments(cam))
        e = np.abs(f / b.obs_sigma)
        problem.obs_factor = np.sqrt(np.minimum(1.0, options.huber_k / np.maximum(e, 1e-300)))
        eg = np.abs((state.points[b.ground_point] + problem.origin - b.ground_xyz)
                    / b.ground_sigma)
        problem.ground_factor = np.sqrt(np.minimum(1.0, options.huber_k /
                                                   np.nan_to_num(np.maximum(eg, 1e-300),
                                                                 nan=1.0)))
    problem.obs_factor[:] = 1.0
    problem.ground_factor[:] = 1.0
    return state


def _reject(problem: Problem, lin, w: np.ndarray, r: np.ndarray, options: Options
            ) -> Rejection | None:
    b = problem.block
    testable = (lin.kind != KIND_CALIB) & (r > 1e-3) & np.isfinite(w)
    # never reject the control the datum rests on (2 XY + 3 Z points, unless >= 3 GNSS centres)
    if (problem.centre_active.all(axis=1)).sum() < 3:
        active = problem.ground_active
        xy_points = int((active[:, 0] & active[:, 1]).sum())
        z_points = int(active[:, 2].sum())
        ground = lin.kind == KIND_GROUND
        testable &= ~(ground & (lin.component < 2) & (xy_points <= 2))
        testable &= ~(ground & (lin.component == 2) & (z_points <= 3))
    if not testable.any():
        return None
    row = int(np.argmax(np.where(testable, np.abs(w), -1.0)))
    if abs(w[row]) <= options.critical_w:
        return None
    kind, i, comp = int(lin.kind[row]), int(lin.index[row]), int(lin.component[row])
    residual = float(lin.r[row])
    if kind == KIND_IMAGE:
        residual *= float(b.obs_sigma[i, comp])
        problem.obs_active[i] = False
        pt = b.obs_point[i]
        left = np.flatnonzero(problem.obs_active & (b.obs_point == pt))
        full = np.isfinite(b.ground_xyz[b.ground_point == pt]).all(axis=1).any() if \
            (b.ground_point == pt).any() else False
        if len(left) < 2 and not full:
            problem.obs_active[left] = False
            problem.ground_active[b.ground_point == pt] = False
        return Rejection("image", i, comp, float(w[row]), float(r[row]), residual)
    if kind == KIND_GROUND:
        problem.ground_active[i, comp] = False
        return Rejection("ground", i, comp, float(w[row]), float(r[row]),
                         residual * float(b.ground_sigma[i, comp]))
    if kind == KIND_ATTITUDE:
        problem.attitude_active[i, comp] = False
        return Rejection("attitude", i, comp, float(w[row]), float(r[row]),
                         residual * float(b.attitude_sigma[i, comp]))
    problem.centre_active[i, comp] = False
    return Rejection("centre", i, comp, float(w[row]), float(r[row]),
                     residual * float(b.centre_sigma[i, comp]))


def adjust(block: Block, exterior: np.ndarray, points: np.ndarray,
           options: Options | None = None, feedback=None) -> Solution:
    """Adjust ``block`` from the approximate ``exterior`` (n, 6: X0, Y0, Z0 in the CRS, angles
    rad) and ``points`` (P, 3); see the module docstring.

    BLAS runs on one thread here: OpenBLAS's threaded Cholesky is 10-40 times slower than the
    single-threaded one on a loaded 2-core machine (measured: 1.9 s against 0.05 s, n = 960)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _adjust(block, exterior, points, options or Options(), feedback)


def _adjust(block: Block, exterior: np.ndarray, points: np.ndarray, options: Options,
            feedback) -> Solution:
    validate(block)
    check_datum(block)
    exterior = np.asarray(exterior, dtype=float)
    points = np.asarray(points, dtype=float)
    if not (np.isfinite(exterior).all() and np.isfinite(points).all()):
        raise InputDataError("approximate orientations and points must all be finite")
    origin = np.round(points.mean(axis=0))
    problem = Problem(block, origin)
    ext = exterior.copy()
    ext[:, :3] -= origin
    state = State(ext, points - origin, block.calibration.copy(),
                  np.zeros(problem.nc - problem.extra_start))
    notes = []
    if options.robust:
        state = _huber(problem, state, options)
        notes.append("Huber IRLS stage before the least squares")
    state, lin, iterations = least_squares(problem, state, options)
    rejections: list[Rejection] = []
    cof = None
    while options.snooping or options.precision:
        normal = normal_equations(problem, lin)
        cof = cofactors(problem, lin, normal)
        if not options.snooping or len(rejections) >= options.max_rejections:
            break
        r = 1.0 - cof.rows
        with np.errstate(invalid="ignore", divide="ignore"):
            w = lin.r / np.sqrt(r)
        rejection = _reject(problem, lin, w, r, options)
        if rejection is None:
            break
        rejections.append(rejection)
        if feedback is not None:
            feedback.push_info(f"data snooping: rejected {rejection.kind} observation "
                               f"{rejection.index} (w = {rejection.w:.2f})")
        state, lin, it = least_squares(problem, state, options)
        iterations += it
    return _solution(problem, state, lin, cof, iterations, rejections,
                     notes + list(dict.fromkeys(problem.warnings)))


def _solution(problem: Problem, state: State, lin, cof, iterations: int,
              rejections: list[Rejection], notes: list[str]) -> Solution:
    b = problem.block
    n, p = b.n_photos, b.n_points
    observed = np.bincount(b.obs_point[problem.obs_active], minlength=p) > 0
    estimated = observed.copy()  # a control point whose rays were all rejected: its ground rows
    estimated[b.ground_point[problem.ground_active.any(axis=1)]] = True  # still hold it
    unknowns = problem.nc + 3 * int(estimated.sum())
    redundancy = len(lin.r) - unknowns
    sigma0 = math.sqrt(lin.cost / redundancy) if redundancy > 0 else math.nan
    cam, kind, aspect = b.observation_cameras()
    f, _ = observation_residuals(b.obs_xy, state.exterior[b.obs_photo], state.points[b.obs_point],
                                 state.calibration[cam], kind, aspect, jacobians=False,
                                 **b.model_arguments(cam))
    g_res = state.points[b.ground_point] + problem.origin - b.ground_xyz
    lever = rotations(state.exterior[:, 3:])[0] @ b.lever_arm
    shift, drift, bore = problem.extras(state)
    h_res = (state.exterior[b.centre_photo, :3] + lever[b.centre_photo] + problem.origin
             - b.centre_xyz + shift[b.centre_group] + drift[b.centre_group]
             * b.centre_time[:, None])
    a_res = attitude_residuals(state.exterior[b.attitude_photo, 3:], bore, b.attitude_obs)
    extra_std = [np.full(c.shape, np.nan) for c in (problem.shift_column, problem.drift_column,
                                                     problem.boresight_column)]
    image_w = np.full((len(b.obs_photo), 2), np.nan)
    image_r = np.full_like(image_w, np.nan)
    ground_w = np.full_like(b.ground_xyz, np.nan)
    ground_r = np.full_like(b.ground_xyz, np.nan)
    attitude_w = np.full_like(b.attitude_obs, np.nan)
    ext_std = np.full((n, 6), np.nan)
    cal_std = np.full(b.calibration.shape, np.nan)
    pt_cov = np.full((p, 3, 3), np.nan)
    if cof is not None:
        r = 1.0 - cof.rows
        with np.errstate(invalid="ignore", divide="ignore"):
            w = lin.r / np.sqrt(r)
        on = lin.kind == KIND_ATTITUDE
        attitude_w[lin.index[on], lin.component[on]] = w[on]
        for kind, wa, ra in ((KIND_IMAGE, image_w, image_r), (KIND_GROUND, ground_w, ground_r)):
            on = lin.kind == kind
            wa[lin.index[on], lin.component[on]] = w[on]
            ra[lin.index[on], lin.component[on]] = r[on]
        var = np.diag(cof.camera) * sigma0 ** 2
        ext_std = np.sqrt(var[:6 * n]).reshape(n, 6)
        on = problem.calib_column >= 0
        cal_std[on] = np.sqrt(var[problem.calib_column[on]])
        for std, cols in zip(extra_std, (problem.shift_column, problem.drift_column,
                                         problem.boresight_column), strict=True):
            std[cols >= 0] = np.sqrt(var[cols[cols >= 0]])
        pt_cov = cof.points * sigma0 ** 2
        pt_cov[~observed] = np.nan
    ext = state.exterior.copy()
    ext[:, :3] += problem.origin
    ext[:, 3:] = (ext[:, 3:] + math.pi) % (2 * math.pi) - math.pi
    pts = state.points + problem.origin
    pts[~observed] = np.nan
    return Solution(ext, pts, state.calibration.copy(), sigma0, int(redundancy), iterations, f,
                    g_res, h_res, problem.obs_active.copy(), problem.ground_active.copy(),
                    problem.centre_active.copy(), image_w, image_r, ground_w, ground_r, ext_std,
                    np.sqrt(np.einsum("pii->pi", pt_cov)), pt_cov, cal_std, rejections,
                    problem.origin.copy(), notes, shift, drift, bore, *extra_std, a_res,
                    problem.attitude_active.copy(), attitude_w)
