"""Round 16 (misc2): small known defects."""

from __future__ import annotations

import json

import numpy as np
import pytest

import toolbox


@pytest.mark.parametrize("sectors", [None, 1])
def test_cross_validate_reports_idw_sectors_as_documented(tmp_path, sectors):
    # SECTORS is documented "1 = none" with default 1; the report said 0
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 100, (25, 2))
    (tmp_path / "pts.csv").write_text(
        "x,y,z\n" + "".join(f"{x},{y},{0.1 * x + 0.2 * y}\n" for x, y in xy))
    params = {"INPUT": tmp_path / "pts.csv", "METHODS": "idw", "OUTPUT": tmp_path / "cv.json"}
    if sectors is not None:
        params["SECTORS"] = sectors
    toolbox.run("dem:cross_validate", params)
    report = json.loads((tmp_path / "cv.json").read_text())
    assert report["methods"]["idw"]["options"]["sectors"] == 1


ODM_XYZ_OPK = """'filename' 'x' 'y' 'z' 'omega' 'phi' 'kappa' 'camera'
'100_0005_0142' 292710.217 2731048.771 186.446 28.831 0.94 1.782 'dji fc6310r 5472 3648 brown 0.6666'
'100_0005_0018'  292746.19 2731093.469 186.56 -2.728 -30.083 -93.729 'dji fc6310r 5472 3648 brown 0.6666'
"""


@pytest.mark.parametrize("quote", ["'", '"'])
def test_gnss_reads_orthority_space_separated_quoted_csv(tmp_path, quote):
    # orientation:bundle's GNSS table sniffed only , ; tab: Orthority's ODM CSV was one column
    from toolbox.triangulation.inputs import read_centres

    path = tmp_path / "odm_xyz_opk.csv"
    path.write_text(ODM_XYZ_OPK.replace("'", quote))
    centres = read_centres(path)
    assert centres.photos == ["100_0005_0142", "100_0005_0018"]
    assert centres.xyz.tolist() == [[292710.217, 2731048.771, 186.446],
                                    [292746.19, 2731093.469, 186.56]]


def test_csv_table_comma_with_quoted_commas_unchanged(tmp_path):
    from toolbox.photogrammetry.tables import read_csv_table

    path = tmp_path / "t.csv"
    path.write_text('photo,X,Y,Z,note\np1,1.5,2.5,3.5,"a, b"\n')
    header, rows = read_csv_table(path)
    assert header == ["photo", "X", "Y", "Z", "note"]
    assert rows == [{"photo": "p1", "X": "1.5", "Y": "2.5", "Z": "3.5", "note": "a, b"}]
