"""orientation:interior - interior orientation of scanned photos from their fiducial marks."""

from __future__ import annotations

import math
from collections import defaultdict
from typing import Any

import numpy as np

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, File, String
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.photogrammetry.fiducials import InteriorOrientation, transformation_name
from toolbox.photogrammetry.tables import (
    column,
    finite_or_none,
    load_project_parameter,
    number,
    read_csv_table,
    write_csv,
    write_json,
)
from toolbox.registry import register
from toolbox.ui.photogrammetry import project_parameter

TRANSFORMATIONS = ("affine", "homography", "similarity", "from_input")


def fit_photo(calibrated: dict[str, tuple[float, float]], measured: dict[str, tuple[float, float]],
              transformation: str, photo: str) -> dict[str, Any]:
    """Fit one photo and describe it (matrices, residuals, sigma) as a JSON-ready dict."""
    io = InteriorOrientation.fit(calibrated, measured, transformation, photo)
    marks = []
    fitted = io.pixel_to_image(np.array([measured[m] for m in io.marks]))
    for k, mark in enumerate(io.marks):
        vx, vy = (float(v) for v in io.residuals_mm[k])
        marks.append({"mark": mark, "col_px": measured[mark][0], "row_px": measured[mark][1],
                      "x_mm": calibrated[mark][0], "y_mm": calibrated[mark][1],
                      "fitted_x_mm": float(fitted[k, 0]), "fitted_y_mm": float(fitted[k, 1]),
                      "res_x_mm": vx, "res_y_mm": vy, "res_mm": math.hypot(vx, vy)})
    return {"transformation": io.transformation, "marks": len(io.marks),
            "redundancy": io.redundancy, "sigma0_mm": finite_or_none(io.sigma0_mm),
            "variance_mm2": finite_or_none(io.variance_mm2),
            "max_residual_mm": max(m["res_mm"] for m in marks),
            "pixel_size_mm": io.pixel_size_mm,
            "pixel_to_fiducial": io.pixel_to_fiducial.tolist(),
            "fiducial_to_pixel": io.fiducial_to_pixel.tolist(), "residuals": marks}


