"""Checking and completing orientation results: residuals of control/check points through the
whole chain (pixels -> interior orientation -> collinearity), single-photo resection of a block.

Residual convention of the toolbox: **computed minus observed**, the correction ``v`` of the
least-squares model ``l + v = f(x)`` (image: projected minus measured; ground: intersected from the
measurements minus the surveyed coordinates), as the fiducial, plane-transform and intersection
reports give them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.photogrammetry.exterior import ExteriorOrientation
from toolbox.photogrammetry.forward_intersection import (
    camera_observations,
    intersect_measured,
    principal_distance,
)
from toolbox.photogrammetry.resection import PARAMETER_NAMES, resect


def _match(project, measurements, control):
    """Observations of known points on project photos: rows of (point, photo, xy), ground xyz."""
    ids, photo_ids, xy, kind = measurements
    c_ids, c_xyz, c_roles = control
    unknown = sorted({p for p in photo_ids if p not in project.photos})
    if unknown:
        raise InputDataError(f"INPUT names photo(s) {', '.join(map(repr, unknown[:5]))} that "
                             f"PROJECT does not have (photos: {', '.join(project.photos)})")
    seen = set()
    for i, p in zip(ids, photo_ids, strict=True):
        if (i, p) in seen:
            raise InputDataError(f"INPUT measures point {i!r} twice on photo {p!r} (duplicate)")
        seen.add((i, p))
    where = {pid: k for k, pid in enumerate(c_ids)}
    return where, c_xyz, c_roles, kind


def _pixel_scale_um(photo) -> float | None:
    """Mean size of one pixel in image µm (None without a pixel transform)."""
    transform = photo.pixel_transform
    return None if transform is None else 1e3 * transform.pixel_size_mm


def resect_photos(project, measurements, control, use_project_start: bool = False,
                  feedback=None) -> tuple[dict[str, ExteriorOrientation], dict[str, Any]]:
    """Resect every photo of ``measurements`` that sees >= 4 control points (role control)."""
    ids, photo_ids, xy, kind = measurements
    where, c_xyz, c_roles, kind = _match(project, measurements, control)
    exteriors, report = {}, {}
    order = list(dict.fromkeys(photo_ids))
    for n, pid in enumerate(order):
        if feedback is not None:
            feedback.check_canceled()
            feedback.set_progress(100.0 * n / max(1, len(order)))
        photo = project.photos[pid]
        rows = [k for k, p in enumerate(photo_ids) if p == pid and ids[k] in where]
        fit_rows = [k for k in rows if c_roles[where[ids[k]]] == "control"]
        cam_xy = camera_observations([photo] * len(rows), xy[rows], kind)
        ground = c_xyz[[where[ids[k]] for k in rows]]
        fit_mask = np.array([k in fit_rows for k in rows], dtype=bool)
        if fit_mask.sum() < 4:
            if feedback is not None:
                feedback.push_warning(f"photo {pid}: {int(fit_mask.sum())} control point(s) "
                                      "measured, space resection needs at least 4: not resected")
            continue
        start = None
        if use_project_start:
            eo = photo.require_exterior()
            start = np.array([*eo.centre, eo.omega, eo.phi, eo.kappa])
        try:
            result = resect(cam_xy[fit_mask], ground[fit_mask], principal_distance(photo),
                            start)
        except InputDataError as exc:
            raise InputDataError(f"photo {pid!r}: {exc}") from None
        x0, y0, z0, om, ph, ka = result.parameters
        eo = ExteriorOrientation(pid, *map(float, (x0, y0, z0, om, ph, ka)), crs=project.crs)
        exteriors[pid] = eo
        fitted = project.with_exteriors({pid: eo}).photos[pid]
        if photo.is_model:  # its camera units are pixel-sized: residuals in pixels
            report[pid] = _model_resection_report(result, fitted, ground, xy[rows],
                                                  [ids[k] for k in rows],
                                                  [c_roles[where[ids[k]]] for k in rows],
                                                  int(fit_mask.sum()))
            continue
        computed = fitted.ground_to_image(ground)
        observed = photo.require_pixel_transform().pixel_to_image(xy[rows]) if kind == "pixel" \
            else xy[rows]
        v_um = (computed - observed) * 1e3
        px = _pixel_scale_um(photo)
        report[pid] = {
            "parameters": dict(zip(PARAMETER_NAMES, map(float, result.parameters), strict=True)),
            "std": dict(zip(PARAMETER_NAMES, map(float, result.std), strict=True)),
            "angle_unit": "rad", "sigma0_um": float(result.sigma0_mm * 1e3),
            "redundancy": result.redundancy, "control_points": int(fit_mask.sum()),
            "points": [{"point_id": ids[k], "role": c_roles[where[ids[k]]],
                        "res_x_um": float(v[0]), "res_y_um": float(v[1]),
                        "res_px": None if px is None else float(math.hypot(*v) / px)}
                       for k, v in zip(rows, v_um, strict=True)]}
    if not exteriors:
        raise InputDataError("no photo of INPUT has control points of CONTROL measured on it")
    return exteriors, report


def _model_resection_report(result, fitted, ground, pixels, ids, roles, n_control
                            ) -> dict[str, Any]:
    """:func:`resect_photos`' report of a camera-model photo: sigma0 and residuals in pixels
    (through the full model: distortion included), no µm (it has no film plane)."""
    v = fitted.ground_to_pixel(ground, behind="nan") - pixels
    return {"parameters": dict(zip(PARAMETER_NAMES, map(float, result.parameters), strict=True)),
            "std": dict(zip(PARAMETER_NAMES, map(float, result.std), strict=True)),
            "angle_unit": "rad", "sigma0_um": None, "sigma0_px": float(result.sigma0_mm),
            "redundancy": result.redundancy, "control_points": n_control,
            "points": [{"point_id": i, "role": r, "res_x_um": None, "res_y_um": None,
                        "res_x_px": float(d[0]), "res_y_px": float(d[1]),
                        "res_px": float(math.hypot(*d))}
                       for i, r, d in zip(ids, roles, v, strict=True)]}


def check_block(project, measurements, control, threshold_px: float = 1.0) -> dict[str, Any]:
    """Residuals of every known point on every photo where it was measured, and ground residuals
    from multi-ray intersection.

    Returns a dict with ``observations`` (one per measurement of a known point: photo, point,
    role, residuals in µm and pixels, flagged), ``points`` (per known point with >= 2 rays: the
    intersected XYZ, ground residuals dX/dY/dZ), ``photos`` (RMSE per photo) and ``block``.
    """
    ids, photo_ids, xy, kind = measurements
    where, c_xyz, c_roles, kind = _match(project, measurements, control)
    rows = [k for k, i in enumerate(ids) if i in where]
    if not rows:
        raise InputDataError("none of the measured points of INPUT is in CONTROL (no common ids)")
    photos = [project.photos[photo_ids[k]] for k in rows]
    for p in {p.id: p for p in photos}.values():
        p.require_exterior()
    ground = c_xyz[[where[ids[k]] for k in rows]]
    observations = []
    for n, k in enumerate(rows):
        photo = photos[n]
        entry = {"point_id": ids[k], "photo": photo.id, "role": c_roles[where[ids[k]]]}
        if photo.is_model:  # no film plane: residuals in pixels through the full model
            if kind != "pixel":
                raise InputDataError(f"photo {photo.id!r}: its camera is a {photo.camera.kind} "
                                     "model: measure it in pixels (col_px, row_px), not image mm")
            v = photo.ground_to_pixel(ground[n:n + 1], behind="nan")[0] - xy[k]
            res_px = float(math.hypot(*v)) if np.isfinite(v).all() else None
            entry |= {"res_x_um": None, "res_y_um": None, "res_um": None}
        else:
            computed = photo.ground_to_image(ground[n:n + 1], behind="nan")[0]
            observed = photo.require_pixel_transform().pixel_to_image(xy[k:k + 1])[0] \
                if kind == "pixel" else xy[k]
            v_um = (computed - observed) * 1e3
            px = _pixel_scale_um(photo)
            res_px = None if px is None or not np.isfinite(v_um).all() else \
                float(math.hypot(*v_um) / px)
            entry |= {"res_x_um": float(v_um[0]), "res_y_um": float(v_um[1]),
                      "res_um": float(math.hypot(*v_um))} if np.isfinite(v_um).all() else \
                {"res_x_um": None, "res_y_um": None, "res_um": None}
        # a known point behind the photo (a wrong id, a measurement on the wrong photo) has no
        # image and no residual: flagged
        behind = entry["res_um"] is None and res_px is None
        observations.append(entry | {
            "res_px": res_px,
            "flagged": bool(behind or res_px is not None and res_px > threshold_px),
            "xyz": ground[n].tolist()})
    # ground residuals by multi-ray intersection
    order = list(dict.fromkeys(ids[k] for k in rows))
    index = {pid: n for n, pid in enumerate(order)}
    point_index = np.array([index[ids[k]] for k in rows])
    result = intersect_measured(photos, xy[rows], point_index, len(order), kind)
    points = []
    for n, pid in enumerate(order):
        known = c_xyz[where[pid]]
        entry = {"point_id": pid, "role": c_roles[where[pid]], "n_photos": int(result.n_rays[n]),
                 "known": known.tolist()}
        if result.ok[n]:
            d = result.xyz[n] - known
            entry |= {"intersected": result.xyz[n].tolist(), "dx_m": float(d[0]),
                      "dy_m": float(d[1]), "dz_m": float(d[2]),
                      "dxy_m": float(math.hypot(d[0], d[1]))}
        points.append(entry)
    per_photo = {}
    for pid in dict.fromkeys(o["photo"] for o in observations):
        mine = [o for o in observations if o["photo"] == pid]
        pxs = [o["res_px"] for o in mine if o["res_px"] is not None]
        per_photo[pid] = {"observations": len(mine), "rmse_um": _rmse_um(mine),
                          "rmse_px": float(np.sqrt(np.mean(np.square(pxs)))) if pxs else None,
                          "flagged": sum(o["flagged"] for o in mine)}
    block = {"observations": len(observations), "rmse_um": _rmse_um(observations),
             "flagged": sum(o["flagged"] for o in observations), "threshold_px": threshold_px}
    ground_ok = [p for p in points if "dx_m" in p]
    for role in ("control", "check"):
        sel = [p for p in ground_ok if p["role"] == role]
        if sel:
            block[f"{role}_rmse_xy_m"] = float(np.sqrt(np.mean([p["dxy_m"] ** 2 for p in sel])))
            block[f"{role}_rmse_z_m"] = float(np.sqrt(np.mean([p["dz_m"] ** 2 for p in sel])))
            block[f"{role}_points"] = len(sel)
    return {"observations": observations, "points": points, "photos": per_photo, "block": block}


def _rmse_um(observations: list[dict[str, Any]]) -> float | None:
    """RMSE (µm) of the observations with image-µm residuals (None: only camera models)."""
    res = np.array([[o["res_x_um"], o["res_y_um"]] for o in observations
                    if o["res_x_um"] is not None], dtype=float).reshape(-1, 2)
    return float(np.sqrt((res ** 2).sum(axis=1).mean())) if len(res) else None
