"""rectify:estimate and its kernels: known homographies recovered, check points, gross errors named,
special cases, degenerate inputs refused, the relief rule (thesis Table 4)."""

import json

import numpy as np
import pytest
import rectify_scene as scene

import toolbox
from toolbox.errors import InputDataError, ParameterError
from toolbox.transforms.control_points import ControlPoints, parse_roles
from toolbox.transforms.plane import AffineTransform, HomographyTransform
from toolbox.transforms.rectification import fit_rectification, load_transform
from toolbox.transforms.relief import max_height_departure, relief_check, relief_displacement
from toolbox.transforms.robust import data_snooping, ransac

TRUE = scene.ground_to_pixel()


def points(ids, image, ground, roles, z=None, units="pixels"):
    return ControlPoints(list(ids), np.asarray(image, float), np.asarray(ground, float),
                         None if z is None else np.asarray(z, float),
                         np.array(roles, dtype=object), units)


def grid_error(fit, n=9):
    """Largest ground distance between the fitted and the true transform over the photo."""
    cc, rr = np.meshgrid(np.linspace(0, scene.WIDTH, n), np.linspace(0, scene.HEIGHT, n))
    img = np.column_stack([cc.ravel(), rr.ravel()])
    truth = scene.apply(np.linalg.inv(TRUE), img)
    return float(np.max(np.hypot(*(fit.transform(img) - truth).T)))


def test_noise_free_homography_is_recovered_exactly():
    fit = fit_rectification(points(*scene.gcp_table(12)), "homography")
    assert grid_error(fit) < 1e-6
    assert fit.fit.sigma0 < 1e-6 and fit.fit.redundancy == 2 * 12 - 8
    # residuals in image units agree with ground ones through the local scale (~0.5 m/px)
    assert np.abs(fit.residual_image).max() < 1e-6


def test_noise_checks_and_gross_error_named():
    """20 points, 0.2 px noise, 4 check points, one 10 px blunder on G05."""
    ids, image, ground, roles = scene.gcp_table(20, noise=0.2, gross={"G05": (8.0, -6.0)},
                                                checks=("G02", "G09", "G14", "G18"))
    pts = points(ids, image, ground, roles)
    fit = fit_rectification(pts, "homography", robust="snooping")
    assert [pts.ids[r.index] for r in fit.rejected] == ["G05"]
    assert fit.rejected[0].statistic > fit.rejected[0].critical
    summary = fit.summary()
    assert summary["rejected_points"] == ["G05"] and summary["used_points"] == 15
    assert summary["check_points"] == 4
    gsd = summary["ground_size_of_image_unit"]
    assert 0.3 < gsd < 0.8  # ~0.5 m ground pixel
    # sigma0 matches the simulated noise (0.2 px) in both units
    assert 0.1 < summary["sigma0_image"] < 0.35
    assert summary["sigma0"] == pytest.approx(summary["sigma0_image"] * gsd, rel=0.35)
    # check points: independent errors within a few sigma, reported separately
    check = summary["check"]
    assert check["count"] == 4 and check["rmse"] < 3 * 0.2 * gsd * np.sqrt(2)
    assert grid_error(fit) < 0.4  # everywhere in the photo, corners included: < 1 pixel
    roles_out = {row["id"]: row["role"] for row in fit.point_table()}
    assert roles_out["G05"] == "rejected" and roles_out["G09"] == "check"
    # the blunder's residual shows it: about 10 px
    g05 = ids.index("G05")
    assert 7 < np.hypot(*fit.residual_image[g05]) < 13


def test_without_robust_the_blunder_spoils_the_fit():
    ids, image, ground, roles = scene.gcp_table(20, noise=0.2, gross={"G05": (8.0, -6.0)})
    plain = fit_rectification(points(ids, image, ground, roles), "homography", robust="none")
    robust = fit_rectification(points(ids, image, ground, roles), "homography", robust="snooping")
    assert plain.rejected == [] and grid_error(plain) > 3 * grid_error(robust)