@register
class InteriorOrientationAlgorithm(Algorithm):
    """Interior orientation of scanned aerial photos from their fiducial marks.

    For each photo the measured pixel positions of the fiducial marks (``col_px``, ``row_px``;
    columns right, rows down) are mapped onto their calibrated coordinates (``x_mm``, ``y_mm``;
    fiducial system, y up) by least squares: an affine transform (6 parameters, >= 3 marks) or a
    homography (8 parameters, >= 4 marks; Gauss-Newton from a normalised DLT), or a similarity (4).
    Domain brief section 2 (thesis S002 eq. [4]-[9]). Residuals are fitted minus calibrated, in
    mm; ``sigma0_mm = sqrt(Σv²/r)`` and ``variance_mm2 = Σv²/r``, which is what the Z-Map reports
    print as "Sigma globale" (r = 2·marks - parameters; with 4 marks a homography has r = 0 and
    zero residuals). The fit reproduces every Siena report (e.g. 1_7150, affine: residuals
    ±0.001897 / ±0.000765 mm, Sigma globale 0.000008).

    INPUT is a delimited table (comma, semicolon or tab) with one row per measured mark:
    ``photo``, ``mark_id`` (or ``mark``), ``col_px``, ``row_px``, and the calibrated ``x_mm``,
    ``y_mm`` unless PROJECT gives them (from the photo's camera, or the camera named in a
    ``camera`` column). Optional: ``transformation`` (used with TRANSFORMATION=from_input:
    AFFINE, OMOGRAFICA/homography, similarity) and ``source`` (rows are grouped by photo and
    source; SOURCE keeps one source). Outputs: a JSON report (matrices pixel -> fiducial and back,
    per-mark residuals, sigma) and optionally a CSV of the residuals.
    """

    id = "orientation:interior"
    display_name = "Interior orientation from fiducial marks"
    group = "Orientation"
    short_help = "Fit pixel -> fiducial transforms (affine/homography) per photo; residuals, sigma."
    parameters = [
        File("INPUT", "measured fiducial marks (CSV: photo, mark_id, col_px, row_px[, x_mm, y_mm])",
             extensions=[".csv", ".txt"]),
        project_parameter("orientation project (YAML) giving the calibrated marks of each photo's "
                          "camera, when INPUT has no x_mm/y_mm", optional=True),
        Enum("TRANSFORMATION", "transform fitted; from_input uses INPUT's transformation column",
             options=TRANSFORMATIONS, default="affine"),
        String("SOURCE", "keep only rows whose 'source' column equals this", optional=True),
        OutputFile("OUTPUT", "JSON report", extensions=[".json"]),
        OutputFile("RESIDUALS", "CSV of per-mark residuals", extensions=[".csv"], optional=True),
    ]
    outputs = [Output("STATISTICS", "photos fitted, largest residual and sigma", "json")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        path = params["INPUT"]
        header, rows = read_csv_table(path)
        c_photo = column(header, "photo", "photo_id", "image", path=path)
        c_mark = column(header, "mark_id", "mark", "fiducial", "id", path=path)
        c_col = column(header, "col_px", "col", "x_px", "column", path=path)
        c_row = column(header, "row_px", "row", "y_px", path=path)
        c_x = column(header, "x_mm", required=False)
        c_y = column(header, "y_mm", required=False)
        c_kind = column(header, "transformation", required=False)
        c_source = column(header, "source", required=False)
        c_camera = column(header, "camera", required=False)
        if params["SOURCE"] is not None:
            if c_source is None:
                raise InputDataError(f"SOURCE is given but INPUT {path} has no 'source' column")
            rows = [r for r in rows if r[c_source] == params["SOURCE"]]
            if not rows:
                raise InputDataError(f"INPUT {path} has no row with source {params['SOURCE']!r}")
        project = None if params["PROJECT"] is None else load_project_parameter(params["PROJECT"])
        if (c_x is None or c_y is None) and project is None:
            raise InputDataError(f"INPUT {path} has no x_mm/y_mm columns: give PROJECT so the "
                                 "calibrated marks come from the photos' cameras")
        groups: dict[tuple[str, str], list[dict[str, str]]] = defaultdict(list)
        for row in rows:
            groups[(row[c_photo], row[c_source] if c_source else "")].append(row)
        photos = []
        residual_rows = []
        for (photo, source), group in feedback.iterate(list(groups.items())):
            calibrated, measured = self._marks(group, photo, project, c_mark, c_col, c_row, c_x,
                                               c_y, c_camera)
            kind = params["TRANSFORMATION"]
            if kind == "from_input":
                values = {r[c_kind] for r in group} if c_kind else {""}
                if len(values) != 1 or "" in values:
                    raise InputDataError(f"TRANSFORMATION is from_input but photo {photo!r}"
                                         f"{' (source ' + source + ')' if source else ''} has "
                                         f"transformation value(s) {sorted(values)} in INPUT")
                kind = transformation_name(values.pop(), f"INPUT photo {photo!r} transformation")
            entry = {"photo": photo, "source": source or None} | fit_photo(calibrated, measured,
                                                                          kind, photo)
            photos.append(entry)
            for m in entry["residuals"]:
                residual_rows.append([photo, source, m["mark"], m["col_px"], m["row_px"],
                                      m["x_mm"], m["y_mm"], m["fitted_x_mm"], m["fitted_y_mm"],
                                      m["res_x_mm"], m["res_y_mm"], m["res_mm"],
                                      entry["transformation"]])
        stats = {"photos": len(photos),
                 "max_residual_mm": max(p["max_residual_mm"] for p in photos),
                 "max_sigma0_mm": max((p["sigma0_mm"] for p in photos
                                       if p["sigma0_mm"] is not None), default=None)}
        write_json(params["OUTPUT"], {"algorithm": self.id, "input": str(path),
                                      "residual_convention": "fitted - calibrated, mm",
                                      "statistics": stats, "photos": photos})
        if params["RESIDUALS"] is not None:
            write_csv(params["RESIDUALS"],
                      ["photo", "source", "mark_id", "col_px", "row_px", "x_mm", "y_mm",
                       "fitted_x_mm", "fitted_y_mm", "res_x_mm", "res_y_mm", "res_mm",
                       "transformation"], residual_rows)
        return {"OUTPUT": params["OUTPUT"], "RESIDUALS": params["RESIDUALS"], "STATISTICS": stats}

    @staticmethod
    def _marks(group, photo, project, c_mark, c_col, c_row, c_x, c_y, c_camera):
        measured: dict[str, tuple[float, float]] = {}
        calibrated: dict[str, tuple[float, float]] = {}
        camera_marks = None
        if c_x is None or c_y is None:
            if c_camera and group[0][c_camera] in project.cameras:
                camera_marks = project.cameras[group[0][c_camera]].fiducials_mm
            elif photo in project.photos:
                camera_marks = project.photos[photo].camera.fiducials_mm
            else:
                raise InputDataError(f"photo {photo!r} of INPUT has no camera: it is not in "
                                     f"PROJECT and names no camera of it")
        for row in group:
            mark = row[c_mark]
            if mark in measured:
                raise InputDataError(f"INPUT: photo {photo!r} lists mark {mark!r} twice (add a "
                                     "'source' column or filter with SOURCE)")
            measured[mark] = (number(row[c_col], f"photo {photo} mark {mark} col_px"),
                              number(row[c_row], f"photo {photo} mark {mark} row_px"))
            if camera_marks is None:
                calibrated[mark] = (number(row[c_x], f"photo {photo} mark {mark} x_mm"),
                                    number(row[c_y], f"photo {photo} mark {mark} y_mm"))
        if camera_marks is not None:
            calibrated = dict(camera_marks)
        return calibrated, measured
