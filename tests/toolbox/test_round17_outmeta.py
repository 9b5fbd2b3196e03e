"""Round 17, what outputs say about themselves:

- mosaic:cut of a raster dropped what its values mean: a scaled Int16 DEM (heights = code x 0.01
  + 100, GDAL's scale/offset) came out as bare codes (1220 read as metres where the source says
  112.2 m, exit 0), a DEM in feet lost its unit type (so dem:slope then read its sheets as metres
  in silence, where it refuses the source), a classified raster kept ColorInterp=Palette without
  its colour table, band descriptions and dataset metadata were gone; now copied
  (:func:`toolbox.raster.writer.copy_band_metadata`);
- dem:slope and dem:aspect wrote a band with neither description nor unit type: a slope in
  percent could not be told from one in degrees; now "slope (degrees)"/"degree",
  "slope (percent)"/"percent", "aspect (...)"/"degree";
- mosaic:build's SOURCE_INDEX did not say which ortho each number is; ortho:photo's INCIDENCE
  and OCCLUSION_MASK had no description, unit nor photo id;
- the ortho of an RGB + near-infrared photo came out as gray, undefined, undefined, undefined
  (+ alpha) with its band names gone: QGIS showed band 1 as grey, nothing said which band is
  the NIR; now each band keeps its colour interpretation, description and unit
  (:func:`toolbox.raster.writer.copy_band_names`, for every warp and MODE=gcps copy).
"""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
import shapely
from rasterio.transform import from_origin

import toolbox
from toolbox.mosaic.sheets import clip_raster


def _raster(path, data, dtype, nodata, **band):
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[1], height=data.shape[0],
                       count=1, dtype=dtype, crs="EPSG:32633", nodata=nodata,
                       transform=from_origin(600000, 4800000, 5, 5)) as dst:
        dst.write(data.astype(dtype), 1)
        if "scale" in band:
            dst.scales, dst.offsets = (band["scale"],), (band["offset"],)
        if "unit" in band:
            dst.set_band_unit(1, band["unit"])
        if "description" in band:
            dst.set_band_description(1, band["description"])
        if "colormap" in band:
            dst.write_colormap(1, band["colormap"])
        dst.update_tags(SOURCE="survey 2024")
    return path


SHEET = shapely.box(600050, 4799850, 600150, 4799950)  # cells 10..29 x 10..29


def test_cut_keeps_scale_offset_unit_description(tmp_path):
    codes = np.arange(1600).reshape(40, 40)
    src = _raster(tmp_path / "scaled.tif", codes, "int16", -32768, scale=0.01, offset=100.0,
                  unit="ft", description="height above EGM2008")
    assert clip_raster(src, SHEET, tmp_path / "sheet.tif")
    with rasterio.open(tmp_path / "sheet.tif") as out:
        heights = out.read(1) * out.scales[0] + out.offsets[0]
        assert out.units[0] == "ft"
        assert out.descriptions[0] == "height above EGM2008"
        assert out.tags()["SOURCE"] == "survey 2024"
        assert out.transform.c == 600050 and out.transform.f == 4799950
    # truth: the source's heights of the same cells (code x scale + offset)
    assert heights == pytest.approx(codes[10:30, 10:30] * 0.01 + 100.0)


def test_cut_keeps_colour_table(tmp_path):
    table = {0: (255, 0, 0, 255), 1: (0, 255, 0, 255), 2: (0, 0, 255, 255)}
    src = _raster(tmp_path / "classes.tif", np.arange(1600).reshape(40, 40) % 3, "uint8", 255,
                  colormap=table)
    assert clip_raster(src, SHEET, tmp_path / "sheet.tif")
    with rasterio.open(tmp_path / "sheet.tif") as out:
        colours = out.colormap(1)  # ValueError before: no colour table
    assert {k: colours[k] for k in table} == table


@pytest.mark.parametrize(("alg", "extra", "unit", "word"), [
    ("dem:slope", {}, "degree", "degrees"),
    ("dem:slope", {"UNITS": "percent"}, "percent", "percent"),
    ("dem:aspect", {}, "degree", "aspect")])
def test_slope_and_aspect_state_their_unit(tmp_path, alg, extra, unit, word):
    y, x = np.mgrid[0:20, 0:20]
    dem = _raster(tmp_path / "dem.tif", 100 + 5.0 * x + 2.0 * y, "float32", -9999)
    out = toolbox.run(alg, {"INPUT": dem, "OUTPUT": tmp_path / "o.tif", **extra})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert ds.units[0] == unit
        assert word in ds.descriptions[0]


def _rgb(path, x0):
    rng = np.random.default_rng(int(x0) % 97)
    with rasterio.open(path, "w", driver="GTiff", width=40, height=40, count=3, dtype="uint8",
                       crs="EPSG:32633", nodata=0,
                       transform=from_origin(x0, 4800000, 1, 1)) as dst:
        dst.write(rng.integers(1, 255, (3, 40, 40), dtype="uint8"))
    return path


