"""Round fifteen, sweep of pipelines and run reports (toolbox batch, --run-report)."""

from __future__ import annotations

import json

from toolbox.batch import load_pipeline, run_pipeline


def _report(path, name):
    path.write_text(json.dumps({"algorithm": "vector:info", "display_name": name,
                                "elapsed_s": 0.1, "outputs": {}, "warnings": []}))


def test_pipeline_folder_parameter_is_relative_to_the_pipeline_file(tmp_path, monkeypatch):
    """report:quality REPORTS: reports (a Folder parameter) was read from the current
    directory, not the pipeline's folder: another project's runs reported in silence."""
    proj, elsewhere = tmp_path / "proj", tmp_path / "elsewhere"
    (proj / "reports").mkdir(parents=True)
    (elsewhere / "reports").mkdir(parents=True)
    _report(proj / "reports" / "project_run.json", "Project run")
    _report(elsewhere / "reports" / "other_run.json", "Other run")
    (proj / "pipe.yaml").write_text("steps:\n  - name: q\n    algorithm: report:quality\n"
                                    "    params: {REPORTS: reports, OUTPUT: quality.html}\n")
    monkeypatch.chdir(elsewhere)
    run_pipeline(load_pipeline(proj / "pipe.yaml"))
    html = (proj / "quality.html").read_text(encoding="utf-8")
    assert "project_run" in html
    assert "other_run" not in html


def test_run_report_records_absolute_paths_and_input_crs(tmp_path, monkeypatch):
    """--run-report recorded the paths as typed ("INPUT": "pts.gpkg"): the report named no file
    once read elsewhere, and not the CRS the inputs were read in."""
    import geopandas as gpd
    from shapely.geometry import Point

    import toolbox

    monkeypatch.chdir(tmp_path)
    gpd.GeoDataFrame({"z": [1.0, 2.0, 3.0, 4.0]},
                     geometry=[Point(0, 0), Point(10, 0), Point(0, 10), Point(10, 10)],
                     crs="EPSG:32632").to_file("pts.gpkg", layer="heights")
    toolbox.run("dem:idw", {"INPUT": "pts.gpkg|layername=heights", "Z_FIELD": "z",
                            "CELL_SIZE": 5, "OUTPUT": "dem.tif"}, report="run.json")
    doc = json.loads((tmp_path / "run.json").read_text())
    assert doc["parameters"]["INPUT"] == f"{tmp_path / 'pts.gpkg'}|layername=heights"
    assert doc["parameters"]["OUTPUT"] == str(tmp_path / "dem.tif")
    assert doc["input_crs"] == {"INPUT": "EPSG:32632"}


def test_run_report_lists_warnings_logged_outside_feedback(tmp_path):
    """A warning the console showed through the toolbox logger (a deprecated parameter name)
    was missing from the run report's warnings."""
    import warnings

    import geopandas as gpd
    from shapely.geometry import LineString, Point

    import toolbox

    pts = [Point(x, y, 10.0 + x / 10) for x in (0, 50, 100) for y in (0, 50, 100)]
    gpd.GeoDataFrame(geometry=pts, crs="EPSG:32632").to_file(tmp_path / "pts.gpkg")
    gpd.GeoDataFrame({"h": [12.0]}, geometry=[LineString([(10, 20), (90, 80)])],
                     crs="EPSG:32632").to_file(tmp_path / "bl.gpkg")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg",
                                     "BREAKLINES": tmp_path / "bl.gpkg", "BREAKLINE_Z_FIELD": "h",
                                     "OUTPUT": tmp_path / "tin.gpkg"},
                    report=tmp_path / "tin.json")
    found = json.loads((tmp_path / "tin.json").read_text())["warnings"]
    assert any("BREAKLINE_Z_FIELD is now called BREAKLINES_Z_FIELD" in w for w in found)
    assert len(found) == len(set(found))  # a pushed warning is not listed twice


def _cv_report(folder, crs, rmse):
    folder.mkdir(parents=True, exist_ok=True)
    stats = {"crs": crs, "best": "idw", "methods": {"idw": {
        "rmse": rmse, "mean_error": 0.0, "max_abs_error": 2 * rmse, "predicted": 100}}}
    (folder / "cv.json").write_text(json.dumps({
        "algorithm": "dem:cross_validate", "display_name": "Cross-validation",
        "elapsed_s": 1.0, "outputs": {"STATISTICS": stats}, "warnings": []}))


