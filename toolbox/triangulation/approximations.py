"""Approximate values for the bundle: connectivity, given orientations, or resection and
intersection chained over the block.

- :func:`components`: photos linked by common points (graph connected components); a block in
  several pieces cannot be adjusted as one and is reported piece by piece.
- :func:`from_exteriors`: given orientations (project YAML: flight plan, GNSS/IMU, an earlier
  adjustment); tie points by forward intersection.
- :func:`by_resection`: photos with >= 4 control points (full XYZ) measured are resected
  (:func:`toolbox.photogrammetry.resection.resect`, near-vertical start); then, in turn, points
  seen on >= 2 oriented photos are intersected and photos seeing >= 4 known points resected, until
  every photo is oriented or no progress is made (004 sl. 28: resection / DLT start values).
  When no photo sees 4 known points, the photo seeing the most (>= 2) gets a near-vertical
  start from a plane similarity (omega = phi = 0; scale, kappa, nadir), and the chain goes on.
- :func:`by_plane_block`: when control is too sparse for that, a near-vertical block is solved
  at once as plane similarities (photo mm -> ground XY, linear; >= 2 XY control points).
- :func:`by_model_chain`: without planimetric control (block corners seen on one photo
  each), the same chain runs in a free model frame seeded by one vertical photo, and the model is
  brought onto the control by a 7-parameter similarity
  (:func:`toolbox.photogrammetry.absolute.fit_similarity`, >= 3 full control points).
"""

from __future__ import annotations

import numpy as np

from toolbox.errors import InputDataError
from toolbox.triangulation.block import Block
from toolbox.triangulation.model import KIND_BROWN, KIND_MODEL, brown_ideal, ideal


def components(block: Block) -> list[list[str]]:
    """Photo ids of each connected piece of the block (largest first)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    n, p = block.n_photos, block.n_points
    inc = sp.csr_matrix((np.ones(len(block.obs_photo)), (block.obs_photo, block.obs_point)),
                        shape=(n, p))
    count, labels = connected_components(inc @ inc.T, directed=False)
    pieces = [[block.photo_ids[i] for i in np.flatnonzero(labels == k)] for k in range(count)]
    return sorted(pieces, key=len, reverse=True)


def require_connected(block: Block) -> None:
    pieces = components(block)
    if len(pieces) > 1:
        desc = "; ".join(f"component {k + 1}: {', '.join(piece[:8])}"
                         f"{' ...' if len(piece) > 8 else ''}"
                         for k, piece in enumerate(pieces[:5]))
        raise InputDataError(f"the block is not connected by common points: {len(pieces)} "
                             f"components ({desc}); add tie points between them")


def camera_xy(block: Block) -> np.ndarray:
    """Ideal camera coordinates (mm; px for a Brown camera, whose ``c`` is f) of every
    observation at the start calibration."""
    cam, kind, aspect = block.observation_cameras()
    calib = block.calibration[cam]
    out = ideal(block.obs_xy, calib)[0]
    brown = kind == KIND_BROWN
    if brown.any():
        out[brown] = brown_ideal(block.obs_xy[brown], calib[brown], aspect[brown])
    for c in np.unique(cam[kind == KIND_MODEL]):
        on = (kind == KIND_MODEL) & (cam == c)
        out[on] = block.camera_models[c].pixel_to_normalised(block.obs_xy[on]) * calib[on, :1]
    return out


def _intersect(block: Block, cam: np.ndarray, exterior: np.ndarray, oriented: np.ndarray,
               known: np.ndarray, points: np.ndarray) -> None:
    """Intersect (in place) the points not yet known that >= 2 oriented photos see."""
    from toolbox.photogrammetry.forward_intersection import intersect
    from toolbox.photogrammetry.rotation import rotation_matrix

    rows = np.flatnonzero(oriented[block.obs_photo] & ~known[block.obs_point])
    if not len(rows):
        return
    ph = block.obs_photo[rows]
    ext = exterior[ph]
    res = intersect(block.obs_point[rows], cam[rows], ext[:, :3],
                    rotation_matrix(ext[:, 3], ext[:, 4], ext[:, 5]),
                    block.calibration[block.photo_camera[ph], 0], block.n_points)
    ok = res.ok & ~known
    points[ok] = res.xyz[ok]
    known |= ok


def _control(block: Block) -> tuple[np.ndarray, np.ndarray]:
    """Full-XYZ control coordinates per point and the mask of points that have them."""
    points = np.full((block.n_points, 3), np.nan)
    full = np.isfinite(block.ground_xyz).all(axis=1)
    points[block.ground_point[full]] = block.ground_xyz[full]
    return points, np.isfinite(points).all(axis=1)


def from_exteriors(block: Block, exterior: np.ndarray) -> np.ndarray:
    """Points (P, 3) from given orientations (n, 6): control where known, else intersected."""
    points, known = _control(block)
    _intersect(block, camera_xy(block), exterior, np.ones(block.n_photos, bool), known, points)
    _check_points(block, known)
    return points


def _check_points(block: Block, known: np.ndarray) -> None:
    if not known.all():
        names = ", ".join(repr(block.point_ids[i]) for i in np.flatnonzero(~known)[:5])
        raise InputDataError(f"{int((~known).sum())} point(s) could not be intersected from the "
                             f"approximate orientations (rays parallel or behind a camera): "
                             f"{names}")


def by_resection(block: Block) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Exterior (n, 6), points (P, 3) and notes, by resection and intersection in turn; falls
    back on :func:`by_model_chain` when the control cannot start the chain."""
    require_connected(block)
    points, known = _control(block)
    exterior = np.full((block.n_photos, 6), np.nan)
    oriented = np.zeros(block.n_photos, dtype=bool)
    notes = _chain(block, exterior, oriented, points, known)
    if not oriented.all():
        xy = np.isfinite(block.ground_xyz[:, :2]).all(axis=1)
        if len(set(block.ground_point[xy].tolist())) >= 2:
            return by_plane_block(block)
        return by_model_chain(block)
    _check_points(block, known)
    return exterior, points, notes


