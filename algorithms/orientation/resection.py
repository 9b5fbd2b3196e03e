"""orientation:resection - exterior orientation of single photos from >= 4 control points."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register
from toolbox.ui.photogrammetry import (
    control_parameter,
    measured_inputs,
    measurement_parameters,
    report_output,
)


@register
class SpaceResection(Algorithm):
    """Single-photo space resection: X0, Y0, Z0, omega, phi, kappa of each photo from control
    points measured on it (collinearity least squares, domain brief section 4).

    PROJECT gives the cameras and interior orientations (its exterior orientations, when present,
    are not needed: START chooses). INPUT lists image measurements as for orientation:intersect
    (``point_id``, ``photo``, ``col_px``/``row_px`` or ``x_mm``/``y_mm``); CONTROL the ground
    coordinates (``id``, ``X``, ``Y``, ``Z``, optional ``role`` control/check: check points are not
    used in the fit, only reported). Every photo of INPUT with at least 4 control points is
    resected.

    Method: Levenberg-Marquardt on the 2n collinearity equations with the 6 parameters, on ground
    coordinates shifted to the centroid of the control points. START ``auto`` needs no
    approximate values for near-vertical photos: a plane similarity image -> ground gives the
    scale, hence the flying height, kappa and the nadir; ``project`` starts from PROJECT's
    exterior orientation instead (oblique photos). Too few points (< 4) or points on one line
    are refused.

    Output: OUTPUT, an orientation project (YAML) equal to PROJECT with the resected exterior
    orientations (angles in radians), readable by every algorithm that takes a PROJECT; REPORT
    (JSON): per photo the six parameters with standard deviations from ``sigma0²·(JᵀJ)⁻¹``,
    sigma0 (µm, image), redundancy 2n - 6, and the residual of every point (computed minus
    observed, µm and pixels when measured in pixels) including check points.
    """

    id = "orientation:resection"
    display_name = "Space resection"
    group = "Orientation"
    short_help = "Exterior orientation of single photos from >= 4 control points (collinearity LSQ)."
    parameters = [
        *measurement_parameters("orientation project (YAML) with cameras and interior "
                                "orientations"),
        control_parameter(),
        Enum("START", "start values: auto (near-vertical photos, no approximate values needed) or "
             "project (PROJECT's exterior orientation)", options=("auto", "project"),
             default="auto"),
        OutputFile("OUTPUT", "orientation project (YAML) with the resected orientations",
                   extensions=[".yaml", ".yml"]),
        report_output("JSON report: parameters, standard deviations, residuals"),
    ]
    outputs = [Output("STATISTICS", "photos resected, sigma0 per photo (µm; camera models: "
                      "sigma0_px)", "dict")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.photogrammetry.orientation_check import resect_photos
        from toolbox.photogrammetry.project import save_project
        from toolbox.photogrammetry.tables import write_json

        project, measurements, control = measured_inputs(params, control=True)
        if project.crs is not None and len(control[1]):  # as for layers: one check everywhere
            from toolbox.io.crs import check_coordinates_in_area

            check_coordinates_in_area("CONTROL", project.crs, control[1][:, :2],
                                      feedback.push_warning)
        exteriors, report = resect_photos(project, measurements, control,
                                          use_project_start=params["START"] == "project",
                                          feedback=feedback)
        save_project(project.with_exteriors(exteriors), params["OUTPUT"], relative_images=False)
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {"algorithm": self.id, "residual_sign":
                                          "computed minus observed", "photos": report})
        stats = {"photos": len(report),
                 "sigma0_um": {pid: r["sigma0_um"] for pid, r in report.items()}}
        px = {pid: r["sigma0_px"] for pid, r in report.items() if "sigma0_px" in r}
        if px:  # camera models (no film plane): sigma0 in pixels, sigma0_um None
            stats["sigma0_px"] = px
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}
