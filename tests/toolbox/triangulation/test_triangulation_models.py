"""Independent-model block adjustment: the seeds' planimetric example count (004 sl. 9: 4 models,
4 control and 5 tie points: 26 unknowns, 32 equations, redundancy 6), truth recovery, a plain
scipy reference on the nonlinear (m, K) form, the spatial block with mixed control."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from toolbox.errors import InputDataError
from toolbox.photogrammetry.rotation import rotation_matrix
from toolbox.triangulation.models import ModelsRequest, adjust_models

GRID = {f"{r}{c}": np.array([1000.0 * c, 1000.0 * r, 300.0 + 40 * np.sin(r + 2 * c)])
        for r in range(3) for c in range(3)}
CORNERS = ["00", "02", "20", "22"]
# 2 x 2 models, each holding the 4 grid points of its quadrant
MODELS = {f"m{r}{c}": [f"{r + i}{c + j}" for i in (0, 1) for j in (0, 1)]
          for r in range(2) for c in range(2)}


# spatial block: 5 x 5 points, 2 x 2 models of 3 x 3 points (adjacent models share 3 points)
GRID5 = {f"{r}{c}": np.array([500.0 * c, 500.0 * r, 300.0 + 40 * np.sin(r + 2 * c)])
         for r in range(5) for c in range(5)}
MODELS5 = {f"m{r}{c}": [f"{2 * r + i}{2 * c + j}" for i in range(3) for j in range(3)]
           for r in range(2) for c in range(2)}


def _models(noise=0.0, seed=0, tilt=0.02, grid=None, models=None):
    rng = np.random.default_rng(seed)
    grid, models = grid or GRID, models or MODELS
    model_ids, point_ids, xyz = [], [], []
    for name, pts in models.items():
        lam = rng.uniform(0.5, 2.0)
        r = rotation_matrix(*rng.normal(0, [tilt, tilt, 1.0]))
        t = rng.normal(0, 500, 3)
        for p in pts:
            model_ids.append(name)
            point_ids.append(p)
            xyz.append(r.T @ (grid[p] - t) / lam + rng.normal(0, noise, 3))
    return model_ids, point_ids, np.array(xyz)


def test_planimetric_example_count_and_truth():
    m, p, xyz = _models(tilt=0.0)  # level models: the plane similarity is then exact
    control = np.array([GRID[c] for c in CORNERS])
    res = adjust_models(ModelsRequest(m, p, xyz, CORNERS, control, "planimetric"))
    assert (res.unknowns, res.equations, res.redundancy) == (26, 32, 6)
    for k, pid in enumerate(res.points):
        assert np.abs(res.ground[k] - GRID[pid][:2]).max() < 1e-6


def test_planimetric_matches_scipy_on_the_nonlinear_form_with_noise():
    # z must not leak into the plane problem: with tilted models it would; keep models level
    rng = np.random.default_rng(3)
    m, p, xyz = [], [], []
    for name, pts in MODELS.items():
        scale, kappa, t = rng.uniform(0.5, 2), rng.uniform(-3, 3), rng.normal(0, 500, 2)
        rot = np.array([[np.cos(kappa), -np.sin(kappa)], [np.sin(kappa), np.cos(kappa)]])
        for q in pts:
            m.append(name)
            p.append(q)
            xy = rot.T @ (GRID[q][:2] - t) / scale + rng.normal(0, 0.05, 2)
            xyz.append([*xy, 0.0])
    xyz = np.array(xyz)
    control = np.array([GRID[c] for c in CORNERS])
    res = adjust_models(ModelsRequest(m, p, xyz, CORNERS, control, "planimetric"))
    models = list(dict.fromkeys(m))
    ties = [q for q in dict.fromkeys(p) if q not in CORNERS]

    def fun(v):  # X = Xu + s·(cos K·x - sin K·y), Y = Yu + s·(sin K·x + cos K·y)
        out = []
        for k in range(len(m)):
            xu, yu, s, kap = v[4 * models.index(m[k]):4 * models.index(m[k]) + 4]
            x, y = xyz[k, :2]
            ground = GRID[p[k]][:2] if p[k] in CORNERS else \
                v[16 + 2 * ties.index(p[k]):18 + 2 * ties.index(p[k])]
            out += [xu + s * (np.cos(kap) * x - np.sin(kap) * y) - ground[0],
                    yu + s * (np.sin(kap) * x + np.cos(kap) * y) - ground[1]]
        return np.array(out)

    start = np.concatenate([np.column_stack([res.parameters[:, :2],
                                             np.hypot(res.parameters[:, 2], res.parameters[:, 3]),
                                             np.arctan2(res.parameters[:, 3],
                                                        res.parameters[:, 2])]).ravel() + 0.01,
                            np.concatenate([GRID[q][:2] + 5.0 for q in ties])])
    ref = least_squares(fun, start, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    for q in ties:
        k = res.points.index(q)
        assert np.abs(res.ground[k] - ref.x[16 + 2 * ties.index(q):18 + 2 * ties.index(q)]
                      ).max() < 1e-6
    assert res.sigma0_m ** 2 * 6 == pytest.approx(2 * ref.cost, rel=1e-8)


def test_spatial_block_with_mixed_control_two_xy_three_z():
    blocks = {"grid": GRID5, "models": MODELS5}
    m, p, xyz = _models(noise=0.0, seed=5, **blocks)
    ids = ["00", "44", "04", "40", "22"]  # 2 full corners, 3 height points (002 par. 1.5.2)
    control = np.array([GRID5["00"], GRID5["44"],
                        [np.nan, np.nan, GRID5["04"][2]], [np.nan, np.nan, GRID5["40"][2]],
                        [np.nan, np.nan, GRID5["22"][2]]])
    res = adjust_models(ModelsRequest(m, p, xyz, ids, control, "spatial"))
    assert res.equations == 3 * 36
    assert res.unknowns == 7 * 4 + 3 * 20 + 2 * 3
    assert res.redundancy == res.equations - res.unknowns
    for k, pid in enumerate(res.points):
        assert np.abs(res.ground[k] - GRID5[pid]).max() < 1e-5
    noisy = adjust_models(ModelsRequest(*_models(noise=0.05, seed=5, **blocks), ids, control,
                                        "spatial"))
    assert 0.02 < noisy.sigma0_m < 0.1
    for k, pid in enumerate(noisy.points):
        assert np.abs(noisy.ground[k] - GRID5[pid]).max() < 0.5


def test_datum_defect_and_unconnected_models_are_refused():
    m, p, xyz = _models()
    xy_only = [[*GRID[c][:2], np.nan] for c in ("02", "20")]
    with pytest.raises(InputDataError, match="datum defect.*3 height"):
        adjust_models(ModelsRequest(m, p, xyz, ["00", "22", "02", "20"],
                                    np.array([GRID["00"], GRID["22"], *xy_only]), "spatial"))
    # 2 x 2 models sharing 2 points per edge: no 3 common points to chain them in space
    with pytest.raises(InputDataError, match="not connected"):
        adjust_models(ModelsRequest(m, p, xyz, CORNERS + ["11"],
                                    np.array([GRID[c] for c in CORNERS + ["11"]]), "spatial"))
