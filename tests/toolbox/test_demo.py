"""`toolbox demo` runs the whole demo pipeline end to end on the bundled sample data."""

from __future__ import annotations

import json

import rasterio

from toolbox.demo import demo_pipeline_doc


def test_demo_runs_end_to_end(demo_run):
    tmp_path, summary = demo_run
    assert f"outputs in {tmp_path}" in summary
    steps = [s["name"] for s in demo_pipeline_doc()["steps"]]
    reports = {p.stem for p in (tmp_path / "reports").glob("*.json")}
    assert reports == set(steps)  # every step ran and reported
    for name in steps:
        report = json.loads((tmp_path / "reports" / f"{name}.json").read_text())
        for value in report["outputs"].values():
            if isinstance(value, str) and value.startswith(str(tmp_path)):
                assert (tmp_path / value).exists(), (name, value)
    with rasterio.open(tmp_path / "hillshade.tif") as ds:
        assert ds.crs.to_epsg() == 3003 and ds.read(1).max() > 200
