"""Batch pipelines: chained outputs, relative paths, static validation, failing step named."""

from __future__ import annotations

import json

import pytest
import rasterio
from conftest import run_cli

from toolbox.batch import load_pipeline, run_pipeline
from toolbox.errors import PipelineError


def write(path, text):
    path.write_text(text)
    return path


def test_chained_steps_via_cli(plane_dem, tmp_path):
    pipe = write(tmp_path / "pipe.yaml", f"""
variables:
  dem: {plane_dem[0]}
steps:
  - name: shade
    algorithm: dem:hillshade
    params:
      INPUT: ${{dem}}
      OUTPUT: out/shade.tif
  - name: reshade
    algorithm: dem:hillshade
    params:
      INPUT: ${{shade.OUTPUT}}
      AZIMUTH: 90
      OUTPUT: out/shade_of_shade.tif
""")
    proc = run_cli("batch", pipe, "--report-dir", tmp_path / "reports")
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout)
    assert results["reshade"]["OUTPUT"] == str(tmp_path / "out" / "shade_of_shade.tif")
    with rasterio.open(results["reshade"]["OUTPUT"]) as ds:
        assert ds.width == 60
    report = json.loads((tmp_path / "reports" / "reshade.json").read_text())
    assert report["parameters"]["INPUT"] == str(tmp_path / "out" / "shade.tif")


def test_validate_catches_bad_references(tmp_path):
    cases = {
        "steps: []": "non-empty 'steps'",
        "steps:\n  - algorithm: raster:nope": "no algorithm",
        "steps:\n  - algorithm: dem:hillshade\n    params: {INPUTT: a}": "INPUTT is not a parameter",
        "steps:\n  - algorithm: dem:hillshade\n    params: {INPUT: '${a.OUTPUT}'}":
            "does not come earlier",
        "steps:\n  - algorithm: dem:hillshade\n    params: {INPUT: '${x}'}": "no such variable",
        ("steps:\n  - name: a\n    algorithm: dem:hillshade\n"
         "  - algorithm: dem:hillshade\n    params: {INPUT: '${a.RESULT}'}"): "outputs are: OUTPUT",
    }
    for text, fragment in cases.items():
        with pytest.raises(PipelineError, match=fragment.replace("$", r"\$")):
            load_pipeline(write(tmp_path / "p.yaml", text))
    proc = run_cli("batch", write(tmp_path / "p.yaml", next(iter(cases))), "--validate")
    assert proc.returncode == 2 and "non-empty" in proc.stderr


def test_failing_step_is_named(plane_dem, tmp_path):
    pipe = write(tmp_path / "p.yaml", f"""
steps:
  - name: ok
    algorithm: dem:hillshade
    params: {{INPUT: {plane_dem[0]}, OUTPUT: a.tif}}
  - name: broken
    algorithm: dem:hillshade
    params: {{INPUT: {plane_dem[0]}, Z_FACTOR: 0, OUTPUT: b.tif}}
""")
    with pytest.raises(PipelineError, match="step 2 of 2 \\(dem:hillshade 'broken'\\): Z_FACTOR"):
        run_pipeline(load_pipeline(pipe))
    assert (tmp_path / "a.tif").exists() and not (tmp_path / "b.tif").exists()
