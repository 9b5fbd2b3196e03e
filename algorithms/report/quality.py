"""report:quality - the project's quality report (PDF or HTML) from the JSON run reports."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Number, Output, OutputFile, String
from toolbox.registry import register


@register
class Quality(Algorithm):
    """A quality report for the client, drawn from the JSON run reports in ``REPORTS`` (the
    ``reports/`` folder a pipeline or ``toolbox demo`` writes) and the residual files they name;
    nothing is recomputed.

    Sections appear for the runs found: interior orientation (residual vectors at the fiducial
    marks per photo), rectification (residual vectors of control, check and rejected points;
    the check-point RMSE against the orthophoto rule RMS <= ``RULE_MM`` mm x ``ORTHO_SCALE``,
    S002 §2.6.6: 0.3 mm for small scales, 0.5 mm for large ones), DEM cross-validation (RMSE
    per method, error histograms, a map of the best method's errors) and topology (error and
    fix counts), after a table of every run. ``OUTPUT`` ``.pdf`` (one page per table and figure)
    or ``.html`` (one page, figures embedded).
    """

    id = "report:quality"
    display_name = "Quality report"
    group = "Reports"
    short_help = "Quality report (PDF/HTML) with residual plots, from the JSON run reports."
    parameters = [
        String("REPORTS", "folder of JSON run reports"),
        String("TITLE", "report title", default="Quality report"),
        Number("ORTHO_SCALE", "orthophoto scale denominator for the accuracy rule",
               default=5000.0, min_value=1),
        Number("RULE_MM", "allowed orthophoto RMS on paper, mm (0.3 small, 0.5 large scales)",
               default=0.3, min_value=0, min_exclusive=True),
        OutputFile("OUTPUT", "report (.pdf or .html)", extensions=[".pdf", ".html"]),
    ]
    outputs = [Output("CONTENTS", "runs, sections and figure counts", "dict")]

    def check(self, params):
        from pathlib import Path

        folder = Path(params["REPORTS"]).expanduser()
        if not folder.is_dir():
            raise self.fail("REPORTS", f"must be a folder of JSON run reports, got "
                            f"'{params['REPORTS']}'")
        if not any(folder.glob("*.json")):
            raise self.fail("REPORTS", f"folder '{params['REPORTS']}' holds no .json report")

    def process(self, params, feedback: Feedback):
        from toolbox.cartography.quality import write_report

        contents = write_report(params["REPORTS"], params["OUTPUT"], params["TITLE"],
                                params["ORTHO_SCALE"], params["RULE_MM"])
        if not contents["sections"]:
            feedback.push_warning("no run report with residuals or counts was found: the "
                                  "report lists the runs only")
        return {"OUTPUT": params["OUTPUT"], "CONTENTS": contents}
