"""Round 16, conform: outputs checked against their format specifications with readers that are
not the toolbox's (the GeoPackage 1.2 specification's requirements as tests/toolbox/gpkg_check.py
and GDAL's validate_gpkg.py check them, sqlite3, a strict JSON parser)."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from tests.toolbox.gpkg_check import gdal_validator_problems as _gdal_validator_problems
from tests.toolbox.gpkg_check import gpkg_problems
from toolbox.io.vector_write import write_layers

X, Y = 1688000.0, 4799000.0


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


# -- an alpha band GDAL does not read as the mask ---------------------------------------------
def _alpha_raster(count: int, size: int = 600) -> np.ndarray:
    """``count`` bands (the last alpha) of Byte: the first 100 rows outside (alpha 0, data 0)."""
    data = np.full((count, size, size), 120, dtype="uint8")
    data[-1] = 255
    data[:, :100, :] = 0
    return data


@pytest.mark.parametrize("mode", ["streamed", "memory", "cog"])
@pytest.mark.parametrize("count", [3, 5])
def test_alpha_band_gdal_would_not_read_is_also_the_files_mask(tmp_path, mode, count):
    # GDAL reads an alpha band as the mask only as band 2 of 2 or 4 of 4: an RGBN photo's
    # 4 bands + alpha (or grey + NIR + alpha) had every pixel valid to GDAL, gdalwarp, QGIS'
    # GDAL tools and rasterio's dataset_mask: the outside of the photo was black data (exit 0)
    import rasterio
    from affine import Affine

    from toolbox.raster.writer import write_raster

    data = _alpha_raster(count)
    options = {"streamed": {}, "memory": {"memory_mb": 64}, "cog": {"cog": True}}[mode]
    path = write_raster(tmp_path / "a.tif", data, Affine(1, 0, X, 0, -1, Y), "EPSG:3003",
                        alpha=True, overviews=True, **options)
    with rasterio.open(path) as src:
        assert src.count == count and src.colorinterp[-1].name == "alpha"
        np.testing.assert_array_equal(src.dataset_mask() > 0, data[-1] > 0)
        assert src.overviews(1) == [2]
        np.testing.assert_array_equal(src.dataset_mask(out_shape=(300, 300)) > 0,
                                      data[-1, ::2, ::2] > 0)


@pytest.mark.parametrize("count", [2, 4])
def test_alpha_band_gdal_reads_gets_no_extra_mask(tmp_path, count):
    import rasterio
    from affine import Affine

    from toolbox.raster.writer import write_raster

    data = _alpha_raster(count)
    path = write_raster(tmp_path / "a.tif", data, Affine(1, 0, X, 0, -1, Y), "EPSG:3003",
                        alpha=True)
    with rasterio.open(path) as src:
        assert "alpha" in [f.name for f in src.mask_flag_enums[0]]  # GDAL's own alpha rule
        np.testing.assert_array_equal(src.dataset_mask() > 0, data[-1] > 0)


def test_rectified_four_band_photo_outside_is_masked_for_gdal(tmp_path):
    import rasterio

    size = 200
    photo = tmp_path / "rgbn.tif"
    bands = np.stack([np.full((size, size), 60 + 30 * k, dtype="uint8") for k in range(4)])
    with rasterio.open(photo, "w", driver="GTiff", width=size, height=size, count=4,
                       dtype="uint8", photometric="RGB") as dst:  # red, green, blue, NIR
        dst.write(bands)
    # a pixel -> ground similarity turned 30 degrees: the rectified grid has corners outside
    angle = np.radians(30.0)
    ca, sa = np.cos(angle), np.sin(angle)
    rows = ["id,col,row,X,Y"]
    for k, (c, r) in enumerate([(0, 0), (size, 0), (0, size), (size, size), (100, 50),
                                (50, 150)]):
        rows.append(f"P{k},{c},{r},{X + ca * c + sa * r},{Y + sa * c - ca * r}")
    gcps = tmp_path / "gcps.csv"
    gcps.write_text("\n".join(rows) + "\n")
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "MODEL": "affine",
                                     "ROBUST": "none", "OUTPUT": tmp_path / "t.json"})
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "t.json",
                                        "CELL_SIZE": 1, "OUTPUT": tmp_path / "r.tif"})
    with rasterio.open(out["OUTPUT"]) as src:
        assert src.count == 5
        alpha = src.read(5) > 0
        assert 0.2 < 1 - alpha.mean() < 0.6  # the rotated photo leaves corners outside
        np.testing.assert_array_equal(src.dataset_mask() > 0, alpha)


# -- CSV reports ---------------------------------------------------------------------------------
def test_tin_volume_csv_report_quotes_a_dem_path_with_a_comma(tmp_path):
    # the reference row was written as 'reference,<path> band 1,': a folder 'Siena, 2024' split
    # it into 4 fields (RFC 4180 quoting; Excel, pandas and csv readers shifted the columns)
    import csv

    from affine import Affine

    from toolbox.raster.writer import write_raster

    xs, ys = np.meshgrid(np.arange(5) * 10.0, np.arange(5) * 10.0)
    points = gpd.GeoDataFrame(geometry=shapely.points(X + xs.ravel(), Y + ys.ravel(),
                                                      300.0 + xs.ravel() / 10), crs="EPSG:3003")
    write_layers(tmp_path / "pts.gpkg", {"pts": points})
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "pts.gpkg", "OUTPUT": tmp_path / "tin.gpkg"})
    folder = tmp_path / "Siena, 2024"
    folder.mkdir()
    dem = write_raster(folder / 'dem "v2".tif', np.full((6, 6), 299.0, dtype="float32"),
                       Affine(10, 0, X - 5, 0, -10, Y + 45), "EPSG:3003")
    report = tmp_path / "volume.csv"
    toolbox.run("tin:volume", {"TIN": f"{tmp_path / 'tin.gpkg'}|layername=triangles",
                               "REFERENCE_DEM": dem, "REPORT": report})
    rows = list(csv.reader(report.open(newline="")))
    assert {len(row) for row in rows} == {3}
    assert rows[-1][0] == "reference" and rows[-1][1] == f"{dem} band 1"


def test_shapefile_of_2d_and_3d_features_warns_of_the_made_up_z(tmp_path, caplog):
    # a Shapefile is 3D or 2D throughout: GDAL wrote the 2D line with Z = 0, a height nobody
    # measured, without a word (exit 0)
    import logging

    import pyogrio

    path = tmp_path / "lines.shp"
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        write_layers(path, {"lines": _mixed_lines()})
    frame = pyogrio.read_dataframe(path)
    assert list(shapely.get_coordinates(frame.geometry[1], include_z=True)[:, 2]) == [0, 0, 0]
    assert any("1 of 2 features have no Z" in r.getMessage() and "Z = 0" in r.getMessage()
               for r in caplog.records)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        write_layers(tmp_path / "z.shp", {"z": _mixed_lines().iloc[[0, 2]]})
    assert not [r for r in caplog.records if "no Z" in r.getMessage()]


# -- LAS/LAZ -------------------------------------------------------------------------------------
def _las_wkt(path: Path) -> tuple[bool, str]:
    """(WKT global-encoding bit, text of the OGC WKT VLR) read from the LAS 1.4 bytes
    (specification tables 3 and 4; not through laspy)."""
    import struct

    data = path.read_bytes()
    encoding = struct.unpack_from("<H", data, 6)[0]
    header_size, = struct.unpack_from("<H", data, 94)
    n_vlrs, = struct.unpack_from("<I", data, 100)
    offset, wkt = header_size, None
    for _ in range(n_vlrs):
        user = data[offset + 2:offset + 18].rstrip(b"\0")
        record, length = struct.unpack_from("<HH", data, offset + 18)
        if user == b"LASF_Projection" and record == 2112:
            wkt = data[offset + 54:offset + 54 + length].rstrip(b"\0").decode()
        offset += 54 + length
    return bool(encoding & 16), wkt


@pytest.mark.parametrize("crs", ["EPSG:3003", "EPSG:3003+5214"])
def test_las_crs_vlr_is_wkt1_as_las_1_4_says(tmp_path, crs):
    # LAS 1.4 R15 2.5: the WKT of the OGC 01-009 specification (WKT1); laspy wrote pyproj's
    # default WKT2 'PROJCRS[...', which readers of the specification's WKT do not parse
    from pyproj import CRS

    from toolbox.io.pointcloud import write_point_cloud

    path = tmp_path / "points.las"
    write_point_cloud(path, np.array([[X, Y, 300.0], [X + 10, Y + 10, 310.0]]), crs=crs)
    wkt_bit, wkt = _las_wkt(path)
    assert wkt_bit
    assert wkt.startswith(("PROJCS[", "COMPD_CS["))
    assert CRS.from_wkt(wkt) == CRS(crs)


def test_las_north_first_crs_keeps_a_wkt_that_reads_back_the_same(tmp_path):
    from pyproj import CRS

    from toolbox.io.pointcloud import write_point_cloud

    path = tmp_path / "points.las"
    write_point_cloud(path, np.array([[4799000.0, 688000.0, 300.0]]), crs="EPSG:6707")
    assert CRS.from_wkt(_las_wkt(path)[1]) == CRS("EPSG:6707")


def test_classified_copy_of_a_cloud_without_crs_gets_a_wkt1_vlr(tmp_path):
    import laspy
    from pyproj import CRS

    from toolbox.io.pointcloud import PointFilter, open_point_cloud, write_classified_copy

    source = tmp_path / "in.las"
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales, header.offsets = [0.01] * 3, [X, Y, 0.0]
    las = laspy.LasData(header)
    las.x, las.y, las.z = np.array([X, X + 5]), np.array([Y, Y + 5]), np.array([300.0, 301.0])
    las.write(source)
    out = tmp_path / "out.las"
    write_classified_copy(open_point_cloud(source), PointFilter(), out, np.array([2, 1]),
                          crs="EPSG:3003")
    wkt_bit, wkt = _las_wkt(out)
    assert wkt_bit and wkt.startswith("PROJCS[") and CRS.from_wkt(wkt) == CRS("EPSG:3003")


# -- nodata consistent with the data -----------------------------------------------------------
def _ramp_points(path: Path) -> Path:
    """11 x 11 points 10 m apart, Z = (x - 50) / 10 exactly: the column x = 50 is at 0 m."""
    xs, ys = np.meshgrid(np.arange(11) * 10.0, np.arange(11) * 10.0)
    frame = gpd.GeoDataFrame(geometry=shapely.points(X + xs.ravel(), Y + ys.ravel(),
                                                     (xs.ravel() - 50) / 10), crs="EPSG:3003")
    write_layers(path, {"pts": frame})
    return path


def _invalid_cells(path: Path) -> int:
    import rasterio

    with rasterio.open(path) as src:
        return int((src.read_masks(1) == 0).sum())


def test_dem_cells_computed_as_the_nodata_value_are_warned_and_not_counted(tmp_path):
    # a sea-level DEM gridded with NODATA 0: every cell at 0 m read as no data in GDAL/QGIS,
    # STATISTICS said all 100 cells had a value (exit 0, no word)
    from toolbox.feedback import Feedback

    out, feedback = tmp_path / "dem.tif", Feedback()
    result = toolbox.run("dem:nearest", {"INPUT": _ramp_points(tmp_path / "p.gpkg"),
                                         "CELL_SIZE": 10, "NODATA": 0, "OUTPUT": out},
                         feedback=feedback)
    lost = _invalid_cells(out)
    assert lost == 10  # the column of cells whose nearest point is at x = 50
    cells = result["STATISTICS"]["cells"]
    assert cells["cells_with_value"] == 100 - lost and cells["cells_nodata"] == lost
    assert any("10 cell(s) were computed as exactly 0, the NODATA value" in w
               for w in feedback.warnings)


def test_tin_raster_cells_computed_as_the_nodata_value_are_warned(tmp_path):
    toolbox.run("tin:delaunay", {"INPUT": _ramp_points(tmp_path / "p.gpkg"),
                                 "OUTPUT": tmp_path / "tin.gpkg"})
    from toolbox.feedback import Feedback

    out, feedback = tmp_path / "tin.tif", Feedback()
    result = toolbox.run("tin:to_raster", {"TIN": f"{tmp_path / 'tin.gpkg'}|layername=triangles",
                                           "CELL_SIZE": 5, "EXTENT": f"{X},{Y},{X + 100},{Y + 100}",
                                           "NODATA": 0.25, "OUTPUT": out}, feedback=feedback)
    lost = _invalid_cells(out)
    assert lost == 20  # the cells centred at x = 52.5 (Z 0.25)
    assert result["STATISTICS"]["cells_with_data"] == 400 - lost
    assert any(f"{lost} cell(s) were computed as exactly 0.25" in w for w in feedback.warnings)


# -- one layer per code, every code kept ---------------------------------------------------------
def test_attribution_codes_making_the_same_layer_name_keep_every_feature(tmp_path):
    # codes 'A-1' and 'A 1' were both written to the layer 'A_1', the second replacing the first;
    # a code 'unresolved' replaced the unresolved layer (features gone, exit 0, no word)
    codes = tmp_path / "codici.txt"
    codes.write_text("codice;descrizione;tipologia;colore\nA-1;strada;polilinea;1\n"
                     "A 1;fiume;polilinea;2\nunresolved;muro;polilinea;3\n")
    lines = gpd.GeoDataFrame(
        {"code": ["A-1", "A 1", "A 1", "unresolved", "XX"]},
        geometry=[shapely.LineString([(X + 10 * k, Y, 300), (X + 10 * k + 5, Y + 5, 301)])
                  for k in range(5)], crs="EPSG:3003")
    source = tmp_path / "lines.gpkg"
    lines.to_file(source, layer="lines")
    out = tmp_path / "coded.gpkg"
    toolbox.run("attribution:apply", {"INPUT": [source], "CODES": codes, "CRS": "EPSG:3003",
                                      "OUTPUT": out})
    with sqlite3.connect(out) as db:
        tables = [t for (t,) in db.execute("SELECT table_name FROM gpkg_contents WHERE "
                                           "data_type = 'features'")]
        stored = {t: sorted(c for (c,) in db.execute(f'SELECT code FROM "{t}"')) for t in tables}
    written = sorted(c for t, cs in stored.items() if t != "unresolved" for c in cs)
    assert written == ["A 1", "A 1", "A-1", "unresolved"]
    assert stored["unresolved"] == ["XX"]  # the unknown code, still in its own layer
    assert gpkg_problems(out) == []
