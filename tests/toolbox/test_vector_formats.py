"""Vector formats: GeoPackage 1.2 conformance, outputs chosen by extension with round trips, the
QGIS layer-source syntax on input, one geometry kind per layer."""

from __future__ import annotations

import sqlite3
import sys
from pathlib import Path

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely

import toolbox
from tests.toolbox.test_output_folders import hashes
from toolbox.errors import OutputExistsError, ParameterError
from toolbox.io.vector import VECTOR_DRIVERS, open_layer, read_vector
from toolbox.io.vector_points import read_points_xyz
from toolbox.io.vector_write import write_layers
from toolbox.parameters import OutputVector, ValidationContext

sys.path.insert(0, str(Path(__file__).parent))
from gpkg_check import gpkg_problems  # noqa: E402

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_799_500.0
FORMATS = list(VECTOR_DRIVERS)


def sample_layers():
    rng = np.random.default_rng(5)
    xyz = np.column_stack([X0 + rng.uniform(0, 100, 6), Y0 + rng.uniform(0, 100, 6),
                           rng.uniform(200, 300, 6)])
    points = gpd.GeoDataFrame({"name": [f"p{i}" for i in range(6)], "h": xyz[:, 2],
                               "n": np.arange(6, dtype="int64")},
                              geometry=shapely.points(xyz), crs=CRS)
    lines = gpd.GeoDataFrame({"code": ["A", "B"]}, geometry=[
        shapely.LineString([(X0, Y0), (X0 + 10, Y0 + 5)]),
        shapely.LineString([(X0 + 1, Y0 + 1), (X0 + 2, Y0 + 8), (X0 + 9, Y0 + 9)])], crs=CRS)
    empty = gpd.GeoDataFrame({"id": np.zeros(0, dtype="int64")}, geometry=[])  # no CRS of its own
    return {"points": points, "lines": lines, "empty": empty}


# -- GeoPackage 1.2 ---------------------------------------------------------------------------------
def test_geopackage_is_version_1_2_and_valid(tmp_path):
    path = tmp_path / "out.gpkg"
    write_layers(path, sample_layers(), crs=CRS, geometry_types={"empty": "Point"})
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA application_id").fetchone()[0] == int.from_bytes(b"GPKG",
                                                                                      "big")
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 10200
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        assert {"gpkg_spatial_ref_sys", "gpkg_contents", "gpkg_geometry_columns",
                "gpkg_extensions"} <= tables
        # the empty layer still carries the CRS
        srs = dict(conn.execute("SELECT table_name, srs_id FROM gpkg_geometry_columns"))
        assert srs == {"points": 3003, "lines": 3003, "empty": 3003}
        assert conn.execute("SELECT organization, organization_coordsys_id FROM "
                            "gpkg_spatial_ref_sys WHERE srs_id = 3003").fetchone() == ("EPSG", 3003)
    assert gpkg_problems(path) == []
    assert read_vector(f"{path}|layername=empty").crs.to_epsg() == 3003


def test_the_check_catches_a_geopackage_1_4_and_a_missing_trigger(tmp_path):
    """The conformance check can fail: GDAL's default (1.4) and a damaged R-tree are caught."""
    frame = sample_layers()["points"]
    default = tmp_path / "default.gpkg"
    pyogrio.write_dataframe(frame, default, layer="points")  # GDAL's own default version
    problems = gpkg_problems(default)
    assert any("user_version 10400" in p for p in problems)
    assert any("update5" in p for p in problems)  # 1.4-style R-tree triggers
    damaged = tmp_path / "damaged.gpkg"
    write_layers(damaged, {"points": frame})
    with sqlite3.connect(damaged) as conn:
        conn.execute("DROP TRIGGER rtree_points_geom_delete")
        conn.execute("UPDATE gpkg_geometry_columns SET geometry_type_name = 'LINESTRING'")
    problems = gpkg_problems(damaged)
    assert any("rtree_points_geom: triggers" in p for p in problems)
    assert any("POINT geometry in a layer declared LINESTRING" in p for p in problems)