def test_mosaic_source_index_names_its_numbers(tmp_path):
    """The source index held 1, 2... with nothing saying which ortho is which number; now the
    tags SOURCE_1, SOURCE_2... name the inputs (in the order given) and the band says what it
    holds."""
    a, b = _rgb(tmp_path / "west.tif", 600000), _rgb(tmp_path / "east.tif", 600020)
    out = toolbox.run("mosaic:build", {"INPUT": [str(a), str(b)], "OUTPUT": tmp_path / "m.tif",
                                       "SOURCE_INDEX": tmp_path / "src.tif"})
    with rasterio.open(out["SOURCE_INDEX"]) as ds:
        index, tags = ds.read(1), ds.tags()
        assert "source" in ds.descriptions[0]
    assert tags["SOURCE_1"] == str(a) and tags["SOURCE_2"] == str(b)
    assert (index[:, :10] == 1).all() and (index[:, -10:] == 2).all()  # west only / east only


def test_incidence_and_occlusion_rasters_say_what_they_hold(tmp_path):
    sc = _scene(tmp_path, 1)
    toolbox.run("ortho:photo", {"INPUT": sc.photo_path, "PROJECT": sc.project_path,
                                "DEM": sc.dem_path, "CELL_SIZE": 10.0, "OCCLUSION": True,
                                "OCCLUSION_MASK": tmp_path / "occ.tif",
                                "INCIDENCE": tmp_path / "inc.tif", "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "inc.tif") as inc, rasterio.open(tmp_path / "occ.tif") as occ:
        assert inc.units[0] == "degree" and "incidence" in inc.descriptions[0]
        assert "1 hidden" in occ.descriptions[0]
        assert inc.tags()["ORTHO_PHOTO"] == occ.tags()["ORTHO_PHOTO"]


def _scene(tmp_path, bands):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
    import ortho_scene as scene

    (tmp_path / "scene").mkdir()
    return scene.make_scene(tmp_path / "scene", bands=bands)


def test_ortho_of_an_rgbn_photo_keeps_band_names_and_colours(tmp_path):
    from rasterio.enums import ColorInterp as CI

    sc = _scene(tmp_path, 4)
    with rasterio.open(sc.photo_path, "r+") as ds:
        ds.colorinterp = [CI.red, CI.green, CI.blue, CI.undefined]
        for k, name in enumerate(["red", "green", "blue", "nir"], start=1):
            ds.set_band_description(k, name)
    toolbox.run("ortho:photo", {"INPUT": sc.photo_path, "PROJECT": sc.project_path,
                                "DEM": sc.dem_path, "CELL_SIZE": 10.0,
                                "OUTPUT": tmp_path / "o.tif"})
    with rasterio.open(tmp_path / "o.tif") as out:
        assert [c.name for c in out.colorinterp] == ["red", "green", "blue", "undefined",
                                                     "alpha"]
        assert out.descriptions[:4] == ("red", "green", "blue", "nir")


def test_mosaic_of_rgbn_orthos_labels_nir_as_data_not_alpha(tmp_path):
    """Four data bands and a nodata value (RGB + NIR orthos, no alpha): GDAL's default for a
    4-band Byte GeoTIFF made band 4 of the mosaic ColorInterp=Alpha, so QGIS drew the NIR
    values as transparency; now red, green, blue, undefined with the orthos' band names."""
    from rasterio.enums import ColorInterp as CI

    paths = []
    for name, x0 in (("west", 600000), ("east", 600020)):
        path = tmp_path / f"{name}.tif"
        with rasterio.open(path, "w", driver="GTiff", width=40, height=40, count=4,
                           dtype="uint8", crs="EPSG:32633", nodata=0, photometric="RGB",
                           alpha="NO", transform=from_origin(x0, 4800000, 1, 1)) as dst:
            dst.write(np.random.default_rng(x0).integers(1, 255, (4, 40, 40), dtype="uint8"))
            dst.colorinterp = [CI.red, CI.green, CI.blue, CI.undefined]
            for k, band in enumerate(["red", "green", "blue", "nir"], start=1):
                dst.set_band_description(k, band)
        with rasterio.open(path) as src:
            assert src.colorinterp[3] == CI.undefined  # the input is what the test says
        paths.append(str(path))
    out = toolbox.run("mosaic:build", {"INPUT": paths, "OUTPUT": tmp_path / "m.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert [c.name for c in ds.colorinterp] == ["red", "green", "blue", "undefined"]
        assert ds.descriptions == ("red", "green", "blue", "nir")
        assert len(np.unique(ds.read(4))) > 100  # band 4 holds the NIR values


def test_shapefile_text_cut_to_254_bytes_is_named(tmp_path, caplog):
    """A text value over a DBF field's 254 bytes (attribution:apply's ``geometry_wkt`` of a
    long unresolved line) was cut with only GDAL's warning quoting the whole value; now one
    toolbox warning names the field, the count and the GeoPackage remedy."""
    import logging
    import warnings

    import geopandas as gpd
    import pyogrio

    from toolbox.io.vector_write import write_layers

    wkt = "LINESTRING (" + ", ".join(f"{1688300 + k}.125 4799610.375" for k in range(20)) + ")"
    frame = gpd.GeoDataFrame({"geometry_wkt": [wkt, "POINT (1 2)"], "code": ["A", "B"]},
                             geometry=[shapely.Point(0, 0), shapely.Point(1, 1)],
                             crs="EPSG:3003")
    with caplog.at_level(logging.WARNING, logger="toolbox"), \
            warnings.catch_warnings(record=True) as raw:
        warnings.simplefilter("always")
        write_layers(tmp_path / "u.shp", {"unresolved": frame})
    assert not [w for w in raw if "truncated" in str(w.message)]
    messages = [r.getMessage() for r in caplog.records if "254 bytes" in r.getMessage()]
    assert len(messages) == 1 and "geometry_wkt (1)" in messages[0] and ".gpkg" in messages[0]
    back = pyogrio.read_dataframe(tmp_path / "u.shp")
    assert back["geometry_w"][0] == wkt.encode()[:254].decode()  # what the DBF holds


def test_shapefile_style_names_the_fields_as_the_file_holds_them(tmp_path):
    """attribution:apply to a .shp wrote a QML/SLD beside each layer labelling by
    ``description``, a field the DBF holds as ``descriptio``: QGIS drew no label. The styles
    now name the cut fields."""
    import geopandas as gpd
    import pyogrio

    from toolbox.attribution.output import store_style
    from toolbox.io.vector_write import write_layers

    frame = gpd.GeoDataFrame({"code": ["FAB01002"], "description": ["building"],
                              "colour_index": [3]}, geometry=[shapely.Point(0, 0)],
                             crs="EPSG:3003")
    write_layers(tmp_path / "coded.shp", {"FAB01002": frame})
    qml = '<qgis><text-style fieldName="description" isExpression="0"/>' \
          '<renderer attr="colour_index"/><rule filter="&quot;code&quot; = 1"/></qgis>'
    sld = "<sld><ogc:PropertyName>description</ogc:PropertyName></sld>"
    store_style(tmp_path / "coded.shp", ["FAB01002"], "FAB01002", qml, sld,
                fields=["code", "description", "colour_index"])
    held = list(pyogrio.read_info(tmp_path / "coded.shp")["fields"])
    assert held == ["code", "descriptio", "colour_ind"]
    text = (tmp_path / "coded.qml").read_text()
    assert 'fieldName="descriptio"' in text and 'attr="colour_ind"' in text
    assert "&quot;code&quot;" in text
    assert "<ogc:PropertyName>descriptio<" in (tmp_path / "coded.sld").read_text()


def test_json_reports_write_no_nan_or_infinity(tmp_path):
    """The shared JSON writer of the orientation and ortho reports wrote a NaN or infinite
    number as ``NaN``/``Infinity`` (each caller had to remember to replace it): not JSON, a
    strict reader refuses the whole report. Now ``null``."""
    import json

    from toolbox.photogrammetry.tables import write_json

    path = write_json(tmp_path / "r.json", {"sigma0": float("nan"), "std": np.array(
        [1.5, np.inf]), "condition": np.float64(-np.inf), "n": np.int64(3), "ok": [2.0]})

    def strict(token):
        raise ValueError(f"not JSON: {token}")

    doc = json.loads(path.read_text(), parse_constant=strict)
    assert doc == {"sigma0": None, "std": [1.5, None], "condition": None, "n": 3, "ok": [2.0]}


def test_ground_filter_rasters_say_what_they_hold(tmp_path):
    """dem:ground's NONGROUND (classes 0, 1, 255) and HEIGHTS rasters had no description: a
    client could not tell a class mask from heights."""
    y, x = np.mgrid[0:30, 0:30]
    dsm = _raster(tmp_path / "dsm.tif", 100 + 0.1 * x + 0.05 * y, "float32", -9999)
    toolbox.run("dem:ground", {"DSM": dsm, "OUTPUT": tmp_path / "dtm.tif",
                               "NONGROUND": tmp_path / "ng.tif", "HEIGHTS": tmp_path / "h.tif"})
    with rasterio.open(tmp_path / "ng.tif") as ng, rasterio.open(tmp_path / "h.tif") as h:
        assert "non-ground" in ng.descriptions[0] and "255" in ng.descriptions[0]
        assert "above the ground" in h.descriptions[0]


def test_csv_tables_write_no_value_empty(tmp_path):
    """The shared CSV writer wrote a NaN as ``nan`` (and a numpy float32 NaN as ``nan`` too):
    OGR's type detection (QGIS, ogr2ogr -oo AUTODETECT_TYPE=YES) then read the whole column as
    text. Now an empty cell, as None; the column stays Real."""
    import pyogrio

    from toolbox.photogrammetry.tables import write_csv

    path = write_csv(tmp_path / "t.csv", ["id", "v", "w"],
                     [["a", 1.5, np.float32(2.5)], ["b", float("nan"), np.float32("nan")],
                      ["c", None, np.inf]])
    assert path.read_text().splitlines()[1:] == ["a,1.5,2.5", "b,,", "c,,"]
    info = pyogrio.read_info(path, AUTODETECT_TYPE="YES")
    assert dict(zip(info["fields"], info["dtypes"], strict=True))["v"] == "float64"
