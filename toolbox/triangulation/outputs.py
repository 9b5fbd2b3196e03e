"""What an adjusted block becomes: the updated project, the report, the vector layers.

Residuals are **computed minus observed** (the toolbox convention); ground residuals of control
and check points are adjusted minus surveyed (m). Pixel residuals divide image mm by the photo's
pixel size (pixel measurements only). Check points take no part in the adjustment.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from toolbox.triangulation.block import Block, Solution
from toolbox.triangulation.model import (
    BROWN_NAMES,
    CALIBRATION_NAMES,
    EXTERIOR_NAMES,
    KIND_BROWN,
    KIND_FILM,
)

MAX_REPORTED_OBSERVATIONS = 50_000  # per-observation residuals in the JSON up to this many


def _num(value) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def error_ellipse(cov_xy: np.ndarray) -> tuple[float, float, float]:
    """Standard error ellipse of a 2 x 2 covariance: semi-axes a >= b (m) and the direction of a,
    degrees counter-clockwise from the X (east) axis, in (-90, 90]."""
    if not np.isfinite(cov_xy).all():
        return math.nan, math.nan, math.nan
    vals, vecs = np.linalg.eigh(cov_xy)
    angle = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
    angle = angle - 180.0 if angle > 90.0 else angle + 180.0 if angle <= -90.0 else angle
    return math.sqrt(max(vals[1], 0.0)), math.sqrt(max(vals[0], 0.0)), angle


def adjusted_project(project, block: Block, solution: Solution):
    """``project`` with the adjusted exterior orientations and, for self-calibrated cameras,
    principal distance, principal point and polynomial distortion (k1, k2, k3, p1, p2)."""
    from toolbox.photogrammetry.camera import RadialDistortion
    from toolbox.photogrammetry.exterior import ExteriorOrientation

    free = block.calibration_mode != 0
    cameras = dict(project.cameras)
    for k, name in enumerate(block.camera_names):
        if not free[k].any():
            continue
        cal = solution.calibration[k]
        cam = cameras[name]
        if block.camera_kind[k] == KIND_BROWN:
            cameras[name] = brown_camera(cam, cal, float(block.camera_aspect[k]))
            continue
        dist = cam.distortion
        if free[k, 3:].any() or (dist is not None and dist.mode == 2):
            dist = RadialDistortion.from_polynomial(*map(float, cal[3:8]))
        cameras[name] = replace(cam, principal_distance_mm=float(cal[0]),
                                principal_point_mm=(float(cal[1]), float(cal[2])),
                                distortion=dist)
    photos = {pid: replace(p, camera=cameras[p.camera.name]) for pid, p in project.photos.items()}
    updated = type(project)(project.crs, cameras, photos, project.source, list(project.notes))
    eos = {pid: ExteriorOrientation(pid, *map(float, solution.exterior[j]), crs=project.crs)
           for j, pid in enumerate(block.photo_ids)}
    return updated.with_exteriors(eos)


def brown_camera(camera, calibration: np.ndarray, aspect: float):
    """The adjusted Brown camera (:class:`toolbox.cameras.Intrinsics`) of a model camera from
    its calibration ``(fx, cx, cy, k1, k2, k3, p1, p2)`` (px): the camera spec written afresh
    (focal length and principal point offsets normalised by max(w, h), the factory's schema),
    built through :func:`toolbox.cameras.create_intrinsics` (which checks the distortion does
    not fold back inside the image)."""
    from toolbox.cameras import create_intrinsics

    w, h = camera.image_size_px
    s = float(max(w, h))
    fx, cx, cy, k1, k2, k3, p1, p2 = map(float, calibration)
    focal = fx / s if aspect == 1.0 else [fx / s, aspect * fx / s]
    spec = {"type": "brown", "im_size": [int(w), int(h)], "focal_len": focal,
            "cx": (cx - w / 2) / s, "cy": (cy - h / 2) / s,
            "k1": k1, "k2": k2, "k3": k3, "p1": p1, "p2": p2}
    return create_intrinsics(spec, camera.name)


def ground_comparison(block: Block, solution: Solution, control, checks: list[str]
                      ) -> list[dict[str, Any]]:
    """Adjusted minus surveyed coordinates of every control and check point of the block."""
    index = {pid: k for k, pid in enumerate(block.point_ids)}
    rows = []
    for k, pid in enumerate(control.ids):
        if pid not in index:
            continue
        p = index[pid]
        adjusted = solution.points[p]
        d = adjusted - control.xyz[k]
        std = solution.point_std[p]
        role = control.roles[k]
        kind = "XYZ" if np.isfinite(control.xyz[k]).all() else \
            ("Z" if np.isnan(control.xyz[k, 0]) else "XY")
        rows.append({"point_id": pid, "role": role, "type": kind,
                     "known": control.xyz[k], "adjusted": adjusted,
                     "dx_m": _num(d[0]), "dy_m": _num(d[1]), "dz_m": _num(d[2]),
                     "sigma_x_m": _num(std[0]), "sigma_y_m": _num(std[1]),
                     "sigma_z_m": _num(std[2])})
    return rows


def _rms(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return _num(math.sqrt(sum(v * v for v in vals) / len(vals))) if vals else None


def model_observations(block: Block, info: dict) -> np.ndarray:
    """(m,) True for image observations of model (Brown, pixel) cameras."""
    model = info.get("model_photos", set())
    return np.array([block.photo_ids[j] in model for j in block.obs_photo], dtype=bool)


def report(block: Block, solution: Solution, info: dict, ground: list[dict[str, Any]],
           notes: list[str], threshold_px: float = 1.0) -> dict[str, Any]:
    """The JSON report (plain types); ``flagged``: active measurements whose residual exceeds
    ``threshold_px`` (pixel measurements only)."""
    px = np.array([info["pixel_mm"].get(block.photo_ids[j], np.nan) for j in block.obs_photo])
    res = solution.image_residuals
    active = solution.obs_active
    film = ~model_observations(block, info)  # image mm; a model camera's are pixels
    with np.errstate(invalid="ignore"):
        over = active & (np.hypot(res[:, 0], res[:, 1]) / px > threshold_px)
    summary = {
        "sigma0": _num(solution.sigma0), "redundancy": solution.redundancy,
        "iterations": solution.iterations, "photos": block.n_photos,
        "points": block.n_points, "image_observations": int(len(block.obs_photo)),
        "rejected": len(solution.rejections), "flagged": int(over.sum()),
        "threshold_px": threshold_px,
        "rms_image_residual_um": _num(1e3 * np.sqrt(np.mean(res[active & film] ** 2)))
        if (active & film).any() else None,
        "rms_image_residual_px": _num(np.sqrt(np.nanmean((res[active] / px[active, None]) ** 2)))
        if info["kind"] == "pixel" else None,
        "local_origin": solution.origin,
    }
    for role in ("control", "check"):
        sel = [g for g in ground if g["role"] == role]
        if sel:
            summary[f"{role}_rmse_m"] = {a: _rms([g[f"d{a}_m"] for g in sel]) for a in "xyz"}
    photos = []
    for j, pid in enumerate(block.photo_ids):
        photos.append({"photo": pid, "angle_unit": "rad",
                       **{n: float(solution.exterior[j, k]) for k, n in enumerate(EXTERIOR_NAMES)},
                       **{f"std_{n}": _num(solution.exterior_std[j, k])
                          for k, n in enumerate(EXTERIOR_NAMES)}})
    cameras = []
    for k, name in enumerate(block.camera_names):
        kind = int(block.camera_kind[k])
        brown = kind != KIND_FILM
        label = ("film (mm)", "brown (px)", "interior model (px, fixed)")[kind]
        cameras.append({"camera": name, "model": label, **{
            n: {"value": float(solution.calibration[k, i]),
                "mode": ("fixed", "free", "weighted")[int(block.calibration_mode[k, i])],
                "std": _num(solution.calibration_std[k, i])}
            for i, n in enumerate(BROWN_NAMES if brown else CALIBRATION_NAMES)}})
    rejections = []
    for rj in solution.rejections:
        if rj.kind == "image":
            what = {"point_id": block.point_ids[block.obs_point[rj.index]],
                    "photo": block.photo_ids[block.obs_photo[rj.index]],
                    "coordinate": "xy"[rj.component], "residual_mm": rj.residual}
        elif rj.kind == "ground":
            what = {"point_id": block.point_ids[block.ground_point[rj.index]],
                    "coordinate": "XYZ"[rj.component], "residual_m": rj.residual}
        elif rj.kind == "attitude":
            what = {"photo": block.photo_ids[block.attitude_photo[rj.index]],
                    "coordinate": EXTERIOR_NAMES[3 + rj.component], "residual_rad": rj.residual}
        else:
            what = {"photo": block.photo_ids[block.centre_photo[rj.index]],
                    "coordinate": "XYZ"[rj.component], "residual_m": rj.residual}
        rejections.append({"observation": rj.kind, **what, "w": rj.w,
                           "redundancy_number": rj.redundancy})
    observations = None
    if len(block.obs_photo) <= MAX_REPORTED_OBSERVATIONS:
        observations = [
            {"point_id": block.point_ids[block.obs_point[i]],
             "photo": block.photo_ids[block.obs_photo[i]],
             "res_x_um": _num(1e3 * res[i, 0]) if film[i] else None,
             "res_y_um": _num(1e3 * res[i, 1]) if film[i] else None,
             "res_x_px": _num(res[i, 0] / px[i]), "res_y_px": _num(res[i, 1] / px[i]),
             "w_x": _num(solution.image_w[i, 0]), "w_y": _num(solution.image_w[i, 1]),
             "r_x": _num(solution.image_r[i, 0]), "r_y": _num(solution.image_r[i, 1]),
             "rejected": not bool(active[i])} for i in range(len(block.obs_photo))]
    gnss_imu = {}
    strips = info.get("gnss_strips") or [str(g + 1) for g in range(block.n_groups)]
    t0 = info.get("gnss_time_origin") or [0.0] * block.n_groups
    for key, on, est, std, unit in (
            ("gnss_shift", block.gnss_shift, solution.gnss_shift, solution.gnss_shift_std, "m"),
            ("gnss_drift", block.gnss_drift, solution.gnss_drift, solution.gnss_drift_std,
             "m per time unit")):
        if on:
            gnss_imu[key] = {"unit": unit, "strips": [
                {"strip": strips[g], **{a: float(est[g, k]) for k, a in enumerate("XYZ")},
                 **{f"std_{a}": _num(std[g, k]) for k, a in enumerate("XYZ")},
                 **({"at_time": float(t0[g])} if key == "gnss_shift" and block.gnss_drift
                    else {})}
                for g in range(len(est))]}
    if len(block.attitude_photo):
        gnss_imu["imu"] = {
            "angle_unit": "rad", "observations": int(len(block.attitude_photo)),
            "rms_residual": {n: _num(np.sqrt(np.mean(solution.attitude_residuals[:, k] ** 2)))
                             for k, n in enumerate(EXTERIOR_NAMES[3:])},
            "rejected": int((~solution.attitude_active).sum()),
            "max_abs_w": _num(np.nanmax(np.abs(solution.attitude_w), initial=0.0))}
        if block.boresight:
            gnss_imu["imu"]["boresight"] = {
                **{n: float(solution.boresight[k]) for k, n in enumerate(EXTERIOR_NAMES[3:])},
                **{f"std_{n}": _num(solution.boresight_std[k])
                   for k, n in enumerate(EXTERIOR_NAMES[3:])},
                "convention": "IMU attitude = angles of R(photo)·R(boresight)"}
    if gnss_imu:
        summary["gnss_imu"] = gnss_imu
    return {"residual_sign": "computed minus observed; ground: adjusted minus surveyed",
            "summary": summary, "photos": photos, "cameras": cameras,
            "image_observations": observations if observations is not None else
            f"{len(block.obs_photo)} observations: see the POINTS GeoPackage",
            "control_and_check": [{k: v for k, v in g.items() if k not in ("known", "adjusted")}
                                  for g in ground],
            "rejected_observations": rejections, "notes": notes}


def layers(block: Block, solution: Solution, info: dict, ground: list[dict[str, Any]],
           crs, threshold_px: float = 1.0) -> dict[str, Any]:
    """GeoDataFrames: projection_centres, points, image_residuals, ground_residuals."""
    import geopandas as gpd
    import shapely

    centres = [{"photo": pid, **{n: float(solution.exterior[j, k])
                                 for k, n in enumerate(EXTERIOR_NAMES)},
                **{f"std_{n}": _num(solution.exterior_std[j, k])
                   for k, n in enumerate(EXTERIOR_NAMES)},
                "geometry": shapely.Point(solution.exterior[j, :3])}
               for j, pid in enumerate(block.photo_ids)]
    roles = {g["point_id"]: g["role"] for g in ground}
    rays = np.bincount(block.obs_point[solution.obs_active], minlength=block.n_points)
    points = []
    for p, pid in enumerate(block.point_ids):
        if not np.isfinite(solution.points[p]).all():
            continue
        std = solution.point_std[p]
        a, b, angle = error_ellipse(solution.point_cov[p, :2, :2])
        points.append({"point_id": pid, "role": roles.get(pid, "tie"), "n_photos": int(rays[p]),
                       "sigma_x_m": _num(std[0]), "sigma_y_m": _num(std[1]),
                       "sigma_z_m": _num(std[2]), "ellipse_a_m": _num(a), "ellipse_b_m": _num(b),
                       "ellipse_angle_deg": _num(angle),
                       "geometry": shapely.Point(solution.points[p])})
    obs = []
    model = info.get("model_photos", set())
    for i in range(len(block.obs_photo)):
        pt = solution.points[block.obs_point[i]]
        if not np.isfinite(pt).all():
            continue
        pid = block.photo_ids[block.obs_photo[i]]
        v = solution.image_residuals[i]
        size = info["pixel_mm"].get(pid)
        res_px = math.hypot(*v) / size if size else None
        obs.append({"point_id": block.point_ids[block.obs_point[i]], "photo": pid,
                    "res_x_um": _num(1e3 * v[0]) if pid not in model else None,
                    "res_y_um": _num(1e3 * v[1]) if pid not in model else None,
                    "res_px": None if res_px is None else _num(res_px),
                    "w_x": _num(solution.image_w[i, 0]), "w_y": _num(solution.image_w[i, 1]),
                    "r_x": _num(solution.image_r[i, 0]), "r_y": _num(solution.image_r[i, 1]),
                    "rejected": not bool(solution.obs_active[i]),
                    "flagged": bool(solution.obs_active[i]) and res_px is not None
                    and res_px > threshold_px,
                    "geometry": shapely.Point(pt)})
    lines = []
    for g in ground:
        known = np.where(np.isfinite(g["known"]), g["known"], g["adjusted"])
        if not np.isfinite(g["adjusted"]).all():
            continue
        lines.append({"point_id": g["point_id"], "role": g["role"], "type": g["type"],
                      "dx_m": g["dx_m"], "dy_m": g["dy_m"], "dz_m": g["dz_m"],
                      "geometry": shapely.LineString([known, g["adjusted"]])})

    def frame(rows, columns):
        if rows:
            return gpd.GeoDataFrame(rows, geometry="geometry", crs=crs)
        return gpd.GeoDataFrame({c: [] for c in columns}, geometry=[], crs=crs)

    return {"projection_centres": frame(centres, ["photo"]),
            "points": frame(points, ["point_id", "role"]),
            "image_residuals": frame(obs, ["point_id", "photo"]),
            "ground_residuals": frame(lines, ["point_id", "role"])}


GEOMETRY_TYPES = {"projection_centres": "Point Z", "points": "Point Z",
                  "image_residuals": "Point Z", "ground_residuals": "LineString Z"}
