"""orientation:precision - normal-case precision estimate (sigma X, Y, Z) of stereo pairs."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.ortho.vertical import project_raster_crs
from toolbox.parameters import File, Number, Output, OutputFile
from toolbox.photogrammetry.normal_case import normal_case_precision, rules_table_sigma_xy
from toolbox.photogrammetry.tables import (
    PROJECT_EXTENSIONS,
    load_project_parameter,
    write_csv,
    write_json,
)
from toolbox.registry import register
from toolbox.ui.photogrammetry import dem_parameters

COLUMNS = ["photo_a", "photo_b", "method", "terrain_height_m", "principal_distance_mm",
           "principal_distance_px", "base_m", "distance_m", "photo_scale", "gsd_m", "base_ratio",
           "sigma_parallax_um", "sigma_image_um", "sigma_pixel_px", "sigma_x_centre_m",
           "sigma_y_centre_m", "sigma_x_edge_m", "sigma_y_edge_m", "sigma_z_m", "sigma_z_edge_m",
           "edge_corners", "sigma_xy_table_m", "xi_edge_mm", "eta_edge_mm"]
NORMAL_CASE = "normal case"
#: half the standard 23 x 23 cm aerial film format: the edge estimate without PROJECT (no frame known)
STANDARD_HALF_FORMAT_MM = 115.0
MODELS = "intersection through the camera models"


def pair_precision(c_mm: float, base_m: float, distance_m: float, sigma_parallax_um: float,
                   sigma_image_um: float | None, xi_edge_mm: float, eta_edge_mm: float
                   ) -> dict[str, Any]:
    """Precision at the image centre and at the format's edge (ξ, η) of the left photo."""
    centre = normal_case_precision(c_mm, base_m, distance_m, sigma_parallax_um, sigma_image_um)
    edge = normal_case_precision(c_mm, base_m, distance_m, sigma_parallax_um, sigma_image_um,
                                 xi_edge_mm, eta_edge_mm)
    return {"method": NORMAL_CASE, "principal_distance_mm": c_mm, "base_m": base_m, "distance_m": distance_m,
            "photo_scale": centre["photo_scale"], "base_ratio": centre["base_ratio"],
            "sigma_parallax_um": sigma_parallax_um, "sigma_image_um": centre["sigma_image_um"],
            "sigma_x_centre_m": centre["sigma_x_m"], "sigma_y_centre_m": centre["sigma_y_m"],
            "sigma_x_edge_m": edge["sigma_x_m"], "sigma_y_edge_m": edge["sigma_y_m"],
            "sigma_z_m": centre["sigma_z_m"], "sigma_z_edge_m": edge["sigma_z_m"],
            "sigma_xy_table_m": rules_table_sigma_xy(c_mm, base_m, distance_m, sigma_parallax_um),
            "xi_edge_mm": xi_edge_mm, "eta_edge_mm": eta_edge_mm}