def by_plane_block(block: Block) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Near-vertical block: every photo as a plane similarity camera mm -> ground XY, all at
    once (the linear planimetric block adjustment of :mod:`toolbox.triangulation.models`, photos
    as models) on the XY control; then per photo kappa = atan2(b, a), the scale m = hypot(a, b)
    gives Z0 = mean control height + m·c, omega = phi = 0; points intersected."""
    from toolbox.triangulation.models import ModelsRequest, planimetric

    require_connected(block)
    cam = camera_xy(block)
    known = np.isfinite(block.ground_xyz)
    xy = known[:, 0] & known[:, 1]
    request = ModelsRequest([str(j) for j in block.obs_photo],
                            [block.point_ids[i] for i in block.obs_point],
                            np.column_stack([cam, np.zeros(len(cam))]),
                            [block.point_ids[i] for i in block.ground_point[xy]],
                            block.ground_xyz[xy], "planimetric")
    plane = planimetric(request)
    order = [int(m) for m in plane.models]
    z_mean = float(np.mean(block.ground_xyz[known[:, 2], 2])) if known[:, 2].any() else 0.0
    exterior = np.zeros((block.n_photos, 6))
    for row, j in enumerate(order):
        xu, yu, a, b = plane.parameters[row]
        scale = float(np.hypot(a, b))
        c = float(block.calibration[block.photo_camera[j], 0])
        exterior[j] = [xu, yu, z_mean + scale * c, 0.0, 0.0, float(np.arctan2(b, a))]
    points, full = _control(block)
    ok = np.zeros(block.n_points, dtype=bool)
    _intersect(block, cam, exterior, np.ones(block.n_photos, bool), ok, points)
    missing = ~(ok | full)
    where = {p: k for k, p in enumerate(plane.points)}
    for i in np.flatnonzero(missing):
        points[i] = [*plane.ground[where[block.point_ids[i]]], z_mean]
    notes = [f"start values: plane similarity block of {block.n_photos} photos on "
             f"{int(xy.sum())} XY control points (near-vertical photos), points intersected"]
    return exterior, points, notes


def by_model_chain(block: Block) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Chain in a free model frame, then a spatial similarity onto the full control points."""
    from toolbox.photogrammetry.absolute import fit_similarity
    from toolbox.photogrammetry.rotation import angles_from_matrix, rotation_matrix

    require_connected(block)
    points = np.full((block.n_points, 3), np.nan)
    known = np.zeros(block.n_points, dtype=bool)
    exterior = np.full((block.n_photos, 6), np.nan)
    oriented = np.zeros(block.n_photos, dtype=bool)
    seed = int(np.argmax(np.bincount(block.obs_photo, minlength=block.n_photos)))
    exterior[seed] = [0.0, 0.0, 1000.0, 0.0, 0.0, 0.0]
    oriented[seed] = True
    notes = [f"photo {block.photo_ids[seed]}: seeds a free model frame (vertical, its points "
             "on the plane Z = 0 until intersected)"]
    cam = camera_xy(block)
    rows = np.flatnonzero(block.obs_photo == seed)
    c = float(block.calibration[block.photo_camera[seed], 0])
    points[block.obs_point[rows], :2] = cam[rows] * 1000.0 / c
    points[block.obs_point[rows], 2] = 0.0
    known[block.obs_point[rows]] = True
    notes += _chain(block, exterior, oriented, points, known)
    # every point again from all the chained photos (the seed's plane points included)
    known[:] = False
    _intersect(block, cam, exterior, oriented, known, points)
    control, full = _control(block)
    on = full & known
    gnss = np.isfinite(block.centre_xyz).all(axis=1)
    if oriented.all() and on.sum() < 3 and gnss.sum() >= 3:
        model = exterior[block.centre_photo[gnss], :3]
        target = block.centre_xyz[gnss]
        what = f"{int(gnss.sum())} GNSS projection centres"
    else:
        model, target = points[on], control[on]
        what = f"{int(on.sum())} control points"
    if not oriented.all() or len(model) < 3:
        missing = [block.photo_ids[j] for j in np.flatnonzero(~oriented)]
        raise InputDataError(
            "no approximate orientations: "
            + (f"photo(s) {', '.join(missing[:8])} could not be chained; " if missing else "")
            + f"{int(on.sum())} full control point(s) in the chained model and "
            f"{int(gnss.sum())} GNSS centres (3 needed); give approximate exterior orientations "
            "in PROJECT (START=project)")
    fit = fit_similarity(model, target)
    rot = rotation_matrix(*fit.angles)
    points = fit.scale * points @ rot.T + fit.translation
    for j in range(block.n_photos):
        exterior[j, :3] = fit.scale * rot @ exterior[j, :3] + fit.translation
        exterior[j, 3:] = angles_from_matrix(rot @ rotation_matrix(*exterior[j, 3:]))
    points[full] = control[full]
    notes.append(f"model -> ground similarity on {what} (scale {fit.scale:.4g})")
    _check_points(block, known | full)
    return exterior, points, notes