def test_snooping_with_a_priori_sigma_and_ransac_agree():
    ids, image, ground, roles = scene.gcp_table(25, noise=0.2,
                                                gross={"G03": (0.0, 9.0), "G17": (-7.0, 0.0)})
    pts = points(ids, image, ground, roles)
    chi2 = fit_rectification(pts, "homography", robust="snooping", sigma=0.1)
    rs = fit_rectification(pts, "homography", robust="ransac", ransac_threshold=1.0)
    named = {pts.ids[r.index] for r in chi2.rejected}
    assert named == {"G03", "G17"} == {pts.ids[r.index] for r in rs.rejected}
    assert chi2.rejected[0].method == "chi2-test" and rs.rejected[0].method == "ransac"
    assert grid_error(rs) < 0.4 and grid_error(chi2) < 0.4


def test_ransac_on_many_outliers():
    rng = np.random.default_rng(3)
    src = rng.uniform(0, 1000, (200, 2))
    h = np.array([[1.1, 0.1, 5.0], [-0.05, 0.9, 20.0], [1e-4, -5e-5, 1.0]])
    dst = scene.apply(h, src) + rng.normal(0, 0.05, src.shape)
    bad = rng.choice(200, 40, replace=False)
    dst[bad] += rng.uniform(20, 80, (40, 2)) * rng.choice([-1, 1], (40, 2))
    fit = ransac(HomographyTransform, src, dst, threshold=0.5)
    assert set(np.flatnonzero(~fit.inliers)) == set(bad)
    # the refit on the 160 inliers maps like the truth to well under the 0.05 noise
    assert np.abs(fit.transform(src) - scene.apply(h, src)).max() < 0.03


def test_snooping_stops_without_redundancy():
    src = np.array([[0, 0], [10, 0], [0, 10], [10, 10.0]])
    fit = data_snooping(HomographyTransform, src, src * 2 + 0.3)
    assert fit.rejections == [] and "too low" in fit.notes[0]


def test_similarity_and_affine_special_cases():
    rng = np.random.default_rng(11)
    image = rng.uniform(0, 1000, (8, 2))
    angle, scale = 0.4, 0.25
    sim = np.array([[scale * np.cos(angle), -scale * np.sin(angle), 1688100.0],
                    [scale * np.sin(angle), scale * np.cos(angle), 4799400.0], [0, 0, 1]])
    roles = ["control"] * 8
    fit = fit_rectification(points(range(8), image, scene.apply(sim, image), roles), "similarity")
    np.testing.assert_allclose(fit.transform.params, sim, rtol=1e-10)
    assert fit.transform.n_params == 4 and fit.fit.redundancy == 12
    aff = np.array([[0.3, 0.05, 1688100.0], [-0.02, -0.28, 4799400.0], [0, 0, 1]])
    fit = fit_rectification(points(range(8), image, scene.apply(aff, image), roles), "affine")
    np.testing.assert_allclose(fit.transform.params, aff, rtol=1e-10)
    # a similarity cannot absorb the affine shear: the residuals show it
    sim_fit = fit_rectification(points(range(8), image, scene.apply(aff, image), roles),
                                "similarity")
    assert sim_fit.fit.sigma0 > 1.0


@pytest.mark.parametrize("model, n", [("homography", 3), ("affine", 2), ("similarity", 1)])
def test_too_few_control_points_refused(model, n):
    ids, image, ground, _ = scene.gcp_table(n + 2)
    roles = ["control"] * n + ["check"] * 2  # enough points, but check points do not count
    with pytest.raises(InputDataError, match=rf"{model} needs at least {n + 1} control points, "
                       rf"got {n} \(2 check points"):
        fit_rectification(points(ids, image, ground, roles), model)


def test_collinear_and_degenerate_configurations_refused():
    line = np.column_stack([np.linspace(0, 300, 6), np.linspace(10, 200, 6)])
    ground = scene.apply(np.linalg.inv(TRUE), line)
    with pytest.raises(InputDataError, match="collinear"):
        fit_rectification(points(range(6), line, ground, ["control"] * 6), "affine")
    # 4 points, 3 of them on one line: no homography
    quad = np.array([[10, 10], [100, 10], [200, 10], [50, 150.0]])
    with pytest.raises(InputDataError, match="do not determine a homography"):
        fit_rectification(points(range(4), quad, scene.apply(np.linalg.inv(TRUE), quad),
                                 ["control"] * 4), "homography")


