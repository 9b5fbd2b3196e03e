"""What orientation:bundle writes of a self-calibration, read back: c, the principal point and
the whole distortion polynomial (k1, k2, k3, p1, p2) go into the project file, equal to REPORT's
values, without a warning; the adjusted project is read again by the bundle itself."""

import json

import pytest

import toolbox
from toolbox.demo.samples.bundle_block import make
from toolbox.photogrammetry.project import load_project

CALIBRATION = ("c:weighted:0.01, x0:weighted:0.01, y0:weighted:0.01, k1:weighted:1e-6, "
               "k2:weighted:1e-9, k3:weighted:1e-12, p1:weighted:1e-6, p2:weighted:1e-6")


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    return make(tmp_path_factory.mktemp("bundle_sample"), {})


def test_the_whole_calibration_is_written_and_read_back(sample, tmp_path):
    from toolbox.feedback import Feedback

    warnings = []

    class Collect(Feedback):
        def push_warning(self, message, *args, **kwargs):
            warnings.append(message)

    params = {"PROJECT": sample["bundle_project"], "INPUT": sample["bundle_measurements"],
              "CONTROL": sample["bundle_control"], "SIGMA_PX": 0.3,
              "SELF_CALIBRATION": CALIBRATION, "OUTPUT": tmp_path / "adjusted.yaml",
              "REPORT": tmp_path / "bundle.json"}
    toolbox.run("orientation:bundle", params, feedback=Collect())
    report = json.loads((tmp_path / "bundle.json").read_text())
    (cam,) = report["cameras"]
    written = load_project(tmp_path / "adjusted.yaml").cameras[cam["camera"]]
    assert written.principal_distance_mm == pytest.approx(cam["c"]["value"], abs=1e-12)
    assert written.principal_point_mm == pytest.approx((cam["x0"]["value"], cam["y0"]["value"]),
                                                       abs=1e-12)
    terms = ("k1", "k2", "k3", "p1", "p2")
    assert [getattr(written.distortion, t) for t in terms] == pytest.approx(
        [cam[t]["value"] for t in terms], rel=1e-12, abs=1e-30)
    for term in terms:  # adjusted, reported and stored
        assert cam[term]["mode"] == "weighted" and cam[term]["std"] is not None
        assert cam[term]["value"] != 0.0
    assert not any("storable" in w or "k3" in w for w in warnings), warnings
    # the written project is read again by the bundle, its calibration as the fixed start
    again = toolbox.run("orientation:bundle", params | {
        "PROJECT": tmp_path / "adjusted.yaml", "SELF_CALIBRATION": "", "START": "project",
        "OUTPUT": tmp_path / "again.yaml", "REPORT": tmp_path / "again.json"})
    assert 0.7 < again["STATISTICS"]["sigma0"] < 1.3