def _chain(block: Block, exterior: np.ndarray, oriented: np.ndarray, points: np.ndarray,
           known: np.ndarray) -> list[str]:
    """Resect and intersect in turn (in place) until no progress; the notes."""
    from toolbox.photogrammetry.resection import resect, similarity_start

    cam = camera_xy(block)
    notes = []
    order = np.argsort(block.obs_photo, kind="stable")
    bounds = np.searchsorted(block.obs_photo[order], np.arange(block.n_photos + 1))
    rows_of = [order[bounds[j]:bounds[j + 1]] for j in range(block.n_photos)]
    for round_ in range(1, 3 * block.n_photos + 2):
        counts = {}
        progress = False
        for j in np.flatnonzero(~oriented):
            rows = rows_of[j][known[block.obs_point[rows_of[j]]]]
            counts[j] = rows
            if len(rows) < 4:
                continue
            try:
                fit = resect(cam[rows], points[block.obs_point[rows]],
                             float(block.calibration[block.photo_camera[j], 0]))
            except Exception:  # collinear or diverging: try again once more points are known
                continue
            exterior[j] = fit.parameters
            oriented[j] = progress = True
            notes.append(f"photo {block.photo_ids[j]}: resected on {len(rows)} points "
                         f"(round {round_})")
        if not progress and counts:
            # near-vertical start from a plane similarity on >= 2 known points (omega = phi = 0)
            j, rows = max(counts.items(), key=lambda kv: len(kv[1]))
            if len(rows) >= 2:
                exterior[j] = similarity_start(cam[rows], points[block.obs_point[rows]],
                                               float(block.calibration[block.photo_camera[j], 0]))
                oriented[j] = progress = True
                notes.append(f"photo {block.photo_ids[j]}: near-vertical similarity start on "
                             f"{len(rows)} points (round {round_})")
        _intersect(block, cam, exterior, oriented, known, points)
        if oriented.all() or not progress:
            break
    return notes