def test_tin_geopackage_is_valid(tmp_path):
    from toolbox.io.crs import parse_crs
    from toolbox.terrain.tin.build import build_tin
    from toolbox.terrain.tin.store import write_tin

    rng = np.random.default_rng(2)
    xyz = np.column_stack([X0 + rng.uniform(0, 50, 80), Y0 + rng.uniform(0, 50, 80),
                           rng.uniform(0, 9, 80)])
    path = tmp_path / "tin.gpkg"
    write_tin(path, build_tin(xyz), parse_crs(CRS))
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 10200
    assert gpkg_problems(path) == []


# -- outputs by extension ---------------------------------------------------------------------------
@pytest.mark.parametrize("ext", FORMATS)
def test_round_trip_in_every_format(tmp_path, ext):
    layers = sample_layers()
    path = tmp_path / f"out{ext}"
    write_layers(path, layers, crs=CRS, geometry_types={"empty": "Point"})
    if ext == ".gpkg":
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out.gpkg"]
    else:  # one layer per file: the first in the path given, the others beside it
        names = {p.name for p in tmp_path.iterdir()}
        assert {f"out{ext}", f"out_lines{ext}", f"out_empty{ext}"} <= names
    for name, expected in layers.items():
        source = path if name == "points" else f"{path}|layername={name}"
        back = read_vector(source)
        if ext == ".fgb" and len(back):  # FlatGeobuf's spatial index stores features in
            key = expected.columns[0]    # Hilbert order: match rows by their first field
            back = back.set_index(key).loc[list(expected[key])].reset_index()
        assert back.crs is not None and back.crs.to_epsg() == 3003, (ext, name)
        assert len(back) == len(expected)
        if len(expected):
            assert shapely.equals_exact(back.geometry.values, expected.geometry.values,
                                        1e-9).all()
            for column in expected.columns.drop("geometry"):
                assert list(back[column]) == pytest.approx(list(expected[column])) \
                    if expected[column].dtype.kind == "f" else list(back[column]) == \
                    list(expected[column])


@pytest.mark.parametrize("ext", [".fgb", ".parquet", ".shp"])
def test_tin_round_trip_in_fast_formats(tmp_path, ext):
    """The same TIN (as triangles in coordinates) comes back from every format, whatever the
    order a format's spatial index puts the features in."""
    from toolbox.io.crs import parse_crs
    from toolbox.terrain.tin.build import build_tin
    from toolbox.terrain.tin.store import read_tin, write_tin

    rng = np.random.default_rng(9)
    xyz = np.column_stack([X0 + rng.uniform(0, 50, 60), Y0 + rng.uniform(0, 50, 60),
                           rng.uniform(0, 9, 60)])
    model = build_tin(xyz)
    path = tmp_path / f"tin{ext}"
    write_tin(path, model, parse_crs(CRS))
    assert (tmp_path / f"tin_nodes{ext}").exists() and (tmp_path / f"tin_edges{ext}").exists()
    back_xyz, back_tri, crs = read_tin(open_layer(path))

    def triangles(points, tri):
        return {tuple(sorted(map(tuple, points[t].round(6).tolist()))) for t in tri}

    assert crs.to_epsg() == 3003
    assert triangles(back_xyz, back_tri) == triangles(model.xyz, model.triangles)


