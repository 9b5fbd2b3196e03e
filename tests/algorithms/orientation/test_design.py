"""orientation:design end to end (layers as declared and consistent with the statistics, the
photo count against 002 eq. [3], a tender verdict) and its bad-input contract (one-line errors,
exit 2, nothing written)."""

import json
import subprocess
import sys

import geopandas as gpd
import pytest
import shapely

import toolbox

EXTENT = "1688000,4797000,1694000,4799500 [EPSG:3003]"


def test_design_from_an_extent_writes_centres_footprints_control_and_report(tmp_path):
    from test_bundle import declared_layer_problems

    params = {"EXTENT": EXTENT, "MAP_SCALE": 1000, "MAX_SIGMA_XY": 0.05, "MAX_SIGMA_Z": 0.002,
              "OUTPUT": tmp_path / "plan.gpkg", "REPORT": tmp_path / "plan.json"}
    out = toolbox.run("orientation:design", params)
    assert not declared_layer_problems("orientation:design", "OUTPUT", out["OUTPUT"], params)
    s = out["STATISTICS"]
    centres = gpd.read_file(out["OUTPUT"], layer="photo_centres")
    control = gpd.read_file(out["OUTPUT"], layer="control")
    prints = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert len(centres) == len(prints) == s["photos"] and centres.crs.to_epsg() == 3003
    assert centres["strip"].nunique() == s["strips"]
    assert s["models"] == s["photos"] - s["strips"]
    assert s["photos"] >= s["minimum_photos_eq3"] == pytest.approx(
        6000 * 2500 / (s["base_m"] * s["strip_spacing_m"]))
    assert 5000 <= s["photo_scale"] <= 6000  # 002 Table 3 for 1:1000
    assert centres.geometry.z.to_numpy() == pytest.approx(s["flying_altitude_m"])
    assert s["flying_height_above_ground_m"] == pytest.approx(0.150 * s["photo_scale"])
    assert len(control) == s["control_points"]["XYZ"] + s["control_points"]["XY"] + \
        s["control_points"]["Z"]
    area = shapely.box(1688000, 4797000, 1694000, 4799500)
    assert area.difference(shapely.union_all(prints.geometry.values)).area == 0
    # a tender asking 2 mm in height fails, 5 cm in planimetry passes
    assert s["checks"]["xy"]["pass"] and not s["checks"]["z"]["pass"]
    assert s["verdict"] == "fail"
    report = json.loads((tmp_path / "plan.json").read_text())
    assert report["verdict"] == "fail" and report["prediction"]["method"] == "bundle"


def test_design_from_a_polygon_layer(tmp_path):
    area = shapely.Polygon([(0, 0), (5000, 0), (5000, 1500), (2000, 1500), (2000, 4000),
                            (0, 4000)])
    path = tmp_path / "area.gpkg"
    gpd.GeoDataFrame({"name": ["L"]}, geometry=[area], crs="EPSG:32632").to_file(path)
    out = toolbox.run("orientation:design", {"AREA": path, "PHOTO_SCALE": 8000,
                                             "OUTPUT": tmp_path / "plan.gpkg"})
    s = out["STATISTICS"]
    prints = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert area.difference(shapely.union_all(prints.geometry.values)).area < 1e-6
    assert s["photos"] < 2.2 * s["minimum_photos_eq3"]  # the L is not flown as its bounding box


def test_a_self_intersecting_area_is_flown_as_its_lobes(tmp_path):
    """A bow-tie AREA (self-intersecting: its signed lobes cancel, area 0) was refused as "the
    project area is empty"; it is repaired as the other algorithms repair polygons (GEOS
    make_valid: two triangles) and the footprints cover both lobes."""
    bowtie = shapely.Polygon([(0, 0), (4000, 2500), (4000, 0), (0, 2500)])
    lobes = shapely.make_valid(bowtie)
    assert bowtie.area == 0 and lobes.area == pytest.approx(5_000_000)
    path = tmp_path / "bowtie.gpkg"
    gpd.GeoDataFrame({"name": ["X"]}, geometry=[bowtie], crs="EPSG:32632").to_file(path)
    out = toolbox.run("orientation:design", {"AREA": path, "PHOTO_SCALE": 8000,
                                             "OUTPUT": tmp_path / "plan.gpkg"})
    prints = gpd.read_file(out["OUTPUT"], layer="footprints")
    assert lobes.difference(shapely.union_all(prints.geometry.values)).area < 1e-6
    assert out["STATISTICS"]["minimum_photos_eq3"] > 0


@pytest.mark.parametrize("args, expect", [
    ([], "EXTENT"),
    (["--EXTENT", EXTENT, "--MAP_SCALE", "1000", "--PHOTO_SCALE", "6000"], "PHOTO_SCALE"),
    (["--EXTENT", EXTENT, "--MAP_SCALE", "100"], "MAP_SCALE"),
    (["--EXTENT", EXTENT, "--MAP_SCALE", "1000", "--FORMAT", "230xabc"], "FORMAT"),
    (["--EXTENT", "11,43,12,44 [EPSG:4326]", "--MAP_SCALE", "1000"], "projected"),
    (["--EXTENT", EXTENT, "--MAP_SCALE", "1000", "--FORWARD_OVERLAP", "40"], "FORWARD_OVERLAP"),
])
def test_bad_input_is_one_line_exit_2_and_nothing_written(tmp_path, args, expect):
    out = tmp_path / "plan.gpkg"
    result = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "orientation:design",
                             *args, "--OUTPUT", str(out), "--REPORT", str(tmp_path / "r.json")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and expect in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "r.json").exists()
