"""orientation:relative on the sample block's photos: model and y-parallaxes, bad input."""

import csv
import json

import numpy as np
import pytest

import toolbox
from toolbox.demo.samples.bundle_block import make
from toolbox.errors import ToolboxError


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    return make(tmp_path_factory.mktemp("relative_sample"), {})


def test_pair_of_the_sample_block(sample, tmp_path):
    out = toolbox.run("orientation:relative", {
        "PROJECT": sample["bundle_project"], "INPUT": sample["bundle_measurements"],
        "PHOTO1": "1_02", "PHOTO2": "1_03", "PARAMETERS": "independent",
        "OUTPUT": tmp_path / "model.csv", "REPORT": tmp_path / "rel.json"})
    stats = out["STATISTICS"]
    # 0.3 px noise of 12 µm pixels on both photos: y-parallax sigma ~ sqrt(2)·3.6 µm
    assert 3.0 < stats["sigma0_um"] < 8.0 and stats["redundancy"] == stats["points"] - 5
    with open(tmp_path / "model.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == stats["points"]
    assert np.sqrt(np.mean([float(r["py_um"]) ** 2 for r in rows])) < 8.0
    report = json.loads((tmp_path / "rel.json").read_text())
    assert report["base"] == [1.0, 0.0, 0.0]


def test_unknown_photo_and_too_few_points_are_one_line_errors(sample, tmp_path):
    base = {"PROJECT": sample["bundle_project"], "INPUT": sample["bundle_measurements"],
            "OUTPUT": tmp_path / "m.csv"}
    with pytest.raises(ToolboxError, match="PHOTO2.*9_99"):
        toolbox.run("orientation:relative", base | {"PHOTO1": "1_01", "PHOTO2": "9_99"})
    with pytest.raises(ToolboxError, match="at least 5"):  # 1_01 and 2_04 barely overlap
        toolbox.run("orientation:relative", base | {"PHOTO1": "1_01", "PHOTO2": "2_01"})
    assert not (tmp_path / "m.csv").exists()
