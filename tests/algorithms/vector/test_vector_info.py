"""vector:info on layers whose content is known by construction: counts, geometry types, empty,
null and invalid geometries, bounds, Z range, CRS labels; a point file is described without
pandas, geopandas, pyarrow or pyproj (the reader of the 10,000-point start-up row)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import toolbox


@pytest.fixture
def mixed_gpkg(tmp_path):
    """Layer 'mixed' (EPSG:3003): a PointZ, a null, an empty point, a self-crossing (invalid)
    polygon, a LineString Z and a MultiPoint; layer 'll' (EPSG:4326): one point; layer 'table':
    two rows without geometry."""
    import geopandas as gpd
    import pandas as pd
    import pyogrio
    from shapely.geometry import LineString, MultiPoint, Point, Polygon

    path = tmp_path / "mixed.gpkg"
    geoms = [Point(1, 2, 3), None, Point(), Polygon([(0, 0), (2, 2), (2, 0), (0, 2)]),
             LineString([(0, 0, 5), (1, 1, 7)]), MultiPoint([(5, 5), (6, 6)])]
    gpd.GeoDataFrame({"a": range(6)}, geometry=geoms, crs="EPSG:3003").to_file(path, layer="mixed")
    gpd.GeoDataFrame({"b": [1.5]}, geometry=[Point(10, 45)], crs="EPSG:4326").to_file(
        path, layer="ll")
    pyogrio.write_dataframe(pd.DataFrame({"t": [1, 2]}), path, layer="table")
    return path


def test_every_layer_described(mixed_gpkg):
    layers = {la["name"]: la for la in toolbox.run("vector:info", {"INPUT": mixed_gpkg})
              ["INFO"]["layers"]}
    assert layers["mixed"] == {
        "name": "mixed", "crs": "EPSG:3003", "fields": {"a": "int64"}, "features": 6,
        "geometry_types": ["LineString", "MultiPoint", "Point", "Polygon"], "empty_or_null": 2,
        "invalid": 1, "bounds": [0.0, 0.0, 6.0, 6.0], "has_z": True, "z_range": [3.0, 7.0]}
    assert layers["ll"]["crs"] == "EPSG:4326" and layers["ll"]["bounds"] == [10, 45, 10, 45]
    table = layers["table"]
    assert (table["features"], table["geometry_types"], table["empty_or_null"]) == (2, [], 2)
    assert not table["has_z"] and table["crs"] == "none"


def test_a_file_of_many_layers_is_listed_once(mixed_gpkg, monkeypatch):
    """Every layer described from one listing of the file: a reference opened per layer listed
    the whole file again for each (a GeoPackage of 200 layers x 60 fields: 72 s, now 48 s; the
    rest is pyogrio opening the file for each layer's information and features)."""
    import pyogrio.core

    calls = []
    real = pyogrio.core.list_layers

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(pyogrio.core, "list_layers", counted)
    layers = toolbox.run("vector:info", {"INPUT": mixed_gpkg})["INFO"]["layers"]
    assert [la["name"] for la in layers] == ["mixed", "ll", "table"]
    assert len(calls) <= 2  # the parameter's validation and the description: not one per layer


@pytest.mark.parametrize("source", ["mixed.gpkg|layername=mixed",
                                    "mixed.gpkg|layername=mixed|subset=a > 2",
                                    "mixed.gpkg|layername=table"])
def test_its_reader_gives_what_geopandas_reads(mixed_gpkg, source):
    """read_geometries (WKB from OGR, no GeoDataFrame) against pyogrio + geopandas."""
    import pyogrio
    import shapely

    from toolbox.io.vector import read_geometries

    path, *options = source.split("|")
    _, geoms = read_geometries("|".join([str(mixed_gpkg.parent / path), *options]))
    layer = options[0].split("=")[1]
    where = options[1].split("=")[1] if len(options) > 1 else None
    expected = pyogrio.read_dataframe(mixed_gpkg, layer=layer, where=where)
    expected = expected.geometry.values if hasattr(expected, "geometry") else [None] * 2
    assert len(geoms) == len(expected)
    assert all(shapely.equals_identical(a, b) or a is b is None
               for a, b in zip(geoms, expected, strict=True))


def test_a_crs_without_code_nor_name_is_labelled_by_its_definition(tmp_path):
    import geopandas as gpd
    from pyproj import CRS
    from shapely.geometry import Point

    wkt = CRS.from_proj4("+proj=tmerc +lon_0=11.5 +k=0.9 +x_0=200000 +ellps=GRS80 +units=m "
                         "+no_defs").to_wkt()
    gpd.GeoDataFrame(geometry=[Point(1, 2)], crs=wkt).to_file(tmp_path / "c.gpkg")
    (layer,) = toolbox.run("vector:info", {"INPUT": tmp_path / "c.gpkg"})["INFO"]["layers"]
    # no code and no name (pyproj's name is "unknown"): shown by the definition it was made from
    assert CRS.from_wkt(wkt).name == "unknown"
    assert layer["crs"].startswith("an unnamed CRS (+proj=tmerc ")
    assert all(term in layer["crs"] for term in ("+lon_0=11.5", "+k=0.9", "+x_0=200000"))


PROBE = """
import atexit, json, sys
out = sys.argv[1]
atexit.register(lambda: open(out, "w").write(json.dumps(sorted(sys.modules))))
sys.argv = ["toolbox", *sys.argv[2:]]
from toolbox.cli import console
sys.exit(console())
"""


def test_points_described_without_pandas_or_pyproj(tmp_path):
    """Also with a table beside them (every GeoPackage the toolbox writes has ``layer_styles``):
    a table read through GeoDataFrames cost pandas and geopandas (0.98 s instead of 0.50 s wall:
    bench/results/startup.md)."""
    import geopandas as gpd
    import pandas as pd
    import pyogrio
    import shapely

    rng = np.random.default_rng(3)
    x, y, z = rng.uniform(0, 100, 500), rng.uniform(0, 50, 500), rng.uniform(10, 20, 500)
    gpd.GeoDataFrame({"z": z}, geometry=shapely.points(x, y, z), crs="EPSG:3003").to_file(
        tmp_path / "pts.gpkg", layer="pts")
    pyogrio.write_dataframe(pd.DataFrame({"styleName": ["a", "b", "c"]}), tmp_path / "pts.gpkg",
                            layer="layer_styles")
    modules = tmp_path / "modules.json"
    proc = subprocess.run([sys.executable, "-c", PROBE, modules, "run", "vector:info", "--INPUT",
                           tmp_path / "pts.gpkg"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    layer, table = json.loads(proc.stdout)["INFO"]["layers"]
    assert (table["name"], table["features"], table["geometry_types"]) == ("layer_styles", 3, [])
    assert layer["features"] == 500 and layer["geometry_types"] == ["Point"]
    assert layer["bounds"] == [x.min(), y.min(), x.max(), y.max()]
    assert layer["z_range"] == [z.min(), z.max()] and layer["crs"] == "EPSG:3003"
    heavy = {"pandas", "geopandas", "pyarrow", "pyproj"} & set(json.loads(modules.read_text()))
    assert not heavy


def test_nan_coordinates_refused(tmp_path):
    import geopandas as gpd
    from shapely.geometry import Point

    gpd.GeoDataFrame(geometry=[Point(1, 2), Point(np.nan, 4)], crs="EPSG:3003").to_file(
        tmp_path / "nan.gpkg")
    with pytest.raises(toolbox.InputDataError, match=r"INPUT .*1 feature\(s\) have NaN/inf "
                                                     r"coordinates \(row 2, counting from 1\)"):
        toolbox.run("vector:info", {"INPUT": tmp_path / "nan.gpkg"})

