"""The project quality report: a verdict per product against the specification's tolerances,
then one section per kind of run, drawn only from the JSON run reports the algorithms write (and
the residual files those reports name); nothing is recomputed.

The tolerances (:class:`Specification`), with their sources:

- planimetric: the orthophoto rule RMS <= 0.3 mm (small scales) or 0.5 mm (large scales) x the
  scale denominator (S002 §2.6.6), used for the orthophoto, rectification and orientation check
  points;
- heights: the contour interval of the map scale (S002 l.3278: 5 m at 1:5000) read as the
  National Map Accuracy Standard's vertical rule, 90 % of the tested points within half the
  interval, i.e. RMSE <= interval / (2 x 1.6449) (1.52 m for 5 m);
- interior orientation: the largest fiducial residual <= a producer's threshold (default 15 µm,
  about one scan pixel; no seed states one: set it to the tender's).

Sections appear for the runs found: interior orientation, orientation (resection, absolute
orientation, orientation check), rectification, orthophotos, DEM cross-validation, mosaic and
seamlines, topology, then every warning of every run and the list of runs.
"""

from __future__ import annotations

from pathlib import Path

from toolbox.cartography.quality_model import (  # noqa: F401 - the report's API
    FAIL,
    NMAS_90,
    NOT_CHECKED,
    PASS,
    Section,
    Specification,
    Verdict,
    _plt,
    load_reports,
    without_paths,
)
from toolbox.cartography.quality_sections import (
    dem_section,
    interior_section,
    mosaic_section,
    orientation_section,
    ortho_section,
    rectification_section,
    runs_section,
    topology_section,
    warnings_section,
)
from toolbox.errors import InputDataError

#: the run reports each multi-step section reads (to name them when one is incomplete)
ORIENTATION_IDS = ("orientation:resection", "orientation:absolute", "orientation:bundle",
                   "orientation:check")
ORTHO_IDS = ("ortho:photo", "ortho:batch", "report:ortho_check")
MOSAIC_IDS = ("mosaic:seamlines", "mosaic:build")


def build_sections(reports, spec: Specification) -> tuple[list[Verdict], list[Section]]:
    """The verdicts and the sections for the runs found (a section only where it has content).
    A run report without what its section reads (an older toolbox's, or edited by hand) is an
    :class:`InputDataError` naming the reports and the missing entry."""
    verdicts: list[Verdict] = []
    sections: list[Section | None] = []

    def add(ids: tuple[str, ...], build, *args) -> None:
        try:
            sections.append(build(*args))
        except KeyError as exc:  # an entry the section reads is missing (not a type error)
            names = [name for i in ids for name, _ in reports.get(i, [])]
            what = f"no {exc.args[0]!r}" if exc.args else "an entry missing"
            raise InputDataError(
                f"REPORTS: the {'/'.join(i for i in ids if reports.get(i))} run report(s) "
                f"{', '.join(names[:5])} are incomplete ({what}): an older toolbox's or edited "
                "report? Run the step again or move its report out of REPORTS") from None

    if reports.get("orientation:interior"):
        add(("orientation:interior",), interior_section, reports["orientation:interior"], spec,
            verdicts)
    add(ORIENTATION_IDS, orientation_section, reports, spec, verdicts)
    if reports.get("rectify:estimate"):
        add(("rectify:estimate",), rectification_section, reports["rectify:estimate"], spec,
            verdicts)
    add(ORTHO_IDS, ortho_section, reports, spec, verdicts)
    if reports.get("dem:cross_validate"):
        add(("dem:cross_validate",), dem_section, reports["dem:cross_validate"], spec, verdicts)
    add(MOSAIC_IDS, mosaic_section, reports, verdicts)
    if reports.get("topology:check"):
        add(("topology:check",), topology_section, reports["topology:check"], verdicts)
    kept = [s for s in sections if s is not None and any(b[0] != "text" for b in s.blocks)]
    return verdicts, kept


def overall_verdict(verdicts: list[Verdict]) -> tuple[str, bool]:
    """The overall verdict and whether the delivery is accepted: NOT ACCEPTED when a criterion
    failed, NOT CHECKED when none was measured, else ACCEPTED saying how many of the criteria
    were checked and naming those that were not (an "ACCEPTED" over 1 of 4 criteria read as a
    full acceptance)."""
    failed = [v for v in verdicts if v.status == FAIL]
    unchecked = [v for v in verdicts if v.status == NOT_CHECKED]
    checked = len(verdicts) - len(unchecked)
    names = "; ".join(f"{v.product}: {v.criterion}" for v in unchecked)
    if failed:
        text = f"NOT ACCEPTED: {len(failed)} of {len(verdicts)} criteria failed"
        return text + (f" (not checked: {names})" if unchecked else ""), False
    if not checked:
        return "NOT CHECKED: no run measured a criterion of the specification" + (
            f" (not checked: {names})" if unchecked else ""), False
    if unchecked:
        return (f"ACCEPTED ({checked} of {len(verdicts)} criteria checked; not checked: "
                f"{names})"), True
    return f"ACCEPTED ({checked} of {len(verdicts)} criteria checked)", True


def verdict_section(verdicts: list[Verdict], spec: Specification, runs: int) -> Section:
    overall, _ = overall_verdict(verdicts)
    sec = Section("verdict", "Verdict")
    sec.text(f"Overall: {overall}; {len(verdicts)} criteria from {runs} runs.")
    sec.text("Specification: " + spec.describe() + ".")
    sec.table(["Product", "Criterion", "Measured", "Tolerance", "Verdict", "Source"],
              [[v.product, v.criterion, v.measured, v.tolerance, v.status, v.source]
               for v in verdicts])
    return sec


def write_report(folder: str | Path, output: str | Path, title: str,
                 spec: Specification | None = None) -> dict:
    """Build the report from the run reports in ``folder``; PDF or HTML by ``output``'s
    extension. Returns what it contains."""
    from toolbox.cartography.quality_pages import write_html, write_pdf

    spec = spec or Specification()
    plt = _plt()
    reports = load_reports(folder)
    verdicts, sections = build_sections(reports, spec)
    runs = sum(len(r) for r in reports.values())
    everything = [verdict_section(verdicts, spec, runs), *sections, warnings_section(reports),
                  runs_section(reports)]
    try:
        if str(output).lower().endswith(".html"):
            write_html(output, title, everything)
        else:
            write_pdf(output, title, everything)
    finally:
        for s in everything:
            for f in s.figures:
                plt.close(f)
    overall, accepted = overall_verdict(verdicts)
    return {"runs": runs, "sections": [s.key for s in sections],
            "figures": {s.key: len(s.figures) for s in sections},
            "verdicts": [v.__dict__ for v in verdicts], "overall": overall,
            "criteria_checked": sum(v.status != NOT_CHECKED for v in verdicts),
            "accepted": accepted}