def test_quality_dem_rmse_in_feet_is_not_judged_as_metres(tmp_path):
    """dem:cross_validate takes a US-feet CRS; report:quality showed its RMSE (in feet) as
    metres and judged it against the metre tolerance."""
    from toolbox.cartography.quality import Specification, write_report

    spec = Specification(contour_interval_m=5.0)  # tolerance 1.52 m
    _cv_report(tmp_path / "compound", "EPSG:2227+6360", 4.0)  # heights in US feet: 1.219 m
    verdict = write_report(tmp_path / "compound", tmp_path / "a.html", "t", spec)["verdicts"][0]
    assert verdict["measured"] == f"{4.0 * 1200 / 3937:.3f} m"
    assert verdict["status"] == "pass"
    _cv_report(tmp_path / "plain", "EPSG:2227", 4.0)  # x, y in feet: heights' unit unknown
    verdict = write_report(tmp_path / "plain", tmp_path / "b.html", "t", spec)["verdicts"][0]
    assert verdict["status"] == "not checked"
    _cv_report(tmp_path / "metric", "EPSG:32632", 1.0)  # metres: as before
    verdict = write_report(tmp_path / "metric", tmp_path / "c.html", "t", spec)["verdicts"][0]
    assert (verdict["measured"], verdict["status"]) == ("1.000 m", "pass")


def test_pipeline_path_list_text_is_relative_to_the_pipeline_file(tmp_path, monkeypatch):
    """orientation:convert INPUT (text holding comma-separated paths) relative in a pipeline
    was looked for in the current directory: refused as 'does not exist' (exit 2), or another
    folder's file read in silence."""
    from toolbox.batch import validate_pipeline

    proj, elsewhere = tmp_path / "proj", tmp_path / "elsewhere"
    proj.mkdir()
    elsewhere.mkdir()
    (proj / "a.yaml").write_text("x")
    (proj / "b.yaml").write_text("x")
    (proj / "pipe.yaml").write_text("steps:\n  - name: c\n    algorithm: orientation:convert\n"
                                    "    params: {INPUT: 'a.yaml, b.yaml', OUTPUT: out.yaml}\n")
    monkeypatch.chdir(elsewhere)
    validate_pipeline(load_pipeline(proj / "pipe.yaml"))  # the inputs are found