def check_attitude_unit(block: Block, exterior: np.ndarray, unit: str,
                        name: str = "IMU_ANGLE_UNIT") -> None:
    """IMU attitudes read in ``unit`` that the approximate orientations contradict while the
    same numbers in another angle unit (deg, rad, gon) agree with them: a ParameterError naming
    both (a vertical block's omega and phi near 0 betray a wrong unit at once). Misfit: the mean
    over photos of the largest angle difference; over 0.1 rad for the given unit, under half of
    it and 0.1 rad for the other."""
    from toolbox.errors import ParameterError
    from toolbox.photogrammetry.rotation import to_radians
    from toolbox.triangulation.solver import attitude_residuals

    if not len(block.attitude_photo):
        return
    raw = block.attitude_obs / to_radians(1.0, unit)
    start = exterior[block.attitude_photo, 3:]
    misfit = {u: float(np.mean(np.abs(attitude_residuals(start, np.zeros(3),
                                                         raw * to_radians(1.0, u))).max(axis=1)))
              for u in ("deg", "rad", "gon")}
    best = min(misfit, key=misfit.get)
    if misfit[unit] > 0.1 and best != unit and misfit[best] < min(0.1, misfit[unit] / 2):
        raise ParameterError(name, f"is {unit} but the IMU angles read so differ from the "
                             f"approximate orientations by {np.degrees(misfit[unit]):.1f} deg "
                             f"(mean largest per photo); read as {best} they agree within "
                             f"{np.degrees(misfit[best]):.2f} deg: give IMU_ANGLE_UNIT {best}")


#: angle-unit mix-ups: factor by which the angles were wrongly scaled, and how to name it
UNIT_MIXUPS = {np.pi / 180: "written in deg, read as rad", 180 / np.pi: "written in rad, read as deg",
               np.pi / 200: "written in gon, read as rad", 200 / np.pi: "written in rad, read as gon"}


def check_start_angle_unit(block: Block, exterior: np.ndarray, name: str = "PROJECT") -> None:
    """Given start orientations whose control points (full XYZ) fall far off their measurements
    while the same angles in another unit put them close (a vertical block's start read in the
    wrong ``angle_unit``): a ParameterError naming the mix-up. Misfit: the median image
    residual of the control observations (behind a camera: infinite); the given angles are
    refused when the best mix-up is 20 times closer."""
    from toolbox.errors import ParameterError
    from toolbox.triangulation.model import observation_residuals

    points, known = _control(block)
    sel = np.flatnonzero(known[block.obs_point])
    if len(sel) < 3:
        return
    cam, kind, aspect = block.observation_cameras(sel)

    def misfit(angles_scale: float) -> float:
        ext = exterior[block.obs_photo[sel]].copy()
        ext[:, 3:] *= angles_scale
        f, depth = observation_residuals(block.obs_xy[sel], ext, points[block.obs_point[sel]],
                                         block.calibration[cam], kind, aspect, jacobians=False,
                                         **block.model_arguments(cam))
        err = np.where(depth < 0, np.hypot(f[:, 0], f[:, 1]), np.inf)
        return float(np.median(err))

    given = misfit(1.0)
    scores = {k: misfit(k) for k in UNIT_MIXUPS}
    best = min(scores, key=scores.get)
    if np.isfinite(scores[best]) and given > 20 * scores[best]:
        where = "behind the cameras" if not np.isfinite(given) else "far off their measurements"
        raise ParameterError(name, f"its exterior angles put the control points {where}, but "
                             f"scaled as if {UNIT_MIXUPS[best]} they fit (median "
                             f"residual {scores[best]:.3g} image units): check its angle_unit")
