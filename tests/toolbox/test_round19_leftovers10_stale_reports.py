"""A pipeline step whose own JSON output lies in report:quality's REPORTS folder, named after a
step (``info`` writing ``reports/info.json``), was warned about as "run reports ... of an earlier
run" although this run had just written it. The warning now counts only the files no earlier
step of this run wrote: a real earlier run's report of a step is still named."""

from __future__ import annotations

import json

import geopandas as gpd
from shapely.geometry import Point

from toolbox.batch import load_pipeline, run_pipeline, validate_pipeline
from toolbox.feedback import Feedback


def test_a_steps_own_json_output_in_the_reports_folder_is_not_an_earlier_runs(tmp_path):
    gpd.GeoDataFrame(geometry=[Point(0, 0)], crs="EPSG:32632").to_file(tmp_path / "p.gpkg")
    (tmp_path / "pipe.yaml").write_text(
        "steps:\n  - name: info\n    algorithm: vector:info\n"
        "    params: {INPUT: p.gpkg, OUTPUT: reports/info.json}\n"
        "  - name: other\n    algorithm: vector:info\n"
        "    params: {INPUT: p.gpkg, OUTPUT: other.json}\n"
        "  - name: quality\n    algorithm: report:quality\n"
        "    params: {REPORTS: reports, OUTPUT: q.html}\n")
    reports = tmp_path / "reports"
    reports.mkdir()
    for name in ("survey", "other"):  # run reports of earlier runs; "other" named after a step
        (reports / f"{name}.json").write_text(json.dumps(
            {"algorithm": "vector:info", "display_name": "EARLIER RUN", "elapsed_s": 0.1,
             "outputs": {}, "warnings": []}))
    pipeline = load_pipeline(tmp_path / "pipe.yaml")
    validate_pipeline(pipeline, overwrite=True)
    feedback = Feedback()
    run_pipeline(pipeline, feedback, overwrite=True)
    assert "EARLIER RUN" not in (reports / "info.json").read_text()  # this run's output
    stale = [w for w in feedback.warnings if "of an earlier run" in w]
    assert len(stale) == 1 and "steps of this pipeline (other) that" in stale[0], stale
