"""report:quality - the project's quality report (PDF or HTML) from the JSON run reports."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Folder, Number, String
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register


@register
class Quality(Algorithm):
    """A quality report for the client, drawn from the JSON run reports in ``REPORTS`` (the
    ``reports/`` folder a pipeline or ``toolbox demo`` writes) and the residual files they name;
    nothing is recomputed.

    The first page is the verdict: every product against the specification's tolerances at the
    map scale, each criterion with what was measured, the tolerance, pass / FAIL / not checked
    and its source, and an overall ACCEPTED (saying how many criteria were checked and naming
    those not checked), NOT ACCEPTED or NOT CHECKED (no criterion measured; also in the
    console and in CONTENTS' ``overall``). Tolerances: planimetric RMS <=
    ``RULE_MM`` mm x ``ORTHO_SCALE`` (by default S002 §2.6.6's rule at that scale, as
    orientation:check and rectify:estimate judge: 0.5 mm for large scales, up to 1:5000, 0.3 mm
    for smaller ones) for orthophotos, rectification and orientation check points; height RMSE <=
    ``CONTOUR_INTERVAL`` / 3.29 (90 % of the points within half the contour interval, the
    National Map Accuracy Standard's rule; S002 uses 5 m at 1:5000); fiducial residuals <=
    ``IO_TOLERANCE_UM`` (a producer's threshold: set the tender's).

    Then the sections of the runs found: interior orientation (residuals per photo, vectors at
    the marks), orientation (resection, absolute orientation, orientation check: control and
    check points), rectification (residual vectors of control, check and rejected points),
    orthophotos (with the check points measured on them by ``report:ortho_check`` runs: RMSE
    and a verdict per orthophoto; "not checked" without such a run), DEM cross-validation
    (RMSE per method, error histograms, a map of the best method's errors), mosaic and
    seamlines, topology (what the check found and fixed), every warning of every run, and the
    list of runs. File paths are shown by name only. ``OUTPUT`` ``.pdf`` (A4 pages, sections
    flowed onto them) or ``.html`` (one page, figures embedded).
    """

    id = "report:quality"
    display_name = "Quality report"
    group = "Reports"
    short_help = "Quality report (PDF/HTML) with residual plots, from the JSON run reports."
    parameters = [
        Folder("REPORTS", "folder of JSON run reports"),
        String("TITLE", "report title", default="Quality report"),
        Number("ORTHO_SCALE", "map and orthophoto scale denominator of the specification",
               default=5000.0, min_value=1),
        Number("RULE_MM", "allowed planimetric RMS on paper, mm (default: S002 §2.6.6 at "
               "ORTHO_SCALE, 0.5 up to 1:5000, 0.3 at smaller scales)", optional=True,
               min_value=0, min_exclusive=True),
        Number("CONTOUR_INTERVAL", "contour interval of the map, m (height tolerance: "
               "interval / 3.29)", default=5.0, min_value=0, min_exclusive=True),
        Number("IO_TOLERANCE_UM", "largest fiducial residual accepted, µm", default=15.0,
               min_value=0, min_exclusive=True),
        OutputFile("OUTPUT", "report (.pdf or .html)", extensions=[".pdf", ".html"]),
    ]
    outputs = [Output("CONTENTS", "runs, sections and figure counts", "dict")]

    def check(self, params):
        from pathlib import Path

        from toolbox.cartography.quality import load_reports

        folder = Path(params["REPORTS"])
        if not any(folder.glob("*.json")):
            raise self.fail("REPORTS", f"folder '{params['REPORTS']}' holds no .json report")
        if not load_reports(folder):  # JSON outputs (vector:info's...), not run reports
            raise self.fail("REPORTS", f"folder '{params['REPORTS']}' holds no run report (the "
                            "JSON --run-report or --report-dir writes, with 'algorithm' and "
                            "'outputs'); its .json files are something else")

    def process(self, params, feedback: Feedback):
        from toolbox.cartography.quality import Specification, write_report
        from toolbox.photogrammetry.accuracy import planimetric_tolerance_mm

        rule_mm = params["RULE_MM"]
        if rule_mm is None:
            rule_mm = planimetric_tolerance_mm(params["ORTHO_SCALE"], "ORTHO_SCALE")
        spec = Specification(params["ORTHO_SCALE"], rule_mm,
                             params["CONTOUR_INTERVAL"], params["IO_TOLERANCE_UM"])
        contents = write_report(params["REPORTS"], params["OUTPUT"], params["TITLE"], spec)
        if not contents["sections"]:
            feedback.push_warning("no run report with residuals or counts was found: the "
                                  "report lists the runs only")
        feedback.push_info(f"Overall: {contents['overall']}")
        return {"OUTPUT": params["OUTPUT"], "CONTENTS": contents}
