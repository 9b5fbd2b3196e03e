"""Round 16, conform: outputs checked against their format specifications with readers that are
not the toolbox's (the GeoPackage 1.2 specification's requirements as tests/toolbox/gpkg_check.py
and GDAL's validate_gpkg.py check them, sqlite3, a strict JSON parser)."""

from __future__ import annotations

import json
import sqlite3
import subprocess
from pathlib import Path

import geopandas as gpd
import shapely

import toolbox
from tests.toolbox.gpkg_check import gpkg_problems
from toolbox.io.vector_write import write_layers

X, Y = 1688000.0, 4799000.0
SYSTEM_VALIDATOR = Path("/usr/lib/python3/dist-packages/osgeo_utils/samples/validate_gpkg.py")


def _gdal_validator_problems(path: Path) -> str:
    """GDAL's own validate_gpkg.py (Debian's python3-gdal) on ``path``: '' when it accepts it."""
    if not (SYSTEM_VALIDATOR.exists() and Path("/usr/bin/python3").exists()):
        return ""
    result = subprocess.run(["/usr/bin/python3", str(SYSTEM_VALIDATOR), str(path)],
                            capture_output=True, text=True, timeout=60)
    return "" if result.returncode == 0 else (result.stdout + result.stderr)[-300:]


def _mixed_lines() -> gpd.GeoDataFrame:
    """Restitution lines as they come from a DXF or a geopandas file: 3D and 2D in one layer."""
    return gpd.GeoDataFrame(
        {"code": ["A", "B", "C"]},
        geometry=[shapely.LineString([(X, Y, 300), (X + 50, Y, 301), (X + 50, Y + 50, 302)]),
                  shapely.LineString([(X + 50, Y), (X + 100, Y), (X + 100, Y + 50)]),
                  None], crs="EPSG:3003")


def _z_flag(path: Path, table: str) -> int:
    with sqlite3.connect(path) as db:
        return db.execute("SELECT z FROM gpkg_geometry_columns WHERE table_name = ?",
                          (table,)).fetchone()[0]


def test_gpkg_layer_of_2d_and_3d_features_declares_z_optional(tmp_path):
    # GDAL declared the layer z = 1 (Z mandatory) and stored the 2D line as it is: GeoPackage
    # requirement 19 broken ('geometry without Z found', GDAL's validator rejects the file)
    path = tmp_path / "lines.gpkg"
    write_layers(path, {"lines": _mixed_lines()})
    assert _z_flag(path, "lines") == 2  # optional: both kinds allowed
    assert gpkg_problems(path) == []
    assert _gdal_validator_problems(path) == ""
    back = gpd.read_file(path, layer="lines")  # nothing made up: each feature as written
    assert list(back.geometry.has_z[:2]) == [True, False] and back.geometry[2] is None


def test_gpkg_layer_declared_z_holding_only_2d_features_declares_z_optional(tmp_path):
    frame = _mixed_lines().iloc[1:2]
    path = tmp_path / "lines.gpkg"
    write_layers(path, {"lines": frame}, geometry_types={"lines": "LineString Z"})
    assert gpkg_problems(path) == []
    assert _gdal_validator_problems(path) == ""


def test_gpkg_layers_of_one_kind_keep_their_z_flag(tmp_path):
    frame = _mixed_lines()
    path = tmp_path / "lines.gpkg"
    write_layers(path, {"z": frame.iloc[[0]], "flat": frame.iloc[[1]], "none": frame.iloc[[2]]})
    assert [_z_flag(path, t) for t in ("z", "flat")] == [1, 0]
    assert gpkg_problems(path) == []


def test_mosaic_cut_of_mixed_lines_writes_valid_geopackages(tmp_path):
    # exit 0, and every sheet holding both kinds was rejected by GDAL's validator
    source = tmp_path / "lines.gpkg"
    pyogrio_frame = _mixed_lines()
    pyogrio_frame.to_file(source, layer="lines")
    out = tmp_path / "cut"
    toolbox.run("mosaic:cut", {"INPUT": source, "SCALE": 1000, "SHEET_WIDTH": 20,
                               "SHEET_HEIGHT": 20, "OUTPUT": out})
    sheets = sorted(out.glob("*.gpkg"))
    assert len(sheets) >= 2
    for sheet in sheets:
        assert gpkg_problems(sheet) == [], sheet.name
        assert _gdal_validator_problems(sheet) == "", sheet.name


def _strict_json(path: Path):
    def refuse(constant):
        raise ValueError(f"{constant} is not JSON (RFC 8259)")

    return json.loads(path.read_text(), parse_constant=refuse)


def test_vector_info_json_of_a_layer_without_geometries_is_standard_json(tmp_path):
    # a layer whose features all have a null geometry: "bounds": [NaN, NaN, NaN, NaN] in the
    # file (exit 0; jq and JSON.parse reject it), where an empty layer said null
    path = tmp_path / "attrs.gpkg"
    frame = gpd.GeoDataFrame({"v": [1.0, 2.0]}, geometry=[None, None], crs="EPSG:3003")
    write_layers(path, {"nulls": frame}, geometry_types={"nulls": "Point"})
    out = tmp_path / "info.json"
    toolbox.run("vector:info", {"INPUT": path, "OUTPUT": out})
    (layer,) = _strict_json(out)["layers"]
    assert layer["features"] == 2 and layer["empty_or_null"] == 2
    assert layer["bounds"] is None


def test_vector_info_bounds_leave_out_null_geometries(tmp_path):
    path = tmp_path / "pts.gpkg"
    frame = gpd.GeoDataFrame({"v": [1.0, 2.0, 3.0]},
                             geometry=[shapely.Point(X, Y), None, shapely.Point(X + 10, Y + 5)],
                             crs="EPSG:3003")
    write_layers(path, {"pts": frame})
    out = tmp_path / "info.json"
    toolbox.run("vector:info", {"INPUT": path, "OUTPUT": out})
    (layer,) = _strict_json(out)["layers"]
    assert layer["bounds"] == [X, Y, X + 10, Y + 5]
