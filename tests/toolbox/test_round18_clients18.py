"""Round 18, clients: outputs as the real clients read them (Debian's GDAL 3.6 / QGIS 3.22).

A DBF Logical field reads as String 'T'/'F' in GDAL before 3.9 (OSGeo/gdal#9515), so Boolean
fields of Shapefile outputs are written as Integer 0/1; the other formats keep the Boolean
subtype, which GDAL 3.6 reads as Boolean. Where the system ``ogrinfo`` is installed the files
are also read with it (the GDAL QGIS uses), else those checks are skipped.
"""

from __future__ import annotations

import shutil
import subprocess

import geopandas as gpd
import numpy as np
import pandas as pd
import pyogrio
import pytest
import shapely

import toolbox
from tests.toolbox.export_files import write_export
from toolbox.io.vector_write import write_layers, write_wkb_layer

CRS = "EPSG:25832"
OGRINFO = shutil.which("ogrinfo")


def _ogrinfo_types(path) -> dict[str, str]:
    """``{field: type}`` as the system ogrinfo (``-so``) lists them."""
    text = subprocess.run([OGRINFO, "-ro", "-al", "-so", str(path)], capture_output=True,
                          text=True, check=True).stdout
    out = {}
    for line in text.splitlines():
        name, sep, rest = line.partition(": ")
        if sep and " " not in name and rest.split(" ")[0] in (
                "String", "Integer", "Integer64", "Real", "Integer(Boolean)", "Date",
                "DateTime"):
            out[name] = rest.split(" ")[0]
    return out


def _points(n=3):
    return shapely.points(np.arange(n) + 500000.0, np.arange(n) + 5000000.0)


def _shp_fields(path) -> dict[str, str]:
    info = pyogrio.read_info(path)
    return dict(zip(info["fields"], [str(t) for t in info["dtypes"]], strict=True))


def test_shapefile_booleans_are_integer_0_1_with_nulls(tmp_path):
    frame = gpd.GeoDataFrame({
        "closed": np.array([True, False, True]),
        "side_ok": pd.array([True, None, False], dtype="boolean"),
        "flag": np.array([False, None, True], dtype=object),
        "name": ["a", "b", "c"], "n": np.array([1, 2**40, 3], dtype=np.int64)},
        geometry=_points(), crs=CRS)
    path = write_layers(tmp_path / "b.shp", {"b": frame})
    fields = _shp_fields(path)
    assert fields["closed"].startswith("int") and fields["side_ok"].startswith("int")
    assert fields["flag"].startswith("int") and fields["name"] == "object"
    assert fields["n"] == "int64"
    back = pyogrio.read_dataframe(path)
    assert back["closed"].tolist() == [1, 0, 1]
    assert back["side_ok"].iloc[0] == 1 and pd.isna(back["side_ok"].iloc[1]) \
        and back["side_ok"].iloc[2] == 0
    assert back["flag"].iloc[0] == 0 and pd.isna(back["flag"].iloc[1]) \
        and back["flag"].iloc[2] == 1
    assert back["n"].tolist() == [1, 2**40, 3]
    assert frame["closed"].dtype == bool  # the caller's frame is not changed
    if OGRINFO:
        types = _ogrinfo_types(path)
        assert types["closed"] == types["side_ok"] == types["flag"] == "Integer", types


@pytest.mark.parametrize("ext", ["gpkg", "fgb", "geojson"])
def test_other_formats_keep_the_boolean_subtype(tmp_path, ext):
    frame = gpd.GeoDataFrame({"closed": np.array([True, False, True])}, geometry=_points(),
                             crs=CRS)
    path = write_layers(tmp_path / f"b.{ext}", {"b": frame})
    assert _shp_fields(path)["closed"] == "bool"
    if OGRINFO:
        assert _ogrinfo_types(path)["closed"] == "Integer(Boolean)"


def test_array_writer_shapefile_booleans_are_integer(tmp_path):
    wkb = shapely.to_wkb(_points())
    path = write_wkb_layer(tmp_path / "w.shp", "w", wkb,
                           {"closed": np.array([True, False, True]),
                            "elev": np.array([1.0, 2.0, 3.0])}, "Point")
    assert _shp_fields(path)["closed"].startswith("int")
    assert pyogrio.read_dataframe(path)["closed"].tolist() == [1, 0, 1]
    if OGRINFO:
        assert _ogrinfo_types(path)["closed"] == "Integer"


def _dem(path):
    import rasterio
    from rasterio.transform import from_origin

    y, x = np.mgrid[0:30, 0:30]
    z = (100 + 18 * np.exp(-((x - 15) ** 2 + (y - 15) ** 2) / 60)).astype("float32")
    with rasterio.open(path, "w", driver="GTiff", width=30, height=30, count=1,
                       dtype="float32", crs=CRS,
                       transform=from_origin(500000, 5000030, 1, 1)) as ds:
        ds.write(z, 1)
    return path


def test_contours_shapefile_closed_is_integer(tmp_path):
    """carto:contours to .shp: ``closed`` read as String 'T'/'F' by GDAL 3.6 (a QGIS 3.22
    rule ``"closed" = 1`` matched nothing); now Integer, 1 exactly for the rings."""
    out = tmp_path / "c.shp"
    toolbox.run("carto:contours", {"INPUT": _dem(tmp_path / "dem.tif"), "INTERVAL": 5,
                                   "OUTPUT": out})
    back = pyogrio.read_dataframe(out)
    assert str(back["closed"].dtype).startswith("int")
    rings = np.array([shapely.get_geometry(g, 0).is_closed for g in back.geometry])
    assert len(back) and (back["closed"].to_numpy() == rings.astype(int)).all()
    if OGRINFO:
        assert _ogrinfo_types(out)["closed"] == "Integer"


