"""orientation:intersect - 3D points from homologous image points on two or more oriented photos."""

from __future__ import annotations

from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.photogrammetry.forward_intersection import STATUS_NAMES, intersect_measured
from toolbox.photogrammetry.tables import write_json
from toolbox.registry import register
from toolbox.ui.photogrammetry import measured_inputs, measured_photos, measurement_parameters, report_output


@register
class SpaceIntersection(Algorithm):
    """Space (forward) intersection of homologous image points by least squares.

    INPUT lists image measurements, one row per point per photo: ``point_id``, ``photo`` (an id
    of PROJECT) and either ``col_px``/``row_px`` (pixels: columns right, rows down, pixel centres
    at +0.5; converted by each photo's interior orientation) or ``x_mm``/``y_mm`` (image mm in the
    fiducial system). CSV/TXT (comma, semicolon or tab) or a GeoPackage table (LAYER).

    Each point seen on two or more photos is solved from all its collinearity equations (domain
    brief sections 4 and 8, with the Impl. note: least squares instead of the thesis' X-only
    eq. [29]): closest point to the rays, then Gauss-Newton on the image residuals, coordinates
    shifted to a local origin. Radial distortion and the principal point are removed from the
    measurements first.

    OUTPUT layers: ``points`` (PointZ; point_id, status, n_photos, sigma0_mm = sqrt(Σv²/(2n-3)),
    std_x/y/z_m from the normal matrix, max_ray_distance_m, max_residual_px when pixels were
    given) and ``rays`` (LineStringZ from each projection centre to its point, with the
    observation's residuals in mm and pixels, computed minus observed). Points that cannot be
    intersected (one photo only, parallel rays, behind a camera) are flagged rows with status
    ``single_ray`` / ``parallel_rays`` / ``behind_camera`` and no geometry, never dropped silently.
    STATISTICS ``rms_residual_mm`` is per coordinate, sqrt(Σ(vx² + vy²) / 2n).
    """

    id = "orientation:intersect"
    display_name = "Space intersection"
    group = "Orientation"
    short_help = "3D points (PointZ) from image points measured on >= 2 oriented photos, with residuals."
    parameters = [
        *measurement_parameters(),
        OutputVector("OUTPUT", "GeoPackage with layers points and rays", layers=[
            Layer("points", "Point Z", [
                ("point_id", "string"), ("status", "string", "ok or why not intersected"),
                ("n_photos", "integer", "photos measuring the point"),
                ("x", "real"), ("y", "real"), ("z", "real"),
                ("sigma0_mm", "real", "a posteriori sigma of unit weight, mm"),
                ("std_x_m", "real"), ("std_y_m", "real"), ("std_z_m", "real"),
                ("max_ray_distance_m", "real", "largest ray-to-point distance, m")],
                "intersected ground points (a max_residual field in the measurement unit)"),
            Layer("rays", "LineString Z", [
                ("point_id", "string"), ("photo", "string"),
                ("res_x_mm", "real", "image residual x, mm"),
                ("res_y_mm", "real", "image residual y, mm")],
                "projection centre to point, per measurement")]),
        report_output("JSON summary"),
    ]
    outputs = [Output("STATISTICS", "points per status, RMS image residual", "json")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import geopandas as gpd
        import shapely

        from toolbox.io.vector_write import write_layers

        project, (ids, photo_ids, xy, kind), _ = measured_inputs(params)
        measured_photos(project, photo_ids)
        photos = [project.photos[p] for p in photo_ids]
        for p in {p.id: p for p in photos}.values():
            p.require_exterior()
        order = list(dict.fromkeys(ids))
        index = {pid: k for k, pid in enumerate(order)}
        point_index = np.array([index[i] for i in ids], dtype=np.int64)
        seen = set()
        for i, p in zip(ids, photo_ids, strict=True):
            if (i, p) in seen:
                raise InputDataError(f"INPUT measures point {i!r} twice on photo {p!r}")
            seen.add((i, p))
        with feedback.timed("intersection"):
            result = intersect_measured(photos, xy, point_index, len(order), kind)
            model = np.array([p.is_model for p in photos])
            if model.any():  # their camera units are not mm: residuals in pixels only
                result.residuals_mm[model] = np.nan
                result.sigma0_mm[np.unique(point_index[model])] = np.nan
        feedback.set_progress(80)
        # residuals in the measurement's own units, through the full model (distortion, IO)
        computed = np.full_like(xy, np.nan)
        for pid in dict.fromkeys(photo_ids):
            rows = [k for k, p in enumerate(photo_ids) if p == pid]
            ok_rows = [k for k in rows if result.ok[point_index[k]]]
            if not ok_rows:
                continue
            photo = project.photos[pid]
            pts = result.xyz[point_index[ok_rows]]
            computed[ok_rows] = photo.ground_to_pixel(pts) if kind == "pixel" else \
                photo.ground_to_image(pts)
        residual_units = computed - xy
        res_norm = np.hypot(residual_units[:, 0], residual_units[:, 1])
        max_res = np.full(len(order), np.nan)
        finite = np.isfinite(res_norm)
        np.fmax.at(max_res, point_index[finite], res_norm[finite])
        unit = "px" if kind == "pixel" else "mm"
        points = []
        for k, pid in enumerate(order):
            ok = bool(result.ok[k])
            points.append({
                "point_id": pid, "status": STATUS_NAMES[int(result.status[k])],
                "n_photos": int(result.n_rays[k]),
                "x": float(result.xyz[k, 0]) if ok else None,
                "y": float(result.xyz[k, 1]) if ok else None,
                "z": float(result.xyz[k, 2]) if ok else None,
                "sigma0_mm": _num(result.sigma0_mm[k]),
                "std_x_m": _num(result.std_xyz[k, 0]), "std_y_m": _num(result.std_xyz[k, 1]),
                "std_z_m": _num(result.std_xyz[k, 2]),
                "max_ray_distance_m": _num(result.max_ray_distance[k]),
                f"max_residual_{unit}": _num(max_res[k]),
                "geometry": shapely.Point(result.xyz[k]) if ok else None})
        rays = []
        for k, (pid, photo) in enumerate(zip(ids, photos, strict=True)):
            pk = point_index[k]
            if not result.ok[pk]:
                continue
            rays.append({"point_id": pid, "photo": photo.id,
                         "res_x_mm": _num(result.residuals_mm[k, 0]),
                         "res_y_mm": _num(result.residuals_mm[k, 1]),
                         f"res_u_{unit}": _num(residual_units[k, 0]),
                         f"res_v_{unit}": _num(residual_units[k, 1]),
                         "geometry": shapely.LineString([photo.exterior.centre, result.xyz[pk]])})
        crs = project.crs
        layers = {"points": gpd.GeoDataFrame(points, geometry="geometry", crs=crs),
                  "rays": gpd.GeoDataFrame(rays, geometry="geometry", crs=crs) if rays else
                  gpd.GeoDataFrame({"point_id": []}, geometry=[], crs=crs)}
        write_layers(params["OUTPUT"], layers, crs=crs,
                     geometry_types={"points": "Point Z", "rays": "LineString Z"})
        ok = result.ok
        stats = {"points": len(order), "status": result.counts(),
                 "observations": len(ids), "coordinates": kind,
                 "rms_residual_mm": _num(rms(result.residuals_mm[ok[point_index]])),
                 f"max_residual_{unit}": _num(np.nanmax(max_res) if ok.any() else np.nan)}
        failed = len(order) - int(ok.sum())
        if failed:
            feedback.push_warning(f"{failed} of {len(order)} points not intersected: "
                                  f"{result.counts()}")
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {"algorithm": self.id, "statistics": stats,
                                          "points": [{k: v for k, v in p.items() if k != "geometry"}
                                                     for p in points]})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}


def _num(value: float) -> float | None:
    value = float(value)
    return value if np.isfinite(value) else None


def rms(values: np.ndarray) -> float:
    """RMS of the finite values (NaN when none: camera models' residuals are in pixels only)."""
    finite = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(finite ** 2))) if finite.size else float("nan")