def test_nearly_collinear_points_warned():
    base = np.column_stack([np.linspace(0, 400, 8), np.linspace(0, 300, 8)])
    base[:, 1] += np.array([0, 3, -3, 2, -2, 3, -3, 0])
    fit = fit_rectification(points(range(8), base, scene.apply(np.linalg.inv(TRUE), base),
                                   ["control"] * 8), "affine")
    assert any("nearly on a line" in w for w in fit.warnings)


def test_role_words():
    assert list(parse_roles(["check", "CP", 1, "0", None, "", "gcp", True, "ignore"])) == [
        "check", "check", "check", "control", "control", "control", "control", "check", "ignore"]
    with pytest.raises(InputDataError, match="role of point 2 is 'maybe'"):
        parse_roles(["check", "maybe"])


# -- the algorithm ------------------------------------------------------------------------------
def test_algorithm_csv_to_transform_and_residuals(tmp_path):
    ids, image, ground, roles = scene.gcp_table(16, noise=0.2, gross={"G07": (10.0, 0.0)},
                                                checks=("G01", "G12"))
    z = np.full(16, 100.0) + np.linspace(0, 3, 16)
    csv_path = scene.write_gcp_csv(tmp_path / "gcps.csv", ids, image, ground, roles, z)
    out = toolbox.run("rectify:estimate", {
        "INPUT": csv_path, "CRS": "EPSG:3003", "OUTPUT": tmp_path / "t.json",
        "RESIDUALS": tmp_path / "res.gpkg", "PRINCIPAL_DISTANCE": 100, "FLYING_HEIGHT": 500,
        "IMAGE_RADIUS": 25})
    stats = out["STATISTICS"]
    assert stats["rejected_points"] == ["G07"] and stats["check"]["count"] == 2
    assert stats["crs"] == "EPSG:3003" and len(stats["points"]) == 16
    # relief rule from the points' Z: range 3 m -> ±1.5 m, c = 100 mm, H = 500 m, ρ = 25 mm
    relief = stats["relief"]
    assert relief["height_range_m"] == pytest.approx(3.0)
    assert relief["displacement_image_mm"] == pytest.approx(1500 * 25 / 500000)
    assert relief["flat_enough"] is True
    doc = json.loads((tmp_path / "t.json").read_text())
    assert doc["model"] == "homography" and doc["image_units"] == "pixels"
    model = load_transform(tmp_path / "t.json")
    assert model.crs.to_epsg() == 3003 and len(model.control_points()) == 13
    # the stored matrix maps image -> ground like the truth (0.2 px noise ~ 0.1 m)
    img = np.array([[200.0, 150.0], [10.0, 10.0], [390.0, 290.0]])
    err = scene.apply(model.image_to_ground, img) - scene.apply(np.linalg.inv(TRUE), img)
    assert np.abs(err).max() < 0.3
    import geopandas as gpd

    res = gpd.read_file(tmp_path / "res.gpkg", layer="residuals")
    assert len(res) == 16 and res.crs.to_epsg() == 3003
    assert res.loc[res["id"] == "G07", "role"].item() == "rejected"
    assert res.loc[res["id"] == "G07", "res_image_x"].item() == pytest.approx(-10.0, abs=1.0)