def test_output_vector_extensions(tmp_path):
    param = OutputVector("OUTPUT")
    for ext in FORMATS:
        assert param.validate(tmp_path / f"a{ext}", ValidationContext()) == tmp_path / f"a{ext}"
    assert set(param.extensions) == set(VECTOR_DRIVERS)
    with pytest.raises(ParameterError, match=r"OUTPUT must be a vector file ending with \.gpkg, "
                                             r"\.fgb, \.parquet, \.shp, \.geojson .*'\.kml'"):
        param.validate(tmp_path / "a.kml", ValidationContext())
    with pytest.raises(ParameterError, match="no extension"):
        param.validate(tmp_path / "a", ValidationContext())
    for name in ("a.SHP", "a.Shp"):  # GDAL would write a.shp: refused before any work
        with pytest.raises(ParameterError, match=r"OUTPUT must end with '.shp' in lower case"):
            param.validate(tmp_path / name, ValidationContext())
    with pytest.raises(ParameterError, match=r"OUTPUT must end with '.shp' in lower case"):
        toolbox.run("topology:build_areas", {"INPUT": square_lines(), "OUTPUT": tmp_path / "t.SHP"})
    assert list(tmp_path.iterdir()) == []


def square_lines() -> gpd.GeoDataFrame:
    """The four sides of a 20 m square: one area for topology:build_areas."""
    corners = [(X0, Y0), (X0 + 20, Y0), (X0 + 20, Y0 + 20), (X0, Y0 + 20), (X0, Y0)]
    return gpd.GeoDataFrame({"code": ["Q"] * 4}, geometry=[
        shapely.LineString(corners[i:i + 2]) for i in range(4)], crs=CRS)


def test_algorithm_writes_shapefiles_with_sidecars(tmp_path):
    """A staged Shapefile output comes into place with its .shx/.dbf/.prj and its other layers."""
    out = tmp_path / "topo.shp"
    toolbox.run("topology:build_areas", {"INPUT": square_lines(), "OUTPUT": out})
    names = {p.name for p in tmp_path.iterdir()}
    for stem in ("topo", "topo_arcs", "topo_nodes", "topo_errors_points", "topo_errors_lines"):
        assert {f"{stem}.shp", f"{stem}.shx", f"{stem}.dbf", f"{stem}.prj"} <= names, stem
    assert not [n for n in names if n.endswith(".part")]  # the staging folder is gone
    areas = read_vector(out)
    assert len(areas) == 1 and areas.area.iloc[0] == pytest.approx(400.0)
    assert len(read_vector(f"{out}|layername=arcs")) == 1
    assert areas.crs.to_epsg() == 3003


def test_a_layer_file_beside_a_shapefile_output_needs_overwrite(tmp_path):
    """A one-layer format puts each further layer in <stem>_<layer>.shp: an existing file there
    (a user's points) is replaced only with --overwrite, as the output itself."""
    out = tmp_path / "topo.shp"
    pyogrio.write_dataframe(sample_layers()["points"], tmp_path / "topo_arcs.shp")
    before = hashes(tmp_path)
    with pytest.raises(OutputExistsError, match=r"OUTPUT '.*topo_arcs.shp' exists"):
        toolbox.run("topology:build_areas", {"INPUT": square_lines(), "OUTPUT": out})
    assert hashes(tmp_path) == before  # nothing replaced, nothing new
    toolbox.run("topology:build_areas", {"INPUT": square_lines(), "OUTPUT": out}, overwrite=True)
    assert pyogrio.read_info(tmp_path / "topo_arcs.shp")["geometry_type"] == "LineString"


