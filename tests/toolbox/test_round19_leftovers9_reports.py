"""report:quality's REPORTS in a pipeline: a folder an earlier step writes into was refused at
validation ('holds no .json report', or 'does not exist' before the first run), though an input
an earlier step writes is checked when its step runs; now a Folder input behaves so too. A
standalone run on an empty folder, and a pipeline in which no step writes there, are refused
as before (exit 2)."""

from __future__ import annotations

import geopandas as gpd
import pytest
import shapely

from tests.helpers_cli import cli, one_error

PIPE = """steps:
  - name: info
    algorithm: vector:info
    params: {{INPUT: p.gpkg, OUTPUT: {info}}}
  - name: quality
    algorithm: report:quality
    params: {{REPORTS: reports, OUTPUT: q.html}}
"""


@pytest.fixture
def project(tmp_path):
    gpd.GeoDataFrame({"a": [1]}, geometry=[shapely.Point(1500050, 5000050)],
                     crs=3003).to_file(tmp_path / "p.gpkg")
    return tmp_path


@pytest.mark.parametrize("made", [True, False], ids=["empty folder", "no folder yet"])
def test_a_reports_folder_an_earlier_step_writes_into_validates(project, made):
    if made:
        (project / "reports").mkdir()
    (project / "pipe.yaml").write_text(PIPE.format(info="reports/info.json"))
    code, out, err = cli("batch", project / "pipe.yaml", "--validate")
    assert code == 0 and "2 steps, valid" in out, err
    assert sorted(p.name for p in project.iterdir()) == ["p.gpkg", "pipe.yaml"] + \
        (["reports"] if made else [])
    # no step writes into it: refused at validation, as before
    (project / "pipe.yaml").write_text(PIPE.format(info="info.json"))
    code, _, err = cli("batch", project / "pipe.yaml", "--validate")
    word = "holds no .json report" if made else "does not exist"
    expected = f"step 2 of 2 (report:quality 'quality'): REPORTS folder " \
               f"'{project / 'reports'}' {word}"
    assert code == 2 and expected in one_error(err), err
    # a standalone run on a truly empty folder: exit 2, one clear line, nothing written
    (project / "empty").mkdir()
    code, _, err = cli("run", "report:quality", "--REPORTS", project / "empty", "--OUTPUT",
                       project / "q.html")
    assert code == 2 and one_error(err) == f"toolbox: error: REPORTS folder " \
                                           f"'{project / 'empty'}' holds no .json report", err
    assert not (project / "q.html").exists()
