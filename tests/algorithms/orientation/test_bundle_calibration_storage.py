"""What orientation:bundle writes of a self-calibration, read back: c, the principal point, k1
and k2 go into the project file (and the adjusted project is read again by the bundle itself);
k3, p1 and p2 have no place in the project's camera (radial polynomial k1, k2 or a table) and
are in REPORT only, with a warning naming them."""

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


def test_calibration_written_read_back_and_the_unstorable_terms_reported(sample, tmp_path):
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
    assert (written.distortion.k1, written.distortion.k2) == pytest.approx(
        (cam["k1"]["value"], cam["k2"]["value"]), rel=1e-12, abs=1e-30)
    for term in ("k3", "p1", "p2"):  # adjusted, reported, not storable
        assert cam[term]["mode"] == "weighted" and cam[term]["std"] is not None
    assert any("k3" in w and "p1" in w and "p2" in w and "not storable" in w for w in warnings)
    # the written project is read again by the bundle, its calibration as the fixed start
    again = toolbox.run("orientation:bundle", params | {
        "PROJECT": tmp_path / "adjusted.yaml", "SELF_CALIBRATION": "", "START": "project",
        "OUTPUT": tmp_path / "again.yaml", "REPORT": tmp_path / "again.json"})
    assert 0.7 < again["STATISTICS"]["sigma0"] < 1.3