def test_a_shapefile_output_never_rewrites_a_prj_gdal_reads(tmp_path):
    """dem.shp beside the input dem.asc would write the grid's CRS file dem.prj: refused, even
    with --overwrite; the .prj of no input (other.prj) is replaced only with --overwrite."""
    from rasterio.shutil import copy as gdal_copy
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    z = 300.0 + np.add.outer(np.arange(30.0), np.arange(40.0))
    (tmp_path / "src").mkdir()
    write_raster(tmp_path / "src" / "dem.tif", z.astype("float32"),
                 from_origin(X0, Y0 + 300, 10, 10), CRS, nodata=-9999.0)
    asc = tmp_path / "dem.asc"
    gdal_copy(tmp_path / "src" / "dem.tif", asc, driver="AAIGrid")
    assert (tmp_path / "dem.prj").exists()
    before = hashes(tmp_path)
    for overwrite in (False, True):
        with pytest.raises(ParameterError, match=r"OUTPUT '.*dem.prj' is an input"):
            toolbox.run("carto:contours", {"INPUT": asc, "INTERVAL": 10,
                                           "OUTPUT": tmp_path / "dem.shp"}, overwrite=overwrite)
        assert hashes(tmp_path) == before
    (tmp_path / "other.prj").write_text("a user's CRS file")
    before = hashes(tmp_path)
    params = {"INPUT": asc, "INTERVAL": 10, "OUTPUT": tmp_path / "other.shp"}
    with pytest.raises(OutputExistsError, match=r"other.prj' exists and GDAL would read it"):
        toolbox.run("carto:contours", params)
    assert hashes(tmp_path) == before
    toolbox.run("carto:contours", params, overwrite=True)
    assert pyogrio.read_dataframe(tmp_path / "other.shp").crs.to_epsg() == 3003
    # beside a GeoTIFF without a .prj (GDAL reads none with it), dem.shp is fine
    toolbox.run("carto:contours", {"INPUT": tmp_path / "src" / "dem.tif", "INTERVAL": 10,
                                   "OUTPUT": tmp_path / "src" / "dem.shp"})
    assert pyogrio.read_dataframe(tmp_path / "src" / "dem.shp").crs.to_epsg() == 3003


# -- QGIS layer-source syntax -----------------------------------------------------------------------
@pytest.fixture
def mixed(tmp_path):
    """A GeoPackage of points and lines, and a GeoJSON mixing points, lines and polygons."""
    layers = sample_layers()
    gpkg = tmp_path / "two.gpkg"
    write_layers(gpkg, {"points": layers["points"], "lines": layers["lines"]})
    frame = gpd.GeoDataFrame({"k": [1, 2, 3, 4]}, geometry=[
        shapely.Point(X0, Y0), shapely.LineString([(X0, Y0), (X0 + 1, Y0)]),
        shapely.box(X0, Y0, X0 + 1, Y0 + 1), shapely.MultiPoint([(X0, Y0), (X0 + 2, Y0)])],
        crs=CRS)
    geojson = tmp_path / "mixed.geojson"
    pyogrio.write_dataframe(frame, geojson)
    return gpkg, geojson


def test_layername_layerid_and_subset(mixed):
    gpkg, _ = mixed
    assert open_layer(f"{gpkg}|layername=lines").layer == "lines"
    assert open_layer(f"{gpkg}|layerid=1").layer == "lines"
    assert open_layer(f"{gpkg}|layerid=0").layer == "points"
    subset = read_vector(f"{gpkg}|layername=points|subset=n >= 4 AND name <> 'p5'")
    assert list(subset["name"]) == ["p4"]
    # the fast point reader honours the subset too, and the reference prints back as typed
    source = f"{gpkg}|layername=points|subset=h > 250"
    xyz = read_points_xyz(source)
    expected = sample_layers()["points"]
    assert len(xyz) == int((expected["h"] > 250).sum()) and (xyz[:, 2] > 250).all()
    assert open_layer(source).as_text() == source
    # a subset may contain '|' (it comes last)
    assert len(read_vector(f"{gpkg}|layerid=0|subset=name = 'p1' OR name || '' = 'p2'")) == 2


def test_geometrytype_keeps_one_kind(mixed):
    _, geojson = mixed
    assert open_layer(geojson).geometry_kind is None  # mixed
    points = read_vector(f"{geojson}|geometrytype=Point")
    assert list(points["k"]) == [1, 4]  # multi-points are points too
    assert open_layer(f"{geojson}|geometrytype=Point").geometry_kind == "point"
    assert list(read_vector(f"{geojson}|geometrytype=LineString")["k"]) == [2]
    assert list(read_vector(f"{geojson}|geometrytype=Polygon|subset=k > 0")["k"]) == [3]


