"""Round 18, leftovers8: small leftovers of this round's helpers."""

from __future__ import annotations

import logging

import geopandas as gpd
import numpy as np
import pytest
import shapely

X0, Y0 = 1_700_000.0, 4_800_000.0  # EPSG:3003


def _square_lines(tmp_path):
    ring = [(X0, Y0), (X0 + 10, Y0), (X0 + 10, Y0 + 10), (X0, Y0 + 10), (X0, Y0)]
    path = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"code": ["A"]}, geometry=[shapely.LineString(ring)],
                     crs="EPSG:3003").to_file(path)
    return path


# -- 1. |layername= of a multi-layer output written in a one-layer format --------------------
# GeoJSON and FlatGeobuf record their layer's name: every layer is found by name. Shapefile and
# GeoParquet do not: the siblings are found by name, and a name for the first file is refused
# with what to give instead (a misspelt name would otherwise read the first layer).
@pytest.mark.parametrize("ext", [".geojson", ".fgb"])
def test_layername_finds_first_and_sibling_layers_through_a_pipeline(tmp_path, ext):
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
    results = run_pipeline(load_pipeline(pipe))
    text = str(results)
    assert f"a{ext}" in text and f"a_arcs{ext}" in text
    # the truth: the files themselves (1 polygon in a.ext)
    areas = gpd.read_file(tmp_path / f"a{ext}")
    assert list(areas.geom_type) == ["Polygon"]
    assert shapely.area(areas.geometry.iloc[0]) == pytest.approx(100.0)


@pytest.mark.parametrize("ext", [".shp", ".parquet"])
def test_first_layer_of_a_set_by_name_is_refused_saying_what_to_give(tmp_path, ext):
    import toolbox
    from toolbox.errors import ParameterError
    from toolbox.io.vector import open_layer, read_vector

    lines = _square_lines(tmp_path)
    toolbox.run("topology:build_areas", {"INPUT": str(lines), "OUTPUT": str(tmp_path / f"a{ext}")})
    for name in ("areas", "areaz"):  # the right name and a misspelt one: neither can be checked
        with pytest.raises(ParameterError, match=f"give 'a{ext}' without \\|layername= for "
                                                 "the first layer"):
            open_layer(f"{tmp_path / f'a{ext}'}|layername={name}")
    ref = open_layer(f"{tmp_path / f'a{ext}'}|layername=arcs")  # a sibling: found by name
    assert ref.path == tmp_path / f"a_arcs{ext}"
    frame = read_vector(open_layer(str(tmp_path / f"a{ext}")))
    assert list(frame.geom_type) == ["Polygon"]
    assert shapely.area(frame.geometry.iloc[0]) == pytest.approx(100.0)


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


# -- 4. a DEM's peak exactly at a level: the isoline is a point, no zero-length "ring" ----------
def _cone(path, n=21, west=1_700_000.3, north=4_800_021.7):
    """z = 100 - 0.5 r (r in cells from the centre cell): the contour at level L is the circle
    of radius 2 (100 - L) cells, the one at 100 the peak's single point."""
    import rasterio
    from rasterio.transform import from_origin

    yy, xx = np.mgrid[0:n, 0:n]
    z = 100.0 - 0.5 * np.hypot(xx - n // 2, yy - n // 2)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs="EPSG:3003", transform=from_origin(west, north, 1, 1)) as dst:
        dst.write(z.astype("float32"), 1)
    return path


@pytest.mark.parametrize(("tracer", "interval"), [("contourpy", 1.0), ("kernel", 0.25)])
def test_peak_exactly_at_a_level_writes_no_degenerate_ring(tmp_path, monkeypatch, tracer,
                                                           interval):
    import pyogrio

    import toolbox
    from toolbox.cartography import contour_io

    monkeypatch.setattr(contour_io, "choose_tracer", lambda *args: tracer)

    out = tmp_path / "c.gpkg"
    stats = toolbox.run("carto:contours", {"INPUT": str(_cone(tmp_path / "cone.tif")),
                                           "INTERVAL": interval, "OUTPUT": str(out)})["STATISTICS"]
    frame = pyogrio.read_dataframe(out, layer="contours")
    assert frame.geometry.is_valid.all()
    assert 100.0 not in set(frame["elev"])  # the peak: a point, not a line
    assert stats["points_dropped"] == 1 and stats["lines"] == len(frame)
    assert stats["tracer"] == tracer
    # the other levels: all there; from 2 cells out, rings of about 2 pi (100 - L) * 2 cells
    # (the bilinear surface of a cone: within 6 %; nearer the peak, diamonds)
    levels = np.arange(100 - interval, 95, -interval)
    assert set(levels) <= set(frame["elev"])
    for level in levels[levels <= 99]:
        length = frame.loc[frame["elev"] == level, "length"].sum()
        assert length == pytest.approx(4 * np.pi * (100 - level), rel=0.06), level
    assert (frame["length"] > 0.01).all()


def test_dropping_points_keeps_the_canonical_order():
    from toolbox.cartography.contour_io import contour_columns
    from toolbox.cartography.contours import Contour

    ring = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 0.0]])
    point = np.repeat([[0.5, 0.5]], 5, axis=0)
    contours = [Contour(2.0, ring + 5), Contour(1.0, point), Contour(1.0, ring),
                Contour(2.0, point + 1e-10 * np.arange(5)[:, None])]
    wkb, fields = contour_columns(contours, 1.0, 0.0, 5, min_length=1e-6)
    assert fields["elev"].tolist() == [1.0, 2.0] and len(wkb) == 2
    assert fields["length"].tolist() == pytest.approx([2 + 2**0.5] * 2)
    assert [shapely.get_coordinates(shapely.from_wkb(w))[0].tolist() for w in wkb] == \
        [[0.0, 0.0], [5.0, 5.0]]


# -- 2. GDAL's own "Warning 6: Normalized/laundered field name" off pyogrio's importing thread ---
def test_shapefile_writes_off_the_importing_thread_print_no_raw_gdal_warning(tmp_path, capfd,
                                                                            caplog):
    import threading

    from toolbox.io.vector import _ogr
    from toolbox.io.vector_write import write_layers, write_wkb_layer

    _ogr()  # pyogrio imported on this (the main) thread, as in a batch
    frame = gpd.GeoDataFrame({"description_long": [1.0]}, geometry=[shapely.Point(X0, Y0)],
                             crs="EPSG:3003")
    errors = []

    def work():  # a batch step's thread: pyogrio was imported (its handler pushed) elsewhere
        try:
            write_layers(tmp_path / "a.shp", {"a": frame})
            write_wkb_layer(tmp_path / "b.shp", "b", shapely.to_wkb(frame.geometry.values),
                            {"displacement_long": np.array([1.0])}, "Point")
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    capfd.readouterr()
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        t = threading.Thread(target=work)
        t.start()
        t.join()
    assert not errors
    assert "Warning 6" not in capfd.readouterr().err  # GDAL's raw line (fd 2)
    renamed = [r.getMessage() for r in caplog.records if "10 characters" in r.getMessage()]
    assert len(renamed) == 2 and "description_long -> descriptio" in renamed[0]
    assert gpd.read_file(tmp_path / "a.shp").columns[0] == "descriptio"  # what GDAL wrote
