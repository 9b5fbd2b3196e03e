"""orientation:footprints, orientation:precision and orientation:monoplot on cases with a known
answer, plus the command line."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from affine import Affine

import toolbox
from toolbox.errors import InputDataError, ParameterError
from toolbox.photogrammetry.normal_case import normal_case_precision
from toolbox.raster.writer import write_raster

X0, Y0 = 1688000.0, 4799000.0
SIDE = 230.0 * (1000.0 - 100.0) / 150.0  # ground side of a nadir 23 cm frame: 1380 m


def nadir_block(tmp_path, kappa=0.0, second_strip=1):
    """Two nadir photos, c = 150 mm, 900 m above the plane Z = 100, base 552 m = 40% of the side
    (forward overlap 60%), and ``second_strip`` photos (1 or 2) in a second strip 1104 m north
    (side overlap 20%)."""
    path = tmp_path / "nadir.yaml"
    photos = [("n1", "1", X0, Y0), ("n2", "1", X0 + 552.0, Y0), ("s1", "2", X0, Y0 + 1104.0),
              ("s2", "2", X0 + 552.0, Y0 + 1104.0)][:2 + second_strip]
    lines = ["version: 1", "crs: EPSG:3003", "angle_unit: rad", "cameras:",
             "  - {name: cam, principal_distance_mm: 150.0, frame_size_mm: [230.0, 230.0],",
             "     image_size_px: [11500, 11500], pixel_size_mm: 0.02}", "photos:"]
    for pid, strip, x, y in photos:
        lines.append(f"  - {{id: {pid}, camera: cam, strip: '{strip}', exterior: {{X0: {x}, "
                     f"Y0: {y}, Z0: 1000.0, omega: 0.0, phi: 0.0, kappa: {kappa}}}}}")
    path.write_text("\n".join(lines) + "\n")
    return path


def flat_dem(tmp_path, height=100.0, west_only=False):
    cell = 10.0
    cols, rows = 400, 300
    xmin, ymax = X0 - 1500.0, Y0 + 2000.0
    z = np.full((rows, cols), height, dtype="float32")
    if west_only:  # the DEM stops 200 m east of photo n1's centre
        z = z[:, : int((X0 + 200.0 - xmin) / cell)]
    path = tmp_path / "dem.tif"
    write_raster(path, z, Affine(cell, 0, xmin, 0, -cell, ymax), "EPSG:3003", nodata=-9999.0)
    return path


@pytest.mark.parametrize("kappa", [0.0, 0.9])
def test_footprints_on_a_plane_have_the_exact_size_and_overlaps(tmp_path, kappa):
    import geopandas as gpd

    out = toolbox.run("orientation:footprints", {"PROJECT": nadir_block(tmp_path, kappa),
                                                 "MEAN_HEIGHT": 100.0, "POINTS_PER_SIDE": 4,
                                                 "OUTPUT": tmp_path / "fp.gpkg"})
    fp = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert fp["area_m2"].to_numpy() == pytest.approx(SIDE ** 2, rel=1e-12)
    assert fp["photo_scale"].to_numpy() == pytest.approx(6000.0)
    assert fp["ground_pixel_m"].to_numpy() == pytest.approx(0.12)
    assert len(fp.geometry[0].exterior.coords) == 17  # 4 per side, closed
    overlaps = gpd.read_file(out["OUTPUT"], layer="overlaps")
    forward = overlaps[overlaps["kind"] == "forward"]
    assert len(forward) == 1 and forward["photo_a"].tolist() == ["n1"]
    if kappa == 0.0:  # (rotated frames overlap less: the overlap is an area ratio)
        assert fp.loc[0, "forward_overlap_pct"] == pytest.approx(60.0)
        side = overlaps[(overlaps["kind"] == "side") & (overlaps["photo_a"] == "n1")]
        assert side["pct_of_a"].tolist() == pytest.approx([20.0])
        assert out["STATISTICS"]["forward_overlap_pct"] == pytest.approx([60.0, 60.0])
    nadir = gpd.read_file(out["OUTPUT"], layer="nadir_points")
    assert (nadir.geometry[0].x, nadir.geometry[0].y, nadir.geometry[0].z) == (X0, Y0, 100.0)
    pp = gpd.read_file(out["OUTPUT"], layer="principal_points")
    assert pp.geometry[0].x == pytest.approx(X0) and pp.geometry[0].z == 100.0


def test_footprints_on_a_dem_and_partial_coverage(tmp_path):
    import geopandas as gpd

    project = nadir_block(tmp_path)
    out = toolbox.run("orientation:footprints", {"PROJECT": project, "DEM": flat_dem(tmp_path),
                                                 "OUTPUT": tmp_path / "fp.gpkg"})
    fp = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert (fp["status"] == "complete").all()
    assert fp["area_m2"].to_numpy() == pytest.approx(SIDE ** 2, rel=1e-9)
    assert np.allclose([c[2] for c in fp.geometry[0].exterior.coords], 100.0)
    partial_dem = tmp_path / "part"
    partial_dem.mkdir()
    feedback = toolbox.Feedback() if hasattr(toolbox, "Feedback") else None
    out = toolbox.run("orientation:footprints", {
        "PROJECT": project, "DEM": flat_dem(partial_dem, 100.0, west_only=True),
        "OUTPUT": tmp_path / "fp2.gpkg"}, feedback=feedback)
    fp = gpd.read_file(out["OUTPUT"], layer="footprints").set_index("photo")
    # 8 points per side; DEM cell centres end 195 m east of n1: 13 of n1's 32 outline points
    # and 21 of n2's (552 m further east) fall beyond it and are placed on the plane
    assert fp.loc["n1", "status"] == "partial" and fp.loc["n1", "vertices_off_dem"] == 13
    assert fp.loc["n2", "vertices_off_dem"] == 21
    assert fp.loc["n2", "area_m2"] == pytest.approx(SIDE ** 2, rel=1e-9)  # plane = DEM height
    assert out["STATISTICS"]["partial_footprints"] == 3


def test_footprints_need_a_dem_or_a_height(tmp_path):
    with pytest.raises(ParameterError, match="MEAN_HEIGHT is required when no DEM is given"):
        toolbox.run("orientation:footprints", {"PROJECT": nadir_block(tmp_path),
                                               "OUTPUT": tmp_path / "fp.gpkg"})


RULES = {  # S000 l.653-659: m_b -> sigma_Z (in the row's unit) for B/Z 1:1, 1:3, 1:10, 1:20
    50000: (1.0, [0.25, 0.75, 2.50, 5.00]), 10000: (0.1, [0.50, 1.5, 5.00, 10.00]),
    1000: (0.01, [0.50, 1.5, 5.00, 10.00]), 100: (0.001, [0.50, 1.5, 5.00, 10.00]),
    25: (0.001, [0.13, 0.38, 1.25, 2.50]),
}


@pytest.mark.parametrize("scale", RULES)
def test_precision_reproduces_the_sigma_z_column_of_the_rules_table(scale):
    unit, expected = RULES[scale]
    c = 150.0
    distance = scale * c / 1000.0
    for ratio, sigma in zip((1, 3, 10, 20), expected, strict=True):
        r = normal_case_precision(c, distance / ratio, distance, 5.0)
        assert r["photo_scale"] == pytest.approx(scale)
        assert abs(r["sigma_z_m"] / unit - sigma) <= 0.005 + 1e-9  # printed with 2 decimals


def test_precision_matches_the_thesis_eq_39_40():
    c, base, z, sigma = 152.0, 920.0, 2300.0, 0.004  # mm, m, m, mm
    n = z * 1000 / c
    xi = 80.0
    r = normal_case_precision(c, base, z, np.sqrt(2) * sigma * 1000, sigma * 1000, xi, 0.0)
    assert r["sigma_z_m"] == pytest.approx(n * (z / base) * np.sqrt(2) * sigma / 1000)
    assert r["sigma_x_m"] == pytest.approx(
        n * sigma * np.sqrt(2 * xi ** 2 * z ** 2 / (c ** 2 * base ** 2) + 1) / 1000)
    assert r["sigma_y_m"] == pytest.approx(n * sigma / 1000)
    with pytest.raises(InputDataError, match="base must be > 0"):
        normal_case_precision(c, 0.0, z, 5.0)


def test_precision_algorithm_manual_and_project(tmp_path):
    out = toolbox.run("orientation:precision", {"PRINCIPAL_DISTANCE": 150, "BASE": 2500,
                                                "DISTANCE": 7500, "OUTPUT": tmp_path / "a.json"})
    assert out["PRECISION"][0]["sigma_z_m"] == pytest.approx(0.75)
    out = toolbox.run("orientation:precision", {"PROJECT": nadir_block(tmp_path),
                                                "DEM": flat_dem(tmp_path),
                                                "OUTPUT": tmp_path / "b.json",
                                                "TABLE": tmp_path / "b.csv"})
    (pair,) = out["PRECISION"]
    assert (pair["photo_a"], pair["photo_b"]) == ("n1", "n2")
    assert pair["base_m"] == pytest.approx(552.0) and pair["distance_m"] == pytest.approx(900.0)
    assert pair["sigma_z_m"] == pytest.approx(6000 * (900 / 552) * 0.005 / 1000)
    assert pair["xi_edge_mm"] == 115.0
    assert json.loads(Path(out["OUTPUT"]).read_text())["pairs"][0]["photo_b"] == "n2"
    with pytest.raises(ParameterError, match="BASE is required when no PROJECT"):
        toolbox.run("orientation:precision", {"PRINCIPAL_DISTANCE": 150, "DISTANCE": 7500,
                                              "OUTPUT": tmp_path / "c.json"})


def test_monoplot_algorithm_flags_misses(tmp_path):
    import geopandas as gpd

    project = nadir_block(tmp_path)
    table = tmp_path / "pts.csv"
    table.write_text("point_id,photo,x_mm,y_mm\nc,n1,0,0\ne,n1,20,-20\nfar,n2,100,0\n")
    dem = flat_dem(tmp_path, 100.0, west_only=True)
    out = toolbox.run("orientation:monoplot", {"PROJECT": project, "INPUT": table, "DEM": dem,
                                               "OUTPUT": tmp_path / "m.gpkg"})
    pts = gpd.read_file(out["OUTPUT"], layer="points")
    assert pts["status"].tolist() == ["ok", "ok", "outside_dem"]
    assert (pts.geometry[1].x, pts.geometry[1].y) == pytest.approx((X0 + 120.0, Y0 - 120.0))
    assert pts.geometry[2] is None
    with pytest.raises(InputDataError, match="1 of 3 rays did not meet the terrain"):
        toolbox.run("orientation:monoplot", {"PROJECT": project, "INPUT": table, "DEM": dem,
                                             "FAIL_ON_MISS": True, "OUTPUT": tmp_path / "n.gpkg"})
    out = toolbox.run("orientation:monoplot", {"PROJECT": project, "INPUT": table, "HEIGHT": 100,
                                               "OUTPUT": tmp_path / "p.gpkg"})
    assert out["STATISTICS"]["status"] == {"ok": 3}


def test_command_line(tmp_path):
    toolbox_cli = [sys.executable, "-m", "toolbox.cli"]
    ok = subprocess.run(toolbox_cli + ["run", "orientation:precision", "--PRINCIPAL_DISTANCE",
                                       "150", "--BASE", "2500", "--DISTANCE", "7500",
                                       "--OUTPUT", str(tmp_path / "p.json")],
                        capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert json.loads((tmp_path / "p.json").read_text())["pairs"][0]["sigma_z_m"] == \
        pytest.approx(0.75)
    bad = subprocess.run(toolbox_cli + ["run", "orientation:footprints", "--PROJECT",
                                        str(nadir_block(tmp_path)), "--OUTPUT",
                                        str(tmp_path / "f.gpkg")],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "MEAN_HEIGHT is required" in bad.stderr
    assert "Traceback" not in bad.stderr
