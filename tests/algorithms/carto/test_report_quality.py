"""report:quality from real run reports (interior orientation, rectification, DEM
cross-validation, topology check on the sample data): the PDF and the HTML exist, hold one
figure per section plot, and quote the run reports' numbers."""

from __future__ import annotations

import json
import re

import pytest

import toolbox
from toolbox.demo.samples import make_samples

pypdf = pytest.importorskip("pypdf", reason="pypdf (dev extra) reads the report PDF back")


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    root = tmp_path_factory.mktemp("quality")
    s = make_samples(root / "data")
    rep = root / "reports"
    rep.mkdir()
    runs = {
        "interior": ("orientation:interior", {
            "INPUT": s["siena_fiducials"], "SOURCE": "log_block", "TRANSFORMATION": "from_input",
            "OUTPUT": root / "interior.json", "RESIDUALS": root / "interior.csv"}),
        "rectify_estimate": ("rectify:estimate", {
            "INPUT": s["photo_gcps"], "CRS": "EPSG:3003", "MODEL": "homography",
            "ROBUST": "snooping", "OUTPUT": root / "t.json",
            "RESIDUALS": root / "res.gpkg"}),
        "dem_cross_validate": ("dem:cross_validate", {
            "INPUT": s["mass_points"], "METHODS": "idw,tin_linear",
            "OUTPUT": root / "cv.json", "RESIDUALS": root / "cv.gpkg"}),
        "topology_check": ("topology:check", {
            "INPUT": s["linework"], "LABELS": s["linework_labels"],
            "PARAMETERS": s["linework_parameters"], "OUTPUT": root / "topo.gpkg"}),
    }
    for name, (alg, params) in runs.items():
        toolbox.run(alg, params, report=rep / f"{name}.json")
    return rep


def test_pdf_report_has_every_section_and_figure(reports, tmp_path):
    out = tmp_path / "quality.pdf"
    res = toolbox.run("report:quality", {"REPORTS": str(reports), "OUTPUT": out,
                                         "TITLE": "Siena quality"})
    contents = res["CONTENTS"]
    assert contents["sections"] == ["interior", "rectification", "dem", "topology"]
    assert contents["figures"] == {"interior": 1, "rectification": 1, "dem": 2, "topology": 1}
    reader = pypdf.PdfReader(out)
    # one table page for the runs and per section, plus the figures
    assert len(reader.pages) == 1 + 4 + 5
    # the table pages: runs, then each section's table before its figures
    text = "\n".join(reader.pages[i].extract_text() for i in (0, 1, 3, 5, 8))
    assert "Siena quality" in text
    check = json.loads((reports / "rectify_estimate.json").read_text())
    rmse = check["outputs"]["STATISTICS"]["check"]["rmse"]
    assert f"{rmse:.3f} m" in text and "S002 §2.6.6" in text
    cv = json.loads((reports / "dem_cross_validate.json").read_text())
    for method, m in cv["outputs"]["STATISTICS"]["methods"].items():
        assert f"RMSE {m['rmse']:.3f} m" in text, method


def test_html_report_embeds_the_figures(reports, tmp_path):
    out = tmp_path / "quality.html"
    toolbox.run("report:quality", {"REPORTS": str(reports), "OUTPUT": out})
    html = out.read_text()
    figures = re.findall(r"<figure class='(\w+)'><img src='data:image/png;base64,", html)
    assert figures == ["interior", "rectification", "dem", "dem", "topology"]
    topo = json.loads((reports / "topology_check.json").read_text())
    errors = topo["outputs"]["STATISTICS"]["output"]["errors"]
    assert re.search(rf"errors left</th><td>{errors}</td>", html)


def test_report_needs_a_folder_of_reports(tmp_path):
    from toolbox.errors import ParameterError

    with pytest.raises(ParameterError, match="REPORTS"):
        toolbox.run("report:quality", {"REPORTS": str(tmp_path), "OUTPUT": tmp_path / "q.pdf"})
