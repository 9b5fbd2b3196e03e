"""Round 17, sweep "stats": reported statistics recomputed from hand-computable cases."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from toolbox.terrain.tin.cutfill import plane_cut_fill


def test_cut_fill_flat_triangles_at_the_reference_crossing_the_mask_are_neither():
    # z = 5 on x <= 10 (flat, at the reference), z = 5 + (x - 10) beyond; mask 5..15 x 0..5:
    # cut = 5 * 5² / 2 = 62.5 over 25 m², no fill, 50 m² compared. The flat triangles crossing
    # the mask's edge counted as cut AND fill (cut_area 50, fill_area 25: more than the area).
    def z(x):
        return 5.0 if x <= 10 else 5.0 + (x - 10)

    nodes = [(x, y) for x in (0, 10, 20) for y in (0, 10)]
    xyz = np.array([(x, y, z(x)) for x, y in nodes])
    k = {p: i for i, p in enumerate(nodes)}
    tri = np.array([[k[(0, 0)], k[(10, 0)], k[(10, 10)]], [k[(0, 0)], k[(10, 10)], k[(0, 10)]],
                    [k[(10, 0)], k[(20, 0)], k[(20, 10)]], [k[(10, 0)], k[(20, 10)], k[(10, 10)]]])
    r = plane_cut_fill(xyz, tri, 5.0, shapely.box(5, 0, 15, 5))
    assert r.cut_volume == pytest.approx(62.5) and r.fill_volume == pytest.approx(0.0, abs=1e-9)
    assert r.cut_area == pytest.approx(25.0) and r.fill_area == pytest.approx(0.0, abs=1e-9)
    assert r.area == pytest.approx(50.0)


def test_loo_error_standard_deviation_is_the_sample_one():
    from toolbox.terrain.gridding.validation import error_summary

    # errors -50 and +50: mean 0, RMSE 50, sample standard deviation 50·sqrt(2) (n - 1);
    # it was the population one, 50
    s = error_summary(np.array([50.0, 150.0, np.nan]), np.array([100.0, 100.0, 7.0]))
    assert s["rmse"] == pytest.approx(50.0) and s["mean_error"] == pytest.approx(0.0)
    assert s["std_error"] == pytest.approx(50.0 * np.sqrt(2.0))
    # one error: no spread to estimate (was 0.0)
    assert error_summary(np.array([3.0]), np.array([1.0]))["std_error"] is None


def test_streamed_loo_standard_deviation_is_the_sample_one(tmp_path):
    from toolbox.terrain.gridding.stream_quality import _summary

    errors = np.array([-50.0, 50.0])
    path = tmp_path / "errors.bin"
    path.write_bytes(errors.tobytes())
    sums = {"n": 2, "points": 2, "err": list(errors), "err2": list(errors ** 2),
            "abs": list(np.abs(errors))}
    s = _summary(sums, path, (50.0, 0, None), np.array([], dtype=np.int64))
    assert s["std_error"] == pytest.approx(50.0 * np.sqrt(2.0))
    one = _summary({"n": 1, "points": 1, "err": [2.0], "err2": [4.0], "abs": [2.0]},
                   path, (2.0, 0, None), np.array([], dtype=np.int64))
    assert one["std_error"] is None


def test_quality_report_interior_sigma0_without_redundancy_is_not_zero():
    from toolbox.cartography.quality import Specification
    from toolbox.cartography.quality_sections import interior_section

    # three marks, an affine: no redundancy, sigma0 undefined (None): it was printed "0.0 µm"
    report = {"outputs": {"STATISTICS": {"photos": 1, "max_residual_mm": 0.0,
                                         "max_sigma0_mm": None}}}
    sec = interior_section([("io", report)], Specification(), [])
    table = next(b for b in sec.blocks if b[0] == "table")
    assert table[2][0][2] == "n/a"


def test_quality_report_keeps_two_significant_digits_of_small_values():
    from toolbox.cartography.quality import Specification
    from toolbox.cartography.quality_sections import ortho_section

    # a 2.5 cm drone orthophoto with a 4 mm check RMSE: it read cell "0.03 m", RMSE "0.00 m"
    reports = {"ortho:photo": [("o", {"outputs": {"STATISTICS": {
        "photo": "p1", "cell_size": 0.025, "photo_gsd_m": 0.0125,
        "max_relief_displacement_m": 0.5, "outside_photo_fraction": 0.0}}})],
        "report:ortho_check": [("c", {"outputs": {"STATISTICS": {
            "ortho": "o.tif", "points": 2, "matched": 2, "rmse_x_m": 0.003, "rmse_y_m": 0.002,
            "rmse_planimetric_m": 0.004, "largest_m": 0.005}}})]}
    verdicts = []
    sec = ortho_section(reports, Specification(500.0, 0.5, 0.5, 15.0), verdicts)
    tables = [b for b in sec.blocks if b[0] == "table"]
    assert tables[0][2][0][1:3] == ["0.025 m", "0.013 m"]
    assert tables[1][2][0][2:6] == ["0.003 m", "0.002 m", "0.004 m", "0.005 m"]
    assert verdicts[-1].measured.startswith("0.004 m")


def _ground_filter_stats(tmp_path, xyz):
    import toolbox
    from toolbox.io.pointcloud import write_point_cloud

    tmp_path = tmp_path / str(len(xyz))
    tmp_path.mkdir()
    write_point_cloud(tmp_path / "pts.las", xyz, "EPSG:32632")
    res = toolbox.run("dem:ground", {"INPUT": str(tmp_path / "pts.las"), "CELL_SIZE": 1.0,
                                     "OUTPUT": str(tmp_path / "dtm.tif"),
                                     "NONGROUND": str(tmp_path / "ng.tif")})
    return res["STATISTICS"]["ground_filter"]


def test_ground_filter_object_fraction_does_not_count_empty_cells(tmp_path):
    # a flat field surveyed in strips (columns 0-1 of every 4 of 1 m): no object at all; the
    # empty cells of the filter grid counted as objects (0.47)
    x0, y0 = 500000.0, 5000000.0
    flat = np.array([(x0 + x + 0.5, y0 + y + 0.5, 100.0) for x in range(40) for y in range(40)
                     if x % 4 < 2])
    g = _ground_filter_stats(tmp_path, flat)
    assert g["ground"] == len(flat) and g["nonground"] == 0
    assert g["object_cells_fraction"] == 0.0
    assert 0.4 < g["empty_cells_fraction"] < 0.55
    # a 10 x 10 m, 10 m high block on a fully surveyed 40 x 40 m field: about 100 of 1600
    full = np.array([(x0 + x + 0.5, y0 + y + 0.5, 110.0 if 15 <= x < 25 and 15 <= y < 25
                      else 100.0) for x in range(40) for y in range(40)])
    g = _ground_filter_stats(tmp_path, full)
    assert g["nonground"] == 100
    assert g["object_cells_fraction"] == pytest.approx(100 / 1600, abs=0.02)


def test_quality_report_bundle_with_height_only_check_points():
    from toolbox.cartography.quality import Specification, build_sections

    # check points all Z-only: the bundle reports check_rmse_m x, y None; the report crashed
    # (exit 3, NoneType has no hypot); now planimetric "not checked", height judged
    report = {"algorithm": "orientation:bundle", "outputs": {"STATISTICS": {
        "sigma0": 1.0, "redundancy": 10, "photos": 2, "points": 9, "rejected": 0, "flagged": 0,
        "control_rmse_m": {"x": 0.05, "y": 0.04, "z": 0.08},
        "check_rmse_m": {"x": None, "y": None, "z": 0.12}}}}
    verdicts, _ = build_sections({"orientation:bundle": [("b", report)]}, Specification())
    got = {v.criterion: (v.measured, v.status) for v in verdicts}
    assert got["check points, planimetric RMSE"] == ("n/a", "not checked")
    assert got["check points, height RMSE"] == ("0.120 m", "pass")


def test_quality_report_orientation_check_without_check_points_counts_zero():
    from toolbox.cartography.quality import Specification
    from toolbox.cartography.quality_sections import orientation_section

    # no check point intersected: the count read "None"
    report = {"outputs": {"STATISTICS": {"observations": 8, "rmse_um": 4.0, "flagged": 0,
                                         "threshold_px": 1.0, "control_points": 4,
                                         "control_rmse_xy_m": 0.1, "control_rmse_z_m": 0.2}}}
    sec = orientation_section({"orientation:check": [("c", report)]}, Specification(), [])
    table = next(b for b in sec.blocks if b[0] == "table")
    assert table[2][0] == ["Points intersected", "4", "0"]


def test_quality_report_small_seamline_cut_area_is_not_zero():
    from toolbox.cartography.quality_sections import mosaic_section

    # a 30 m² sliver an orthophoto supplies read "0.00 ha"
    report = {"outputs": {"STATISTICS": {"method": "voronoi", "orthos": 2,
                                         "cut_areas": {"a": 25000.0, "b": 30.0}}}}
    sec = mosaic_section({"mosaic:seamlines": [("s", report)]}, [])
    table = next(b for b in sec.blocks if b[0] == "table")
    assert table[2] == [["a", "2.50 ha"], ["b", "0.003 ha"]]


def test_quality_report_resection_of_a_camera_model_photo():
    from toolbox.cartography.quality import Specification
    from toolbox.cartography.quality_sections import orientation_section

    # a Brown/OpenCV photo has no film plane: sigma0_um None (its sigma0 in pixels); the
    # report crashed (exit 3, None.__format__)
    report = {"outputs": {"STATISTICS": {"photos": 3, "sigma0_um": {
        "F1": 4.25, "DJI_1": None, "DJI_2": None}, "sigma0_px": {"DJI_1": 0.8}}}}
    sec = orientation_section({"orientation:resection": [("r", report)]}, Specification(), [])
    table = next(b for b in sec.blocks if b[0] == "table")
    assert table[2] == [["DJI_1", "0.80 px"], ["DJI_2", "n/a"], ["F1", "4.2 µm"]]


def test_quality_report_cross_validation_without_predicted_points():
    from toolbox.cartography.quality import Specification
    from toolbox.cartography.quality_sections import dem_section

    def run(methods, best):
        return ("cv", {"outputs": {"STATISTICS": {"crs": "EPSG:32632", "methods": methods,
                                                  "best": best}}})

    none = {"points": 5, "predicted": 0, "rmse": None, "mean_error": None,
            "max_abs_error": None}
    # every point a hull vertex: no RMSE anywhere; the report crashed (exit 3, None < None)
    verdicts = []
    dem_section([run({"nearest": none, "idw": none}, None)], Specification(), verdicts)
    assert [(v.measured, v.status) for v in verdicts] == [("no point predicted", "not checked")]
    # one method without predictions beside one with: its bar crashed (None * scale)
    verdicts = []
    some = none | {"predicted": 3, "rmse": 0.5, "mean_error": 0.1, "max_abs_error": 0.9}
    sec = dem_section([run({"nearest": none, "idw": some}, "idw")], Specification(), verdicts)
    assert [(v.measured, v.status) for v in verdicts] == [("0.500 m", "pass")]
    for fig in sec.figures:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_quality_report_tolerance_is_printed_with_its_digits():
    from toolbox.cartography.quality import Specification
    from toolbox.cartography.quality_sections import orientation_section

    # contour interval 0.25 m: height RMSE <= 0.25 / 3.29 = 0.076 m; it read "<= 0.08 m", so a
    # 0.078 m RMSE failed against a printed tolerance it met
    spec = Specification(500.0, 0.3, 0.25, 15.0)
    assert "height RMSE <= 0.076 m" in spec.describe()
    report = {"outputs": {"STATISTICS": {"observations": 8, "rmse_um": 4.0, "flagged": 0,
                                         "threshold_px": 1.0, "check_points": 3,
                                         "check_rmse_xy_m": 0.1, "check_rmse_z_m": 0.078}}}
    verdicts = []
    orientation_section({"orientation:check": [("c", report)]}, spec, verdicts)
    height = next(v for v in verdicts if "height" in v.criterion)
    assert (height.measured, height.tolerance, height.status) == ("0.078 m", "<= 0.076 m",
                                                                  "FAIL")


def test_tin_interpolate_check_points_that_are_tin_nodes_are_not_checks(tmp_path):
    import geopandas as gpd

    import toolbox

    # TIN z = x on a 10 m square; check points: a node of the TIN itself (dz 0 by construction)
    # and one surveyed 0.3 above the surface. dz_rmse over the one independent check: 0.3 (it
    # was sqrt(0.09 / 2) = 0.21, the node counted as a perfect check)
    x0, y0 = 500000.0, 5000000.0

    def node(x, y):
        return (x0 + x, y0 + y, float(x))

    tris = [shapely.Polygon([node(0, 0), node(10, 0), node(10, 10)]),
            shapely.Polygon([node(0, 0), node(10, 10), node(0, 10)])]
    gpd.GeoDataFrame(geometry=tris, crs="EPSG:32632").to_file(tmp_path / "tin.gpkg",
                                                              layer="triangles")
    gpd.GeoDataFrame(geometry=[shapely.Point(x0, y0, 0.0), shapely.Point(x0 + 5, y0 + 2, 5.3)],
                     crs="EPSG:32632").to_file(tmp_path / "checks.gpkg")
    s = toolbox.run("tin:interpolate", {"INPUT": tmp_path / "checks.gpkg",
                                        "TIN": tmp_path / "tin.gpkg",
                                        "OUTPUT": tmp_path / "out.gpkg"})["STATISTICS"]
    assert s["dz_rmse"] == pytest.approx(0.3) and s["dz_mean"] == pytest.approx(0.3)
    assert (s["dz_points"], s["dz_at_tin_nodes"]) == (1, 1)