def test_layer_source_errors_name_the_parameter(mixed):
    gpkg, _ = mixed
    with pytest.raises(ParameterError, match="LINES .*layerid=5 but .* has 2 layer"):
        open_layer(f"{gpkg}|layerid=5", "LINES")
    with pytest.raises(ParameterError, match="INPUT .*unknown option 'foo'"):
        open_layer(f"{gpkg}|foo=1")
    with pytest.raises(ParameterError, match="geometrytype must be Point, LineString or Polygon"):
        open_layer(f"{gpkg}|geometrytype=Curvy")
    with pytest.raises(ParameterError, match="layername= or layerid=, not both"):
        open_layer(f"{gpkg}|layername=lines|layerid=0")
    with pytest.raises(ParameterError, match="subset 'nosuchfield > 1' is not a valid filter"):
        open_layer(f"{gpkg}|layername=points|subset=nosuchfield > 1")


def test_layer_source_through_an_algorithm(mixed, tmp_path):
    """A VectorLayer parameter takes the syntax: tin:delaunay on a subset of the points."""
    gpkg, _ = mixed
    out = tmp_path / "tin.gpkg"
    result = toolbox.run("tin:delaunay", {"INPUT": f"{gpkg}|layername=points|subset=n < 5",
                                          "OUTPUT": out})
    assert result["STATISTICS"]["nodes"] == 5


def test_mixed_kinds_are_refused_by_the_writer(tmp_path):
    frame = gpd.GeoDataFrame(geometry=[shapely.Point(0, 0), shapely.LineString([(0, 0), (1, 1)])])
    with pytest.raises(ValueError, match="mixes line and point"):
        write_layers(tmp_path / "m.gpkg", {"bad": frame})


SYSTEM_VALIDATOR = Path("/usr/lib/python3/dist-packages/osgeo_utils/samples/validate_gpkg.py")


@pytest.mark.skipif(not (SYSTEM_VALIDATOR.exists() and Path("/usr/bin/ogrinfo").exists()),
                    reason="Debian's GDAL (gdal-bin, python3-gdal) is not installed")
def test_debian_gdal_validator_and_ogrinfo_accept_our_geopackages(tmp_path):
    """Where Debian's GDAL (3.6 on bookworm) is installed: its own validate_gpkg.py passes our
    files and its ogrinfo opens them without the "only partially supported" warning, while
    GDAL's default (1.4) output fails both: the check can fail."""
    import subprocess

    ours = tmp_path / "ours.gpkg"
    write_layers(ours, sample_layers(), crs=CRS, geometry_types={"empty": "Point"})
    default = tmp_path / "default.gpkg"
    pyogrio.write_dataframe(sample_layers()["points"], default, layer="points")

    def validate(path):
        return subprocess.run(["/usr/bin/python3", str(SYSTEM_VALIDATOR), str(path)],
                              capture_output=True, text=True, timeout=120)

    def ogrinfo(path):
        return subprocess.run(["/usr/bin/ogrinfo", "-ro", "-so", str(path)],
                              capture_output=True, text=True, timeout=120)

    result = validate(ours)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "partially supported" not in ogrinfo(ours).stderr
    assert validate(default).returncode != 0
    version = subprocess.run(["/usr/bin/ogrinfo", "--version"], capture_output=True,
                             text=True).stdout
    if version.startswith("GDAL 3.6"):
        assert "partially supported" in ogrinfo(default).stderr


def test_vector_info_reads_geoparquet(tmp_path):
    path = tmp_path / "pts.parquet"
    write_layers(path, {"points": sample_layers()["points"]})
    info = toolbox.run("vector:info", {"INPUT": path})["INFO"]
    (layer,) = info["layers"]
    assert layer["name"] == "pts" and layer["crs"] == "EPSG:3003"
    assert layer["features"] == 6 and layer["has_z"]
