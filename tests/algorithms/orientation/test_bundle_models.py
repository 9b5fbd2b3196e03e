"""orientation:models on the seeds' planimetric example (004 sl. 9) through the algorithm: the
count 26 unknowns, 32 equations, redundancy 6, and the truth."""

import csv

import numpy as np
import pytest

import toolbox
from toolbox.errors import ToolboxError

GRID = {f"P{r}{c}": (1000.0 * c, 1000.0 * r, 300.0) for r in range(3) for c in range(3)}
CONTROL = ["P00", "P02", "P20", "P22"]  # points 1-4 of the slide; the other 5 are tie points


def _files(tmp_path):
    rng = np.random.default_rng(2)
    rows = [["model", "point_id", "x", "y", "z"]]
    for r in range(2):
        for c in range(2):
            scale, kappa, t = rng.uniform(0.5, 2), rng.uniform(-3, 3), rng.normal(0, 500, 2)
            rot = np.array([[np.cos(kappa), np.sin(kappa)], [-np.sin(kappa), np.cos(kappa)]])
            for i in (0, 1):
                for j in (0, 1):
                    pid = f"P{r + i}{c + j}"
                    x, y = rot @ (np.array(GRID[pid][:2]) - t) / scale
                    rows.append([f"model_{r}{c}", pid, x, y, 0.0])
    with open(tmp_path / "models.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    with open(tmp_path / "control.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "X", "Y", "Z"])
        for cid in CONTROL:
            w.writerow([cid, *GRID[cid]])
    return tmp_path / "models.csv", tmp_path / "control.csv"


def test_planimetric_example_of_the_seeds(tmp_path):
    import geopandas as gpd

    models, control = _files(tmp_path)
    from test_bundle import declared_layer_problems

    params = {"INPUT": models, "CONTROL": control, "MODE": "planimetric",  # local: no CRS
              "OUTPUT": tmp_path / "block.gpkg", "REPORT": tmp_path / "block.json"}
    out = toolbox.run("orientation:models", params)
    assert not declared_layer_problems("orientation:models", "OUTPUT", out["OUTPUT"], params)
    s = out["STATISTICS"]
    assert (s["unknowns"], s["equations"], s["redundancy"]) == (26, 32, 6)
    pts = gpd.read_file(out["OUTPUT"], layer="points")
    assert set(pts["role"]) == {"control", "tie"} and len(pts) == 9
    for _, row in pts.iterrows():
        assert row.geometry.x == pytest.approx(GRID[row["point_id"]][0], abs=1e-6)
        assert row.geometry.y == pytest.approx(GRID[row["point_id"]][1], abs=1e-6)


def test_too_little_control_is_a_one_line_error(tmp_path):
    models, control = _files(tmp_path)
    rows = list(csv.reader(open(control)))[:2]
    with open(tmp_path / "one.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    with pytest.raises(ToolboxError, match="not determined|datum") as info:
        toolbox.run("orientation:models", {"INPUT": models, "CONTROL": tmp_path / "one.csv",
                                           "MODE": "planimetric",
                                           "OUTPUT": tmp_path / "x.gpkg"})
    assert "\n" not in str(info.value)
    assert not (tmp_path / "x.gpkg").exists()


def test_spatial_models_of_the_bundle_sample(tmp_path):
    import json

    from toolbox.demo.samples.bundle_block import make

    sample = make(tmp_path / "data", {})
    out = toolbox.run("orientation:models", {"INPUT": sample["bundle_models"],
                                             "CONTROL": sample["bundle_control"],
                                             "CRS": "EPSG:3003", "OUTPUT": tmp_path / "m.gpkg",
                                             "REPORT": tmp_path / "m.json"})
    s = out["STATISTICS"]
    assert s["models"] == 6 and s["redundancy"] == s["equations"] - s["unknowns"] > 0
    assert 0.01 < s["sigma0_m"] < 0.04  # 2 cm of noise on the model coordinates
    assert len(s["check_residuals_m"]) == 2
    for d in s["check_residuals_m"].values():
        assert np.abs(d).max() < 0.15
    assert json.loads((tmp_path / "m.json").read_text())["model_parameters"][0]["scale"] > 100
