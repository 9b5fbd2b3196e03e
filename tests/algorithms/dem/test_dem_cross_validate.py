"""Leave-one-out cross-validation (dem:cross_validate, QUALITY): exact against brute force."""

from __future__ import annotations

import json

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely
from scipy.spatial import cKDTree

import toolbox
from toolbox.errors import ParameterError
from toolbox.terrain.gridding.methods import METHODS
from toolbox.terrain.gridding.request import MethodOptions
from toolbox.terrain.gridding.tin_constrained import tin_loo
from toolbox.terrain.gridding.validation import error_summary, loo_predict
from toolbox.terrain.tin.kernels import interpolate_tin, triangulate

X0, Y0 = 1_688_000.0, 4_799_500.0


def test_tin_loo_is_the_tin_of_the_other_points():
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 100, (80, 2))
    xyz = np.column_stack([xy, np.sin(xy[:, 0] / 15) * 10 + xy[:, 1] * 0.1])
    got = tin_loo(xyz, None)
    for i in range(len(xyz)):
        others = np.delete(np.arange(len(xyz)), i)
        tri = triangulate(xyz[others, :2])
        want = interpolate_tin(xyz[others], tri, xyz[i:i + 1, 0], xyz[i:i + 1, 1])[0]
        if np.isnan(want):
            assert np.isnan(got[i])  # a hull vertex: outside the others' TIN
        else:
            assert got[i] == pytest.approx(want, abs=1e-9)
    assert np.isfinite(got).sum() > 60


def test_tin_loo_keeps_breakline_vertices():
    rng = np.random.default_rng(4)
    xy = np.vstack([rng.uniform(0, 100, (60, 2)), [[10, 50], [50, 50], [90, 50]]])
    xyz = np.column_stack([xy, xy[:, 0] * 0.3])
    seg = np.array([[60, 61], [61, 62]])
    got = tin_loo(xyz, seg)
    assert np.isnan(got[60:]).all()  # constraints are never left out
    ok = np.isfinite(got)
    assert np.abs(got[ok] - xyz[ok, 2]).max() < 1e-9  # a plane: every prediction exact


def test_knn_loo_matches_brute_force():
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 200, (500, 2))
    z = 300 + 5 * np.sin(xy[:, 0] / 30) + rng.normal(0, 0.2, 500)
    xyz = np.column_stack([xy, z])
    options = METHODS["idw"].options(MethodOptions(neighbours=8, power=1.0))
    predicted, details = loo_predict(METHODS["idw"], xyz, options, extrapolate=True)
    dd, ii = cKDTree(xy).query(xy, 9)
    want = np.sum(z[ii[:, 1:]] / dd[:, 1:], axis=1) / np.sum(1 / dd[:, 1:], axis=1)
    np.testing.assert_allclose(predicted, want, rtol=1e-12)
    predicted, details = loo_predict(METHODS["nearest"], xyz, METHODS["nearest"].options(MethodOptions()),
                                     extrapolate=False)
    assert details["hull_vertices_not_predicted"] == np.isnan(predicted).sum() > 0
    ok = np.isfinite(predicted)
    assert np.array_equal(predicted[ok], z[ii[ok, 1]])
    summary = error_summary(predicted, z)
    err = predicted[ok] - z[ok]
    assert summary["rmse"] == pytest.approx(np.sqrt(np.mean(err ** 2)))
    assert summary["max_abs_error"] == pytest.approx(np.abs(err).max())
    assert summary["mean_error"] == pytest.approx(err.mean())


def test_cross_validate_ranks_methods_and_writes_residuals(tmp_path):
    rng = np.random.default_rng(6)
    xy = np.column_stack([X0 + rng.uniform(0, 300, 1200), Y0 + rng.uniform(0, 300, 1200)])
    u, v = (xy[:, 0] - X0) / 300, (xy[:, 1] - Y0) / 300
    z = 300 + 20 * u * u - 10 * u * v + 5 * v  # a quadratic: quadratic/cubic are exact
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z),
                     crs="EPSG:3003").to_file(tmp_path / "pts.gpkg")
    out = toolbox.run("dem:cross_validate", {"INPUT": tmp_path / "pts.gpkg",
                                             "OUTPUT": tmp_path / "cv.json",
                                             "RESIDUALS": tmp_path / "res.gpkg"})
    report = json.loads((tmp_path / "cv.json").read_text())
    methods = report["methods"]
    assert list(methods) == ["nearest", "idw", "plane", "quadratic", "cubic", "tin_linear"]
    assert methods["quadratic"]["rmse"] < 1e-9 and methods["cubic"]["rmse"] < 1e-9
    assert methods["nearest"]["rmse"] > methods["idw"]["rmse"] > methods["tin_linear"]["rmse"] > 0
    assert set(report["ranking_by_rmse"][:2]) == {"quadratic", "cubic"}
    assert report["best"] in ("quadratic", "cubic")
    assert methods["idw"]["worst_point"]["x"] > X0
    assert out["STATISTICS"]["points"] == 1200
    residuals = gpd.read_file(tmp_path / "res.gpkg", layer="residuals")
    assert len(residuals) == 1200 and residuals.crs.to_epsg() == 3003
    ok = residuals["idw_z"].notna()
    np.testing.assert_allclose(residuals.loc[ok, "idw_err"],
                               residuals.loc[ok, "idw_z"] - residuals.loc[ok, "z"])
    assert pyogrio.read_info(tmp_path / "res.gpkg", layer="residuals")["geometry_type"] == "Point Z"


def test_cross_validate_rejects_bad_method_lists(tmp_path):
    xy = np.array([[X0, Y0], [X0 + 1, Y0], [X0, Y0 + 1], [X0 + 1, Y0 + 1]])
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], np.arange(4.0)),
                     crs="EPSG:3003").to_file(tmp_path / "p.gpkg")
    with pytest.raises(ParameterError, match="METHODS must list methods among"):
        toolbox.run("dem:cross_validate", {"INPUT": tmp_path / "p.gpkg", "METHODS": "idw,kriging",
                                           "OUTPUT": tmp_path / "cv.json"})
    with pytest.raises(ParameterError, match="NEIGHBOURS must be >= 10 for cubic, got 8"):
        toolbox.run("dem:cross_validate", {"INPUT": tmp_path / "p.gpkg", "METHODS": "idw, cubic",
                                           "NEIGHBOURS": 8, "OUTPUT": tmp_path / "cv.json"})
