"""Adjusted orientations against a reference (toolbox/triangulation/reference.py).

Truth (analytic): moving every projection centre of a block by the same vector t, attitudes
unchanged, moves the whole bundle of rays rigidly, so every point intersected from its reference
image positions moves by exactly t; on a vertical photo (omega = phi = kappa = 0, no distortion,
principal point at the origin) the image of a point at depth D = Z0 - Z moves by -c·t_xy/D.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from toolbox.errors import ParameterError
from toolbox.photogrammetry.project import load_project
from toolbox.triangulation.reference import compare, parse_tolerance

SIENA = Path(__file__).resolve().parents[3] / "toolbox" / "demo" / "data" / "siena"
GROUND = {"a": (1688300.0, 4799650.0, 320.0), "b": (1688420.0, 4799700.0, 300.0),
          "c": (1688250.0, 4799580.0, 340.0)}


def _strip_one():
    """Photos 1_7150-1_7152 (camera 'wild 303.55': no distortion), made vertical."""
    project = load_project(SIENA / "siena_project.yaml")
    return {p: replace(ph, exterior=replace(ph.exterior, omega=0.0, phi=0.0, kappa=0.0))
            for p, ph in project.photos.items() if p.startswith("1_")}


def test_a_common_centre_shift_moves_the_ground_by_it_and_the_images_by_c_t_over_depth():
    reference = _strip_one()
    t = np.array([0.07, -0.05, 0.12])
    adjusted = {p: replace(ph, exterior=replace(ph.exterior, x0=ph.exterior.x0 + t[0],
                                                y0=ph.exterior.y0 + t[1],
                                                z0=ph.exterior.z0 + t[2]))
                for p, ph in reference.items()}
    out = compare(adjusted, reference, GROUND, tolerance=(0.1, 0.1, 0.1, 100.0))
    assert out["summary"]["points"] == 3 and out["summary"]["photos"] == 3
    for row in out["points"]:
        np.testing.assert_allclose([row["dX"], row["dY"], row["dZ"]], t, atol=1e-6)
    # X over its tolerance (0.07 < 0.1 but Z 0.12 > 0.1): differs
    assert out["summary"]["agrees"] is False and "DIFFERS" in out["summary"]["line"]
    worst = 0.0
    for pid, ph in reference.items():
        e = ph.exterior
        c = ph.camera.c
        for xyz in GROUND.values():
            depth_new = e.z0 + t[2] - xyz[2]
            depth = e.z0 - xyz[2]
            # x = c·(X - X0)/(Z0 - Z): exact image motion in µm
            dx = 1e3 * c * ((xyz[0] - e.x0 - t[0]) / depth_new - (xyz[0] - e.x0) / depth)
            dy = 1e3 * c * ((xyz[1] - e.y0 - t[1]) / depth_new - (xyz[1] - e.y0) / depth)
            got = 1e3 * (adjusted[pid].ground_to_image(np.array([xyz]))
                         - ph.ground_to_image(np.array([xyz])))[0]
            np.testing.assert_allclose(got, [dx, dy], atol=1e-6)
            worst = max(worst, abs(dx), abs(dy))
    row = out["photos"][0]
    np.testing.assert_allclose([row["dX0"], row["dY0"], row["dZ0"]], t, atol=1e-9)
    assert out["summary"]["max_image_um"] <= worst + 1e-6


def test_identical_orientations_agree_and_the_tolerance_is_parsed():
    reference = _strip_one()
    std = {p: [0.1, 0.1, 0.05] for p in reference}
    out = compare(reference, reference, GROUND, std, parse_tolerance("0.01; 0.01; 0.01; 1"))
    assert out["summary"]["agrees"] is True
    assert out["summary"]["max_centre_m"] == 0.0
    assert "agrees within the tolerance" in out["summary"]["line"]
    assert compare(reference, reference, GROUND)["summary"]["agrees"] is None


@pytest.mark.parametrize("text", ["0.1, 0.1, 0.1", "0.1, 0.1, -0.1, 5", "a, b, c, d",
                                  "0.1, 0.1, 0.1, nan"])
def test_a_bad_tolerance_names_the_parameter(text):
    with pytest.raises(ParameterError, match="REFERENCE_TOLERANCE must be four positive"):
        parse_tolerance(text)
