"""Every parameter type: accepted values normalised, bad values refused with a message that names
the parameter, the value and what was expected."""

from __future__ import annotations

import pytest
from pyproj import CRS

from toolbox.errors import OutputExistsError, ParameterError
from toolbox.parameters import (
    Boolean,
    Crs,
    Enum,
    ExtentParameter,
    Field,
    File,
    Integer,
    MultipleLayers,
    Number,
    OutputFile,
    OutputRaster,
    OutputVector,
    RasterLayer,
    String,
    ValidationContext,
    VectorLayer,
)


def check(param, value, ctx=None):
    return param.resolve(value, ctx or ValidationContext())


def refused(param, value, *fragments, ctx=None):
    with pytest.raises(ParameterError) as info:
        check(param, value, ctx)
    message = str(info.value)
    assert message.startswith(param.name), message
    for fragment in fragments:
        assert fragment in message, message
    return message


def test_number_range_and_message():
    p = Number("CELL_SIZE", min_value=0, min_exclusive=True)
    assert check(p, "2.5") == 2.5
    assert refused(p, -2) == "CELL_SIZE must be > 0, got -2"
    refused(p, 0, "> 0")
    refused(p, "abc", "must be a number", "'abc'")
    refused(p, "nan", "finite")
    refused(p, True, "must be a number")
    q = Number("ALPHA", min_value=0, max_value=1)
    assert check(q, 1) == 1.0
    refused(q, 1.5, "<= 1", "1.5")


def test_integer():
    p = Integer("NEIGHBOURS", min_value=1, default=12)
    assert check(p, None) == 12
    assert check(p, "7") == 7
    refused(p, 2.5, "integer", "2.5")
    refused(p, 0, ">= 1", "got 0")


def test_required_and_optional():
    p = Number("Z", "height")
    refused(p, None, "is required", "number")
    assert check(Number("Z", optional=True), None) is None


def test_boolean():
    p = Boolean("OVERVIEWS")
    assert check(p, "yes") is True and check(p, "false") is False and check(p, True) is True
    refused(p, "maybe", "true or false", "'maybe'")


def test_enum_lists_options():
    p = Enum("METHOD", options=["nearest", "bilinear", "cubic"], default="bilinear")
    assert check(p, None) == "bilinear" and check(p, "CUBIC") == "cubic"
    refused(p, "lanczos", "nearest, bilinear, cubic", "'lanczos'")


def test_string():
    assert check(String("NAME"), 12) == "12"


def test_crs():
    p = Crs("CRS")
    assert check(p, "EPSG:3003") == CRS.from_epsg(3003)
    assert check(p, 32632).to_epsg() == 32632
    refused(p, "EPSG:99999", "not a CRS PROJ knows", "EPSG:99999")


def test_extent_order_and_crs():
    p = ExtentParameter("EXTENT")
    e = check(p, "1688000,4799000,1689000,4800000 [EPSG:3003]")
    assert e.bounds == (1688000, 4799000, 1689000, 4800000) and e.crs.to_epsg() == 3003
    assert check(p, [0, 0, 1, 2]).height == 2
    refused(p, "1,2,3", "xmin,ymin,xmax,ymax")
    refused(p, "10,0,5,1", "xmin < xmax")


def test_file(tmp_path):
    f = tmp_path / "codes.txt"
    f.write_text("x")
    p = File("CODES", extensions=[".txt"])
    assert check(p, str(f)) == f
    refused(p, tmp_path / "missing.txt", "does not exist", "missing.txt")
    other = tmp_path / "codes.csv"
    other.write_text("x")
    refused(p, other, ".txt")


def test_vector_layer(points_gpkg, tmp_path):
    p = VectorLayer("INPUT", geometry_types=["point"])
    ref = check(p, str(points_gpkg))
    assert ref.count == 10 and ref.crs.to_epsg() == 3003 and ref.geometry_kind == "point"
    assert check(p, f"{points_gpkg}|layername=pts").layer == "pts"
    refused(p, f"{points_gpkg}|layername=nope", "layer 'nope'", "pts")
    refused(p, tmp_path / "none.gpkg", "does not exist")
    junk = tmp_path / "junk.gpkg"
    junk.write_text("not a geopackage")
    refused(p, junk, "cannot read")
    refused(VectorLayer("LINES", geometry_types=["line"]), points_gpkg, "must be a line layer")


def test_vector_layer_from_geodataframe(points_gpkg):
    import geopandas as gpd

    ref = check(VectorLayer("INPUT"), gpd.read_file(points_gpkg))
    assert ref.path is None and ref.count == 10 and "height" in ref.fields


def test_csv_points_are_a_point_layer(tmp_path):
    csv = tmp_path / "pts.csv"
    csv.write_text("id,East,North,Elev\n1,10,20,30\n2,11,21,31\n")
    ref = check(VectorLayer("INPUT", geometry_types=["point"]), csv)
    assert ref.geometry_kind == "point" and ref.count == 2


def test_field(points_gpkg):
    ctx = ValidationContext()
    ctx.values["INPUT"] = check(VectorLayer("INPUT"), points_gpkg)
    p = Field("Z_FIELD", parent="INPUT", numeric=True)
    assert p.resolve("HEIGHT", ctx) == "height"  # case-insensitive match returns the real name
    refused(p, "elev", "field 'elev'", "height", ctx=ctx)
    refused(p, "name", "must be numeric", ctx=ctx)


def test_raster_layer(plane_dem, tmp_path):
    path = plane_dem[0]
    info = check(RasterLayer("INPUT"), path)
    assert (info.width, info.height, info.count) == (60, 50, 1) and info.crs.to_epsg() == 3003
    bad = tmp_path / "bad.tif"
    bad.write_bytes(b"\x00" * 100)
    refused(RasterLayer("INPUT"), bad, "cannot read", "as a raster")


def test_multiple_layers(plane_dem):
    p = MultipleLayers("INPUTS", layer_type="raster", min_count=2)
    assert len(check(p, [plane_dem[0], plane_dem[0]])) == 2
    refused(p, [plane_dem[0]], "at least 2")


def test_outputs(tmp_path, plane_dem):
    ctx = ValidationContext()
    check(RasterLayer("INPUT"), plane_dem[0], ctx)
    out = OutputRaster("OUTPUT")
    assert check(out, tmp_path / "new.tif", ctx) == tmp_path / "new.tif"
    refused(out, tmp_path / "new.png", ".tif")
    refused(out, plane_dem[0], "also the input INPUT", ctx=ctx)
    existing = tmp_path / "exists.gpkg"
    existing.write_text("x")
    with pytest.raises(OutputExistsError, match="--overwrite"):
        check(OutputVector("OUTPUT"), existing)
    assert check(OutputVector("OUTPUT"), existing, ValidationContext(overwrite=True)) == existing
    refused(OutputFile("REPORT", extensions=[".json"]), tmp_path / "r.txt", ".json")


def test_names_must_be_uppercase():
    with pytest.raises(ValueError):
        Number("cell_size")


def test_describe_is_json_ready():
    import json

    d = Number("CELL_SIZE", "cell", min_value=0, min_exclusive=True, default=2).describe()
    assert json.loads(json.dumps(d))["min_exclusive"] is True