@register
class NormalCasePrecision(Algorithm):
    """Precision of stereo restitution estimated with the normal case (domain brief section 7).

    ``σZ = m_b·(Z/B)·σp`` and ``σX = m_b·sqrt((ξ·Z/(c·B))²·σp² + σξ²)`` (σY likewise with η), with
    m_b = Z/c the photo scale, B the base, Z the distance from the projection centres to the
    terrain, σp the x-parallax precision and σξ the image-coordinate precision (S000 l.605-649,
    S002 eq. [35]-[40]). The defaults, SIGMA_PARALLAX = 5 µm and SIGMA_IMAGE = σp/√2, reproduce
    the σZ column of S000's rules table. σX and σY are given at the image centre and at the edge
    of the format (ξ, η = half the format, 115 mm of a 23 x 23 cm frame without PROJECT, or
    XI/ETA); these are per-axis figures.

    ``sigma_xy_table_m`` is the quantity S000's rules table prints as σXY: the two-axis figure
    ``sqrt(σX² + σY²)`` with σξ = ση = σp = SIGMA_PARALLAX at a point c/3 from the principal
    point, ``m_b·σp·sqrt(2 + (Z/B)²/9)`` (0.072 m at 1:10,000 for B/Z = 1, where the per-axis
    σX at the centre with the default SIGMA_IMAGE is 0.035 m).

    With PROJECT, every stereo pair (consecutive photos of a strip) is evaluated: B is the distance
    between the projection centres, Z the mean Z0 minus the terrain height (MEAN_HEIGHT, or the
    DEM at the two nadir points and their midpoint), c the camera's principal distance.
    Without PROJECT, give PRINCIPAL_DISTANCE, BASE and DISTANCE for one configuration.

    Digital cameras given as camera models (pinhole, Brown, OpenCV, fisheye: ``model:`` in the
    project) have no film plane: their pairs are computed through the models themselves
    (``method``: intersection through the camera models), the covariance of the least-squares
    intersection ``σ²·(JᵀJ)⁻¹`` with J the derivatives of both photos' pixels with respect to
    X, Y, Z (distortion and tilts included) and σ = SIGMA_PIXEL per measured pixel coordinate
    (the x-parallax then has √2·σ; in the normal case this is the formula above, in pixels).
    ``centre``: the ground point below the middle of the base, on the terrain height; ``edge``:
    the worst of the points seen at the left photo's image corners that both photos see
    (``edge_corners`` of 4). The µm and mm fields are empty; ``principal_distance_px``,
    ``gsd_m`` (Z/f) and ``sigma_pixel_px`` are filled. A pair of consecutive photos that does
    not both see the point below the middle of its base is not a stereo pair: skipped with a
    warning.
    Outputs: a JSON report and optionally a CSV table; PRECISION returns the rows.
    """

    id = "orientation:precision"
    display_name = "Normal-case precision"
    group = "Orientation"
    short_help = "Estimated sigma X, Y, Z of stereo pairs from scale, base and parallax accuracy."
    parameters = [
        File("PROJECT", "orientation project (YAML); its stereo pairs are evaluated",
             extensions=PROJECT_EXTENSIONS, optional=True),
        *dem_parameters("terrain heights, for the distance to the terrain", optional=True),
        Number("MEAN_HEIGHT", "terrain height (CRS units), instead of a DEM", optional=True),
        Number("PRINCIPAL_DISTANCE", "c, mm (without PROJECT)", optional=True, min_value=0,
               min_exclusive=True),
        Number("BASE", "base B, m (without PROJECT)", optional=True, min_value=0,
               min_exclusive=True),
        Number("DISTANCE", "distance Z from the projection centres to the terrain, m (without "
               "PROJECT)", optional=True, min_value=0, min_exclusive=True),
        Number("SIGMA_PARALLAX", "x-parallax precision σp, µm", default=5.0, min_value=0,
               min_exclusive=True),
        Number("SIGMA_IMAGE", "image-coordinate precision σξ = ση, µm (default σp/√2)",
               optional=True, min_value=0),
        Number("SIGMA_PIXEL", "camera models: precision σ of each measured image coordinate, "
               "pixels", default=0.5, min_value=0, min_exclusive=True),
        Number("XI", "film: image x (mm) for the edge estimate (default: half the format width; "
               "115, of a 23 x 23 cm frame, without PROJECT)",
               optional=True),
        Number("ETA", "film: image y (mm) for the edge estimate (default: half the format "
               "height; 115 without PROJECT)", optional=True),
        OutputFile("OUTPUT", "JSON report", extensions=[".json"]),
        OutputFile("TABLE", "CSV table, one row per pair", extensions=[".csv"], optional=True),
    ]
    outputs = [Output("PRECISION", "one dict per stereo pair (or the single configuration)",
                      "json")]

    def check(self, params: dict[str, Any]) -> None:
        if params["PROJECT"] is None:
            for name in ("PRINCIPAL_DISTANCE", "BASE", "DISTANCE"):
                if params[name] is None:
                    raise self.fail(name, "is required when no PROJECT is given (a number > 0)")
        elif params["DEM"] is None and params["MEAN_HEIGHT"] is None:
            raise self.fail("MEAN_HEIGHT", "is required with PROJECT when no DEM is given (the "
                            "terrain height the distance is measured to)")

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        sp, si = params["SIGMA_PARALLAX"], params["SIGMA_IMAGE"]
        rows: list[dict[str, Any]] = []
        if params["PROJECT"] is None:
            xi = params["XI"] if params["XI"] is not None else STANDARD_HALF_FORMAT_MM
            eta = params["ETA"] if params["ETA"] is not None else STANDARD_HALF_FORMAT_MM
            rows.append({"photo_a": None, "photo_b": None} | pair_precision(
                params["PRINCIPAL_DISTANCE"], params["BASE"], params["DISTANCE"], sp, si, xi, eta))
        else:
            rows = self._project_rows(params, feedback)
        rows = [{c: r.get(c) for c in COLUMNS} for r in rows]  # every field, None if it has none
        write_json(params["OUTPUT"], {
            "algorithm": self.id, "method": "normal case, S000 l.605-649 (brief section 7)",
            "units": {"sigma": "m", "base": "m", "distance": "m", "image": "mm",
                      "sigma_parallax": "um"}, "pairs": rows})
        if params["TABLE"] is not None:
            write_csv(params["TABLE"], COLUMNS, [[r.get(c) for c in COLUMNS] for r in rows])
        return {"OUTPUT": params["OUTPUT"], "TABLE": params["TABLE"], "PRECISION": rows}

    @staticmethod
    def _project_rows(params: dict[str, Any], feedback: Feedback) -> list[dict[str, Any]]:
        project = load_project_parameter(params["PROJECT"])
        dem = params["DEM"]
        project_raster_crs(project.crs, None if dem is None else dem.crs,
                           bounds=None if dem is None else dem.bounds)
        pairs = project.consecutive_pairs()
        if not pairs:
            raise InputDataError(f"PROJECT {params['PROJECT']} has no stereo pair (two oriented "
                                 "photos in one strip)")
        surface = None
        if dem is not None and params["MEAN_HEIGHT"] is None:
            from toolbox.photogrammetry.surface import read_dem_window

            centres = np.array([p.require_exterior().centre for pair in pairs for p in pair])
            bounds = (centres[:, 0].min(), centres[:, 1].min(), centres[:, 0].max(),
                      centres[:, 1].max())
            surface = read_dem_window(dem, bounds, params["BAND"])
        rows = []
        for a, b in feedback.iterate(pairs):
            ca, cb = a.require_exterior().centre, b.require_exterior().centre
            if surface is None:
                ground = params["MEAN_HEIGHT"]
            else:
                xs = np.array([ca[0], cb[0], (ca[0] + cb[0]) / 2])
                ys = np.array([ca[1], cb[1], (ca[1] + cb[1]) / 2])
                heights = surface.height(xs, ys)
                if not np.isfinite(heights).any():
                    raise InputDataError(f"DEM {dem} has no height below photos {a.id}, {b.id}; "
                                         "give MEAN_HEIGHT")
                ground = float(np.nanmean(heights))
            distance = (ca[2] + cb[2]) / 2 - ground
            if not distance > 0:
                raise InputDataError(f"photos {a.id}, {b.id}: the projection centres are not above "
                                     f"the terrain height {ground:.2f}")
            row = {"photo_a": a.id, "photo_b": b.id, "terrain_height_m": ground}
            if a.is_model or b.is_model:
                check_model_pair(a, b, params)
                try:
                    rows.append(row | model_row(a, b, ground, params["SIGMA_PIXEL"]))
                except InputDataError as exc:
                    feedback.push_warning(f"photos {a.id}, {b.id} skipped: {exc}")
                continue
            c = (a.camera.c + b.camera.c) / 2
            outline = a.frame_outline_mm(1)
            xi = params["XI"] if params["XI"] is not None else float(np.abs(outline[:, 0]).max())
            eta = params["ETA"] if params["ETA"] is not None else float(np.abs(outline[:, 1]).max())
            base = float(np.linalg.norm(cb - ca))
            rows.append(row | pair_precision(c, base, distance, params["SIGMA_PARALLAX"],
                                             params["SIGMA_IMAGE"], xi, eta))
        if not rows:
            raise InputDataError(f"PROJECT {params['PROJECT']}: no pair of consecutive photos is "
                                 "a stereo pair (each skipped: see the warnings)")
        if not all(math.isfinite(r["sigma_z_m"]) for r in rows):
            raise InputDataError("a pair gave a non-finite precision (check the orientations)")
        return rows


def check_model_pair(a: Any, b: Any, params: dict[str, Any]) -> None:
    """Refuse a pair of a film and a model camera, and XI/ETA (film mm) with model cameras."""
    if not (a.is_model and b.is_model):
        film = b if a.is_model else a
        raise InputDataError(f"photos {a.id}, {b.id}: photo {film.id} has a film camera, the "
                             "other a camera model: a pair is evaluated with one kind of camera")
    for name in ("XI", "ETA"):
        if params[name] is not None:
            raise ParameterError(name, f"is in film mm: photos {a.id}, {b.id} have camera "
                                 "models, whose edge is their image corners")


def model_row(a: Any, b: Any, ground: float, sigma_px: float) -> dict[str, Any]:
    """The precision of a pair of camera-model photos (the class docstring)."""
    from toolbox.photogrammetry.pair_precision import model_pair_precision

    return {"method": MODELS} | model_pair_precision(a.sensor(), b.sensor(), ground, sigma_px)
