"""Round 18, leftovers8: small leftovers of this round's helpers."""

from __future__ import annotations

import logging

import geopandas as gpd
import pytest
import shapely

X0, Y0 = 1_700_000.0, 4_800_000.0  # EPSG:3003


def _square_lines(tmp_path):
    ring = [(X0, Y0), (X0 + 10, Y0), (X0 + 10, Y0 + 10), (X0, Y0 + 10), (X0, Y0)]
    path = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"code": ["A"]}, geometry=[shapely.LineString(ring)],
                     crs="EPSG:3003").to_file(path)
    return path


# -- 1. |layername= finds every layer of a multi-layer output written in a one-layer format ------
@pytest.mark.parametrize("ext", [".shp", ".geojson", ".fgb", ".parquet"])
def test_layername_finds_first_and_sibling_layers_through_a_pipeline(tmp_path, ext, caplog):
    from toolbox.batch import load_pipeline, run_pipeline

    lines = _square_lines(tmp_path)
    pipe = tmp_path / "p.yaml"
    pipe.write_text(  # topology:build_areas writes areas (first), arcs, nodes, errors_*
        "steps:\n"
        f"  - {{name: areas, algorithm: topology:build_areas, params: {{INPUT: {lines}, "
        f"OUTPUT: a{ext}}}}}\n"
        "  - {name: first, algorithm: vector:info, params: "
        "{INPUT: '${areas.OUTPUT}|layername=areas'}}\n"
        "  - {name: other, algorithm: vector:info, params: "
        "{INPUT: '${areas.OUTPUT}|layername=arcs'}}\n")
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        results = run_pipeline(load_pipeline(pipe))
    text = str(results)
    assert f"a{ext}" in text and f"a_arcs{ext}" in text
    # the truth: the files themselves (1 polygon in a.ext, 1 arc in a_arcs.ext)
    areas = gpd.read_parquet(tmp_path / f"a{ext}") if ext == ".parquet" else \
        gpd.read_file(tmp_path / f"a{ext}")
    assert list(areas.geom_type) == ["Polygon"]
    assert shapely.area(areas.geometry.iloc[0]) == pytest.approx(100.0)


@pytest.mark.parametrize("ext", [".shp", ".parquet"])
def test_first_layer_of_a_set_is_read_by_name_with_a_warning(tmp_path, ext, caplog):
    import toolbox
    from toolbox.io.vector import open_layer, read_vector

    lines = _square_lines(tmp_path)
    toolbox.run("topology:build_areas", {"INPUT": str(lines), "OUTPUT": str(tmp_path / f"a{ext}")})
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        ref = open_layer(f"{tmp_path / f'a{ext}'}|layername=areas")
        frame = read_vector(ref)
    assert ref.path == tmp_path / f"a{ext}"
    assert list(frame.geom_type) == ["Polygon"]
    assert shapely.area(frame.geometry.iloc[0]) == pytest.approx(100.0)
    assert "layer 'areas' read from" in caplog.text and "arcs" in caplog.text


def test_layername_of_a_lone_shapefile_is_still_refused(tmp_path):
    from toolbox.errors import ParameterError
    from toolbox.io.vector import open_layer

    path = tmp_path / "lone.shp"
    gpd.GeoDataFrame({"v": [1]}, geometry=[shapely.Point(X0, Y0)], crs="EPSG:3003").to_file(path)
    with pytest.raises(ParameterError, match="layer 'areas' is not in"):
        open_layer(f"{path}|layername=areas")


# -- 3. an empty GeoJSON layer keeps no fields nor geometry type: one warning names it ----------
def test_empty_geojson_layers_are_named_in_one_warning(tmp_path, caplog):
    import json

    import numpy as np
    import pyogrio

    from toolbox.io.vector_write import write_layers, write_wkb_layer

    full = gpd.GeoDataFrame({"code": ["A"]}, geometry=[shapely.Point(X0, Y0)], crs="EPSG:3003")
    layers = {"pts": full, "none": full.iloc[:0], "nothing": full.iloc[:0]}
    types = {"none": "Point", "nothing": "Point"}
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        write_layers(tmp_path / "a.geojson", layers, geometry_types=types)
        write_layers(tmp_path / "a.gpkg", layers, geometry_types=types)  # keeps them: silent
        write_wkb_layer(tmp_path / "w.geojson", "c", np.empty(0, dtype=object),
                        {"v": np.empty(0)}, "LineString Z", None)
    # what GDAL wrote: an empty FeatureCollection, no fields, no geometry type
    assert json.loads((tmp_path / "a_none.geojson").read_text())["features"] == []
    info = pyogrio.read_info(tmp_path / "a_none.geojson")
    assert list(info["fields"]) == [] and info["geometry_type"] == "Unknown"
    assert pyogrio.read_info(tmp_path / "a.gpkg", layer="none")["geometry_type"] == "Point"
    found = [r.getMessage() for r in caplog.records if "empty GeoJSON" in r.getMessage()]
    assert len(found) == 2
    assert found[0].startswith("a_none.geojson, a_nothing.geojson: no features")
    assert ".gpkg" in found[0] and found[1].startswith("w.geojson: no features")