def test_algorithm_relief_warning_and_table4(tmp_path):
    ids, image, ground, roles = scene.gcp_table(8)
    csv_path = scene.write_gcp_csv(tmp_path / "g.csv", ids, image, ground, roles)
    from toolbox.feedback import Feedback

    feedback = Feedback()
    out = toolbox.run("rectify:estimate", {
        "INPUT": csv_path, "OUTPUT": tmp_path / "t.json", "PRINCIPAL_DISTANCE": 150,
        "FLYING_HEIGHT": 150, "HEIGHT_RANGE": 4.0, "IMAGE_RADIUS": 100}, feedback=feedback)
    relief = out["STATISTICS"]["relief"]
    # Table 4: c = 150 mm, 1:1000 -> ΔZ_max = 1.5 m; ±2 m is too much
    assert relief["scale_number"] == pytest.approx(1000)
    assert relief["allowed_departure_m"] == pytest.approx(1.5)
    assert relief["flat_enough"] is False
    assert any("not flat enough" in w and "orthorectification" in w for w in feedback.warnings)
    assert out["STATISTICS"]["crs"] == "none"  # no CRS: a local object system


@pytest.mark.parametrize("c, values", [(150, [1.5, 3, 7.5, 15, 37.5]), (300, [3, 6, 15, 30, 75])])
def test_relief_rule_reproduces_table4(c, values):
    scales = [1000, 2000, 5000, 10000, 25000]
    for m_b, dz in zip(scales, values, strict=True):
        assert max_height_departure(1.0, c, m_b, 100.0) == pytest.approx(dz)
        # eq. [49] at that departure gives exactly the 1 mm tolerance
        assert relief_displacement(dz, 100.0, c, m_b) == pytest.approx(1.0)
        check = relief_check(c, c * m_b / 1000.0, 2 * dz, edge_radius=100.0)
        assert check.flat_enough and check.displacement_image_mm == pytest.approx(1.0)


def test_algorithm_parameter_errors(tmp_path):
    ids, image, ground, roles = scene.gcp_table(8)
    csv_path = scene.write_gcp_csv(tmp_path / "g.csv", ids, image, ground, roles)
    with pytest.raises(ParameterError, match="RANSAC_THRESHOLD is required when ROBUST is ransac"):
        toolbox.run("rectify:estimate", {"INPUT": csv_path, "ROBUST": "ransac",
                                         "OUTPUT": tmp_path / "t.json"})
    with pytest.raises(ParameterError, match="FLYING_HEIGHT is needed"):
        toolbox.run("rectify:estimate", {"INPUT": csv_path, "PRINCIPAL_DISTANCE": 150,
                                         "OUTPUT": tmp_path / "t.json"})
    with pytest.raises(ParameterError, match="HEIGHT_RANGE is required"):
        toolbox.run("rectify:estimate", {"INPUT": csv_path, "PRINCIPAL_DISTANCE": 150,
                                         "FLYING_HEIGHT": 1000, "OUTPUT": tmp_path / "t.json"})
    with pytest.raises(ParameterError, match="MODEL must be one of similarity, affine, homography"):
        toolbox.run("rectify:estimate", {"INPUT": csv_path, "MODEL": "projective",
                                         "OUTPUT": tmp_path / "t.json"})
    with pytest.raises(InputDataError, match="no image-coordinate columns for IMAGE_UNITS=mm"):
        toolbox.run("rectify:estimate", {"INPUT": csv_path, "IMAGE_UNITS": "mm",
                                         "OUTPUT": tmp_path / "t.json"})
    assert not (tmp_path / "t.json").exists()


def test_bad_tables_refused(tmp_path):
    ids, image, ground, roles = scene.gcp_table(8)
    dup = scene.write_gcp_csv(tmp_path / "dup.csv", ["A", "B", "C", "D", "E", "F", "G", "A"],
                              image, ground, roles)
    with pytest.raises(InputDataError, match="point id 'A' appears twice"):
        toolbox.run("rectify:estimate", {"INPUT": dup, "OUTPUT": tmp_path / "t.json"})
    image_nan = image.copy()
    image_nan[3, 0] = np.nan
    bad = scene.write_gcp_csv(tmp_path / "nan.csv", ids, image_nan, ground, roles)
    with pytest.raises(InputDataError, match="NaN/empty image or ground coordinates: G04"):
        toolbox.run("rectify:estimate", {"INPUT": bad, "OUTPUT": tmp_path / "t.json"})