def test_tin_shapefile_breakline_is_integer(tmp_path):
    """tin:delaunay to .shp (written through Arrow): the edges' ``breakline`` was a DBF
    Logical (String in GDAL 3.6); now Integer, 1 on the breakline's edge only."""
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 100, (30, 2)) + [500000, 5000000]
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], 100 + xy[:, 0] * 0),
                     crs=CRS).to_file(tmp_path / "p.gpkg")
    gpd.GeoDataFrame(geometry=[shapely.LineString([(500010, 5000050, 100),
                                                   (500090, 5000050, 100)])],
                     crs=CRS).to_file(tmp_path / "bl.gpkg")
    toolbox.run("tin:delaunay", {"INPUT": tmp_path / "p.gpkg", "BREAKLINES": tmp_path / "bl.gpkg",
                                 "OUTPUT": tmp_path / "t.shp"})
    edges = pyogrio.read_dataframe(tmp_path / "t_edges.shp")
    assert str(edges["breakline"].dtype).startswith("int")
    on_line = np.array([abs(c[0][1] - 5000050) < 1e-6 and abs(c[-1][1] - 5000050) < 1e-6
                        for c in edges.geometry.map(lambda g: list(g.coords))])
    assert on_line.any() and (edges["breakline"].to_numpy() == on_line.astype(int)).all()
    if OGRINFO:
        assert _ogrinfo_types(tmp_path / "t_edges.shp")["breakline"] == "Integer"


@pytest.mark.parametrize("ext", ["fgb", "shp", "geojson", "parquet"])
def test_merge_to_one_layer_formats_writes_the_merge_style_beside_its_file(tmp_path, ext):
    """attribution:merge to .fgb/.shp/.geojson/.parquet (offered by OUTPUT) stored the merge
    layer's style with sqlite in the output: exit 2, 'cannot read an input: it is truncated or
    corrupt (file is not a database)'. Now the style goes beside the merge layer's file, as
    for attribution:apply, and QGIS loads it with the file."""
    square = [(0, 0, 330), (10, 0, 330), (10, 10, 330), (0, 10, 330), (0, 0, 330)]
    moved = [(x + 0.03, y + 0.02, z + 0.02) for x, y, z in square]
    paths = [write_export(tmp_path / "a.txt", [("FAB01002", square)]),
             write_export(tmp_path / "b.txt", [("FAB01002", moved)])]
    out = tmp_path / f"merged.{ext}"
    stats = toolbox.run("attribution:merge", {"INPUT": paths, "SNAP_TOLERANCE": 0.2,
                                              "HEIGHT_SNAP_TOLERANCE": 0.1, "CRS": "EPSG:3003",
                                              "OUTPUT": out})["STATISTICS"]
    assert stats["duplicates_removed"] == 1
    merge = tmp_path / f"merged_merge.{ext}"
    events = gpd.read_parquet(merge) if ext == "parquet" else pyogrio.read_dataframe(merge)
    assert events["kind"].tolist() == ["duplicate_removed"]
    qml = (tmp_path / "merged_merge.qml").read_text()
    assert "<qgis" in qml and (tmp_path / "merged_merge.sld").is_file()
    lines = gpd.read_parquet(out) if ext == "parquet" else pyogrio.read_dataframe(out)
    assert len(lines) == 1


def test_quality_report_reads_shapefile_residuals_with_cut_names(tmp_path):
    """dem:cross_validate RESIDUALS as a Shapefile holds ``tin_linear_err`` as ``tin_line_1``
    (``nearest_err`` as ``nearest_er``...): report:quality then failed with exit 2, blaming the
    run report as 'incomplete (no 'tin_linear_err')', and its histogram left out every method
    whose name was cut. Now every method's errors are read back under the written names."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 100, (60, 2)) + [500000, 5000000]
    z = 100 + 0.05 * (xy[:, 0] - 500000)  # a plane: tin_linear exact, the best method
    gpd.GeoDataFrame(geometry=shapely.points(xy[:, 0], xy[:, 1], z), crs=CRS).to_file(
        tmp_path / "p.gpkg")
    (tmp_path / "reports").mkdir()
    for ext in ("shp", "gpkg"):
        toolbox.run("dem:cross_validate", {
            "INPUT": tmp_path / "p.gpkg", "METHODS": "nearest,idw,tin_linear",
            "OUTPUT": tmp_path / f"cv_{ext}.json", "RESIDUALS": tmp_path / f"res.{ext}"},
            report=tmp_path / "reports" / "cv.json" if ext == "shp" else None)
    toolbox.run("report:quality", {"REPORTS": tmp_path / "reports",
                                   "OUTPUT": tmp_path / "q.html"})  # exit 2 before
    assert (tmp_path / "q.html").stat().st_size > 0
    from toolbox.cartography.quality_sections import _residual_points

    methods = ["nearest", "idw", "tin_linear"]
    shp = _residual_points(gpd, tmp_path / "res.shp", methods)
    ref = gpd.read_file(tmp_path / "res.gpkg")
    for k in methods:
        np.testing.assert_allclose(shp[f"{k}_err"], ref[f"{k}_err"], atol=1e-9, equal_nan=True)
        np.testing.assert_allclose(shp[f"{k}_z"], ref[f"{k}_z"], atol=1e-9, equal_nan=True)
