"""orientation:relative - relative orientation of a stereo pair from homologous points."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, String
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register
from toolbox.ui.photogrammetry import measured_inputs, measurement_parameters, report_output


@register
class RelativeOrientation(Algorithm):
    """Relative orientation of two photos from >= 5 homologous points (6-12 recommended, in the
    Gruber positions; 002 par. 1.5.2, eq. [22]-[24]; 003).

    INPUT: image measurements as for orientation:bundle (``point_id``, ``photo``,
    ``col_px``/``row_px`` or ``x_mm``/``y_mm``); the points measured on both PHOTO1 and PHOTO2
    are used (default: the two photos of INPUT). Pixels go to image mm through each photo's
    interior orientation, then to camera coordinates (principal point, distortion).

    PARAMETERS: ``dependent`` (asymmetric: photo 1 fixed, unknowns by, bz, omega2, phi2, kappa2;
    eq. [24]) or ``independent`` (symmetric: base along X, unknowns phi1, kappa1, omega2, phi2,
    kappa2; eq. [23]). Condition: coplanarity of the base and the two rays; residuals are the
    y-parallaxes of the points (image mm at photo 1's scale), minimised exactly by
    Levenberg-Marquardt from the normal case. The model has ``bx = 1`` (arbitrary scale).
    A weak geometry (points near the critical cylinder through both projection centres) is a
    warning.

    OUTPUT (CSV): per point the model coordinates ``X, Y, Z`` and the residual y-parallax
    ``py_um`` (µm; ``py_px``, pixels, when photo 1 is a camera model: pinhole, Brown, OpenCV,
    fisheye, measured in pixels and undistorted through its model). REPORT (JSON): the 5
    parameters with standard deviations, the rotation matrices and base, sigma0 (µm, or px),
    redundancy n - 5, condition number and warnings.
    """

    id = "orientation:relative"
    display_name = "Relative orientation"
    group = "Orientation"
    short_help = "Relative orientation of a stereo pair (coplanarity; dependent or independent " \
                 "parameters), model coordinates and y-parallaxes."
    parameters = [
        *measurement_parameters("orientation project (YAML): cameras and interior orientations"),
        String("PHOTO1", "left photo id (default: the first photo of INPUT)", optional=True),
        String("PHOTO2", "right photo id (default: the second photo of INPUT)", optional=True),
        Enum("PARAMETERS", "parameter set: dependent (by, bz, ω2, φ2, κ2) or independent "
             "(φ1, κ1, ω2, φ2, κ2)", options=("dependent", "independent"), default="dependent"),
        OutputFile("OUTPUT", "model points: point_id, X, Y, Z (model units, bx = 1), py_um",
                   extensions=[".csv"]),
        report_output(),
    ]
    outputs = [Output("STATISTICS", "parameters, sigma0 (µm), redundancy, warnings", "dict")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import numpy as np

        from toolbox.photogrammetry.forward_intersection import camera_observations, principal_distance
        from toolbox.photogrammetry.tables import write_csv, write_json
        from toolbox.triangulation.relative import RelativeRequest, relative_orientation

        project, (ids, photos, xy, kind), _ = measured_inputs(params)
        order = list(dict.fromkeys(photos))
        left = params["PHOTO1"] or (order[0] if order else None)
        right = params["PHOTO2"] or (order[1] if len(order) > 1 else None)
        for name, pid in (("PHOTO1", left), ("PHOTO2", right)):
            if pid is None:
                raise self.fail("INPUT", f"measures {len(order)} photo(s) "
                                f"({', '.join(order) or 'none'}): a relative orientation needs "
                                "a pair")
            if pid not in order:
                raise self.fail(name, f"photo {pid!r} has no measurements in INPUT (photos: "
                                f"{', '.join(order)})")
            if pid not in project.photos:
                raise self.fail(name, f"photo {pid!r} is not in PROJECT")
        if left == right:
            raise self.fail("PHOTO2", f"must differ from PHOTO1 ({left!r})")
        per = {left: {}, right: {}}
        for k, (i, p) in enumerate(zip(ids, photos, strict=True)):
            if p in per:
                if i in per[p]:
                    raise self.fail("INPUT", f"measures point {i!r} twice on photo {p!r}")
                per[p][i] = k
        common = [i for i in per[left] if i in per[right]]
        rows1 = [per[left][i] for i in common]
        rows2 = [per[right][i] for i in common]
        p1, p2 = project.photos[left], project.photos[right]
        xy1 = camera_observations([p1] * len(rows1), xy[rows1], kind)
        xy2 = camera_observations([p2] * len(rows2), xy[rows2], kind)
        result = relative_orientation(RelativeRequest(xy1, xy2, principal_distance(p1),
                                                      principal_distance(p2),
                                                      params["PARAMETERS"]))
        for w in result.warnings:
            feedback.push_warning(w)
        # a camera model's units are pixel-sized: its parallaxes in pixels (photo 1's scale)
        unit, factor = ("px", 1.0) if p1.is_model else ("um", 1e3)
        write_csv(params["OUTPUT"], ["point_id", "X", "Y", "Z", f"py_{unit}"],
                  [[i, *map(float, result.model[k]), float(factor * result.py_mm[k])]
                   for k, i in enumerate(common)])
        stats = {"photos": [left, right], "points": len(common),
                 "parameter_set": params["PARAMETERS"], "parameters": result.parameters,
                 f"sigma0_{unit}": None if np.isnan(result.sigma0_mm) else
                 factor * result.sigma0_mm,
                 "redundancy": result.redundancy, "warnings": result.warnings}
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {
                "algorithm": self.id, **stats, "angle_unit": "rad",
                "std": {k: (None if np.isnan(v) else v) for k, v in result.std.items()},
                "base": result.base, "rotation1": result.rotation1,
                "rotation2": result.rotation2, "condition_number": result.condition,
                "residual": f"y-parallax, image {'pixels' if p1.is_model else 'mm'} at "
                            "photo 1's scale"})
        return {"OUTPUT": params["OUTPUT"], "REPORT": params["REPORT"], "STATISTICS": stats}