def test_image_mm_units_and_point_layer(tmp_path):
    """Image mm (fiducial x right, y up) from a GeoPackage point layer, named columns."""
    import geopandas as gpd
    import shapely

    ids, image, ground, roles = scene.gcp_table(10)
    mm = np.column_stack([(image[:, 0] - scene.WIDTH / 2) * scene.PIXEL_MM,
                          (scene.HEIGHT / 2 - image[:, 1]) * scene.PIXEL_MM])
    frame = gpd.GeoDataFrame({"name": ids, "xi": mm[:, 0], "eta": mm[:, 1], "use": roles},
                             geometry=shapely.points(ground), crs="EPSG:3003")
    frame.to_file(tmp_path / "gcps.gpkg", layer="gcps")
    out = toolbox.run("rectify:estimate", {"INPUT": tmp_path / "gcps.gpkg", "IMAGE_UNITS": "mm",
                                           "OUTPUT": tmp_path / "t.json"})
    model = load_transform(tmp_path / "t.json")
    assert model.image_units == "mm" and out["STATISTICS"]["points"][0]["id"] == "G01"
    np.testing.assert_allclose(scene.apply(model.image_to_ground, mm), ground, atol=1e-6)


def test_load_transform_refuses_other_files(tmp_path):
    (tmp_path / "x.json").write_text('{"format": "something else"}')
    with pytest.raises(ParameterError, match="TRANSFORM .* is not a transform written by"):
        load_transform(tmp_path / "x.json")
    (tmp_path / "y.json").write_text("not json")
    with pytest.raises(ParameterError, match="cannot read"):
        load_transform(tmp_path / "y.json")


def test_affine_snooping_on_estimated_sigma():
    """The F test (sigma estimated without the tested point) finds a blunder among 7 points."""
    rng = np.random.default_rng(5)
    src = rng.uniform(0, 100, (7, 2))
    dst = scene.apply(np.array([[2, 0.1, 5], [-0.1, 2, 3], [0, 0, 1]]), src)
    dst += rng.normal(0, 0.01, dst.shape)
    dst[2] += (0.5, -0.4)
    fit = data_snooping(AffineTransform, src, dst)
    assert [r.index for r in fit.rejections] == [2] and fit.rejections[0].method == "F-test"


def test_map_scale_judges_check_points_and_relief(tmp_path):
    """MAP_SCALE: the relief rule at the map scale (Table 4's column) and the check points
    against the ±0.5 mm rule; the same check errors pass at 1:5000 (2.5 m) and fail at 1:500."""
    ids, image, ground, roles = scene.gcp_table(16, noise=0.3, checks=("G01", "G12"))
    csv_path = scene.write_gcp_csv(tmp_path / "gcps.csv", ids, image, ground, roles)
    common = {"INPUT": csv_path, "CRS": "EPSG:3003", "PRINCIPAL_DISTANCE": 150,
              "FLYING_HEIGHT": 2250, "HEIGHT_RANGE": 16.0, "IMAGE_RADIUS": 100}
    out = toolbox.run("rectify:estimate", common | {"MAP_SCALE": 5000,
                                                      "OUTPUT": tmp_path / "a.json"})
    stats = out["STATISTICS"]
    assert stats["relief"]["rule_scale_number"] == 5000
    assert stats["relief"]["allowed_departure_m"] == pytest.approx(7.5)
    assert stats["relief"]["flat_enough"] is False  # ±8 m > 7.5 m at 1:5000
    rmse = stats["check"]["rmse"]
    assert stats["accuracy"]["tolerance_m"] == pytest.approx(2.5)
    assert stats["accuracy"]["passes"] is (rmse <= 2.5)
    tight = toolbox.run("rectify:estimate", common | {
        "MAP_SCALE": rmse / 0.6e-3, "OUTPUT": tmp_path / "b.json"})["STATISTICS"]
    assert tight["accuracy"]["passes"] is False  # 0.5 mm at a scale where rmse is 0.6 mm
    photo = toolbox.run("rectify:estimate", common | {"OUTPUT": tmp_path / "c.json"})
    assert photo["STATISTICS"]["relief"]["flat_enough"] is True  # 22.5 m at the photo scale
    assert "accuracy" not in photo["STATISTICS"]
