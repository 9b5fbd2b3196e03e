"""`toolbox demo` runs the whole demo pipeline end to end on the bundled sample data."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import rasterio

from toolbox.demo import demo_pipeline_doc

sys.path.insert(0, str(Path(__file__).parent))
from gpkg_check import gpkg_problems  # noqa: E402

DEBIAN_VALIDATOR = Path("/usr/lib/python3/dist-packages/osgeo_utils/samples/validate_gpkg.py")


def test_demo_runs_end_to_end(demo_run):
    tmp_path, summary = demo_run
    assert f"outputs in {tmp_path}" in summary
    # the Siena bundle's orientations against Z-Map's, within the block log's stated residuals
    # (tests/algorithms/orientation/test_tiepoints_siena.py checks the figures independently)
    line = next(ln for ln in summary.splitlines() if "siena_bundle: against the reference" in ln)
    assert line.endswith("agrees within the tolerance"), line
    bundle = json.loads((tmp_path / "orientation" / "siena_bundle.json").read_text())
    assert bundle["reference"]["summary"]["agrees"] is True
    assert bundle["reference"]["summary"]["tolerance"] == [0.153, 0.16, 0.346, 65.4]
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
    # every GeoPackage the demo writes is a valid GeoPackage 1.2 (tests/toolbox/gpkg_check.py)
    gpkgs = sorted(tmp_path.rglob("*.gpkg"))
    assert len(gpkgs) >= 5
    assert {str(p.relative_to(tmp_path)): gpkg_problems(p) for p in gpkgs} == \
        {str(p.relative_to(tmp_path)): [] for p in gpkgs}
    if DEBIAN_VALIDATOR.exists():  # and GDAL's own validator, where Debian's GDAL is installed
        script = ("import sys\nfrom osgeo_utils.samples.validate_gpkg import check\n"
                  "for f in sys.argv[1:]:\n    check(f, warning_msg=False)\n")
        result = subprocess.run(["/usr/bin/python3", "-c", script, *map(str, gpkgs)],
                                capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, result.stderr[-2000:]


def test_the_demo_reruns_into_its_own_folder(demo_run, tmp_path):
    """`make demo` twice: the second run replaces the first one's outputs and reports (the
    quality report reads the reports folder, which holds its own report of the first run)."""
    import shutil

    from toolbox.demo import run_demo

    first, _ = demo_run
    again = tmp_path / "demo_out"
    shutil.copytree(first, again)
    before = (again / "reports" / "report_quality.json").stat().st_mtime_ns
    summary = run_demo(again)
    assert f"outputs in {again}" in summary
    steps = {s["name"] for s in demo_pipeline_doc()["steps"]}
    assert {p.stem for p in (again / "reports").glob("*.json")} == steps
    assert (again / "reports" / "report_quality.json").stat().st_mtime_ns > before
    assert (again / "carto" / "quality.pdf").exists()