def test_pipeline_deprecated_parameter_name_is_renamed(tmp_path):
    """A step using a deprecated parameter name (accepted by the loader and by toolbox run)
    failed with an internal error, KeyError (exit 3), in --validate and in the run."""
    import warnings

    (tmp_path / "pipe.yaml").write_text(
        "steps:\n  - name: t\n    algorithm: tin:delaunay\n"
        "    params: {INPUT: p.gpkg, BREAKLINES: b.gpkg, BREAKLINE_Z_FIELD: h, OUTPUT: t.gpkg}\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        pipeline = load_pipeline(tmp_path / "pipe.yaml")
    assert pipeline.steps[0].params["BREAKLINES_Z_FIELD"] == "h"
    assert "BREAKLINE_Z_FIELD" not in pipeline.steps[0].params


def test_pipeline_rerun_reports_this_run_to_its_quality_step(tmp_path):
    """Rerunning a pipeline whose report:quality step reads the report folder: with
    --report-dir and --overwrite it failed at that step (its earlier report is a file of its
    input folder, exit 2); without --report-dir the quality report showed the earlier run's
    reports in silence. Now the earlier reports of these steps go first, and a folder holding
    them that this run does not rewrite is warned about."""
    import geopandas as gpd
    from shapely.geometry import Point

    from toolbox.feedback import Feedback

    gpd.GeoDataFrame(geometry=[Point(0, 0)], crs="EPSG:32632").to_file(tmp_path / "p.gpkg")
    (tmp_path / "pipe.yaml").write_text(
        "steps:\n  - name: info\n    algorithm: vector:info\n"
        "    params: {INPUT: p.gpkg, OUTPUT: info.json}\n"
        "  - name: quality\n    algorithm: report:quality\n"
        "    params: {REPORTS: reports, OUTPUT: q.html}\n")
    reports = tmp_path / "reports"
    reports.mkdir()
    for name in ("info", "quality"):  # an earlier run's
        _report(reports / f"{name}.json", "EARLIER RUN")
    pipeline = load_pipeline(tmp_path / "pipe.yaml")
    feedback = Feedback()
    run_pipeline(pipeline, feedback, overwrite=True)  # no --report-dir: warned
    assert any("of an earlier run" in w and "info, quality" in w for w in feedback.warnings)
    run_pipeline(pipeline, Feedback(), overwrite=True, report_dir=reports)
    assert "EARLIER RUN" not in (reports / "info.json").read_text()
    assert "EARLIER RUN" not in (tmp_path / "q.html").read_text(encoding="utf-8")


def test_batch_set_of_an_unknown_variable_or_without_value_is_refused(tmp_path):
    """--set ou=second (misspelt) and --set out (no value) were ignored in silence (exit 0):
    the run wrote where the file's variable said, over the earlier outputs with --overwrite."""
    import pytest
    from click.testing import CliRunner

    from toolbox.cli import main
    from toolbox.errors import PipelineError

    (tmp_path / "pipe.yaml").write_text(
        "variables: {out: first}\nsteps:\n  - name: info\n    algorithm: vector:info\n"
        "    params: {INPUT: '${data}/p.gpkg', OUTPUT: '${out}/info.json'}\n")
    with pytest.raises(PipelineError, match="no variable 'ou'"):
        load_pipeline(tmp_path / "pipe.yaml", {"ou": "second", "data": "d"})
    pipeline = load_pipeline(tmp_path / "pipe.yaml", {"out": "second", "data": "d"})
    assert pipeline.variables["out"] == "second"  # declared, or used only: accepted
    result = CliRunner().invoke(main, ["batch", str(tmp_path / "pipe.yaml"), "--validate",
                                       "--set", "out"])
    assert result.exit_code == 2
    assert "--set 'out': expected NAME=VALUE" in result.output


def test_quality_with_no_criterion_is_not_accepted(tmp_path):
    """report:quality over runs that measure no criterion said 'Overall: ACCEPTED (0 criteria
    ...)' with accepted true; over a folder of JSON outputs that are no run reports too."""
    import pytest

    import toolbox
    from toolbox.errors import ParameterError

    (tmp_path / "reports").mkdir()
    _report(tmp_path / "reports" / "info.json", "Vector info")  # a run without criteria
    out = toolbox.run("report:quality", {"REPORTS": tmp_path / "reports",
                                         "OUTPUT": tmp_path / "q.html"})
    assert out["CONTENTS"]["accepted"] is False
    html = (tmp_path / "q.html").read_text(encoding="utf-8")
    assert "ACCEPTED" not in html.replace("NOT ACCEPTED", "")
    (tmp_path / "outputs").mkdir()
    (tmp_path / "outputs" / "info.json").write_text(json.dumps({"layers": []}))
    with pytest.raises(ParameterError, match="REPORTS.*no run report"):
        toolbox.run("report:quality", {"REPORTS": tmp_path / "outputs",
                                       "OUTPUT": tmp_path / "q2.html"})


def test_quality_skips_a_json_whose_outputs_are_not_a_mapping(tmp_path):
    """A JSON with 'algorithm' and 'outputs': null was taken for a run report: internal error
    (AttributeError, exit 3)."""
    from toolbox.cartography.quality import load_reports

    (tmp_path / "a.json").write_text('{"algorithm": "rectify:estimate", "outputs": null}')
    _report(tmp_path / "b.json", "Vector info")
    assert [name for runs in load_reports(tmp_path).values() for name, _ in runs] == ["b"]


def test_validate_accepts_a_folder_input_that_is_the_report_dir(tmp_path, monkeypatch):
    """A pipeline whose report:quality step reads the folder --report-dir writes was refused
    on its first run, before anything ran: 'REPORTS folder does not exist' (exit 2)."""
    import pytest

    from toolbox.batch import validate_pipeline
    from toolbox.errors import PipelineError

    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.gpkg").write_text("")
    (tmp_path / "pipe.yaml").write_text(
        "steps:\n  - name: quality\n    algorithm: report:quality\n"
        "    params: {REPORTS: reports, OUTPUT: q.html}\n")
    pipeline = load_pipeline(tmp_path / "pipe.yaml")
    validate_pipeline(pipeline, report_dir="reports")  # written as the steps run
    with pytest.raises(PipelineError, match="does not exist"):
        validate_pipeline(pipeline)  # no --report-dir: nothing makes it
