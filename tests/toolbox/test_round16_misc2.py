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
