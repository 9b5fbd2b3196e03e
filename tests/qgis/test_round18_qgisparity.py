"""The QGIS provider against the CLI (round 18): each test runs a short PyQGIS script in
Debian's QGIS Python (skipped when QGIS is absent, as the other QGIS tests)."""

from __future__ import annotations

from pathlib import Path

from test_qgis_provider import needs_qgis
from test_round15_sweep_qgis import plugin_values, pyqgis


def _lines(path: Path) -> None:
    import geopandas as gpd
    from shapely.geometry import LineString

    gpd.GeoDataFrame({"elev": [10.0]}, geometry=[LineString([(1_680_010, 4_800_010),
                                                             (1_680_090, 4_800_090)])],
                     crs="EPSG:3003").to_file(path, driver="GPKG")


@needs_qgis
def test_a_second_grid_crs_is_not_taken_for_the_extent_crs(tmp_path):
    """carto:sheet with GRID_CRS (a second CRS ticked along the frame) and no CRS: the plugin
    took GRID_CRS for the data's CRS and sent the extent reprojected into it, so the sheet was
    refused ('no input meets the sheets', exit 2) where the CLI with the same values draws it.
    The extent stays in the data's CRS (the layer's, or the CRS parameter's)."""
    gpkg = tmp_path / "lines.gpkg"
    _lines(gpkg)
    params = [{"name": "EXTENT", "type": "extent"}, {"name": "CONTOURS", "type": "vector"},
              {"name": "CRS", "type": "crs"}, {"name": "GRID_CRS", "type": "crs"}]
    drawn = "1680000,1680100,4800000,4800100 [EPSG:3003]"  # QGIS's order
    got = plugin_values(tmp_path, params, {
        "grid": {"CONTOURS": {"layer": str(gpkg)}, "EXTENT": drawn, "GRID_CRS": "EPSG:6707"},
        "crs": {"CONTOURS": {"layer": str(gpkg)}, "EXTENT": drawn, "GRID_CRS": "EPSG:4326",
                "CRS": "EPSG:3003"}})
    for label in ("grid", "crs"):
        assert got[label]["EXTENT"] == "1680000.0,4800000.0,1680100.0,4800100.0 [EPSG:3003]"


DIALOG_DEFAULTS = """
from qgis.gui import QgsProcessingLayerOutputDestinationWidget
out = {}
for spec in SPECS:
    alg = ToolboxAlgorithm(spec, "tb")
    alg.initAlgorithm()
    for p in spec["parameters"]:
        widget = QgsProcessingLayerOutputDestinationWidget(alg.parameterDefinition(p["name"]),
                                                           False)
        out[spec["id"] + " " + p["name"]] = "skipped" if widget.outputIsSkipped() else \\
            str(widget.value()).split("'sink':")[-1].split(",")[0]
done(out)
"""


@needs_qgis
def test_the_dialog_writes_an_optional_output_only_when_asked(tmp_path):
    """QGIS's dialog created every optional output as a temporary file (createByDefault), so
    ortho:photo run with its defaults was refused ('OCCLUSION_MASK: needs OCCLUSION=true',
    exit 2) and other algorithms computed and loaded rasters nobody asked for (dem:ground's
    ground points, the incidence raster...). As the CLI: only the outputs asked for; when every
    output is optional (carto:sheet) the first one is still created."""
    ortho = {"id": "ortho:photo", "parameters": [
        {"name": "OUTPUT", "type": "output_raster"},
        {"name": "OCCLUSION_MASK", "type": "output_raster", "optional": True},
        {"name": "REPORT", "type": "output_file", "optional": True, "extensions": [".json"]},
        {"name": "POINTS", "type": "output_vector", "optional": True},
        {"name": "CHIPS", "type": "output_folder", "optional": True}]}
    sheet = {"id": "carto:sheet", "parameters": [
        {"name": "OUTPUT", "type": "output_file", "optional": True, "extensions": [".pdf"]},
        {"name": "PNG", "type": "output_file", "optional": True, "extensions": [".png"]},
        {"name": "FOLDER", "type": "output_folder", "optional": True}]}
    got = pyqgis(tmp_path, f"SPECS = {[ortho, sheet]!r}\n" + DIALOG_DEFAULTS)
    assert got == {"ortho:photo OUTPUT": "TEMPORARY_OUTPUT",
                   "ortho:photo OCCLUSION_MASK": "skipped", "ortho:photo REPORT": "skipped",
                   "ortho:photo POINTS": "skipped", "ortho:photo CHIPS": "skipped",
                   "carto:sheet OUTPUT": "TEMPORARY_OUTPUT", "carto:sheet PNG": "skipped",
                   "carto:sheet FOLDER": "skipped"}


@needs_qgis
def test_project_layers_given_to_a_multiple_files_input_reach_the_toolbox(tmp_path):
    """carto:sheet's LAYERS (several vector files) given project layers, as a model or the
    Python console does: a layer object became '' (the sheet was drawn without it, exit 0) and
    a layer id was refused as a missing file (exit 2). Each now reaches the toolbox as its file
    (a memory layer as a copy); a path stays as given."""
    gpkg = tmp_path / "lines.gpkg"
    _lines(gpkg)
    got = pyqgis(tmp_path, f"""
        alg = ToolboxAlgorithm({{"id": "carto:sheet", "parameters": [
            {{"name": "LAYERS", "type": "multiple", "optional": True}}]}}, "tb")
        alg.initAlgorithm()
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        layer = QgsVectorLayer({str(gpkg)!r}, "lines", "ogr")
        memory = layer.materialize(QgsFeatureRequest())
        QgsProject.instance().addMapLayers([layer, memory])
        spec = alg.spec["parameters"][0]
        values = {{}}
        for label, value in (("object", [layer]), ("id", [layer.id()]), ("path", [{str(gpkg)!r}]),
                             ("both", [memory.id(), {str(tmp_path / "restitution.dxf")!r}])):
            values[label] = alg._value(spec, {{"LAYERS": value}}, context,
                                       QgsProcessingFeedback())
        copy = QgsVectorLayer(values["both"][0], "copy", "ogr")
        values["copy"] = [copy.isValid(), copy.featureCount(), copy.crs().authid()]
        done(values)
        """)
    for label in ("object", "id", "path"):
        assert got[label] == [str(gpkg)], label
    assert got["both"][0] != "" and got["both"][1] == str(tmp_path / "restitution.dxf")
    assert got["copy"] == [True, 1, "EPSG:3003"]


@needs_qgis
def test_a_crs_qgis_cannot_read_reaches_the_toolbox_as_typed(tmp_path):
    """CRS='EPSG:999999' (a typo) from processing.run or qgis_process: QGIS reads it as an
    invalid CRS and the plugin left the parameter out, so the run went on with the inputs' CRS
    (exit 0) where the CLI refuses it (exit 2, 'CRS ... is not a CRS PROJ knows'). It now goes
    as typed, for the toolbox to refuse; a CRS QGIS reads goes as its authority id."""
    got = plugin_values(tmp_path, [{"name": "CRS", "type": "crs", "optional": True}], {
        "typo": {"CRS": " EPSG:999999 "}, "ok": {"CRS": "EPSG:3003"}, "empty": {"CRS": ""}})
    assert got == {"typo": {"CRS": "EPSG:999999"}, "ok": {"CRS": "EPSG:3003"},
                   "empty": {"CRS": None}}


@needs_qgis
def test_booleans_as_text_and_fractional_integers_reach_the_toolbox_as_given(tmp_path):
    """qgis_process or processing.run with OVERVIEWS=no: QGIS reads any text but '0'/'false'
    as true, so the run had the option on (exit 0) where the CLI reads 'no'/'off' as false;
    NEIGHBOURS=4.5 (a model's number) ran as 5 where the CLI refuses it (exit 2). Both now go
    as given, for the toolbox to read as the CLI does; real booleans and whole numbers as
    before."""
    params = [{"name": "OVERVIEWS", "type": "boolean", "default": True},
              {"name": "NEIGHBOURS", "type": "integer", "default": 12}]
    got = plugin_values(tmp_path, params, {
        "text": {"OVERVIEWS": " no ", "NEIGHBOURS": 4.5},
        "typed": {"OVERVIEWS": False, "NEIGHBOURS": 4.0},
        "qgis_process": {"OVERVIEWS": "false", "NEIGHBOURS": "6"}})
    assert got == {"text": {"OVERVIEWS": "no", "NEIGHBOURS": "4.5"},
                   "typed": {"OVERVIEWS": "false", "NEIGHBOURS": "4"},
                   "qgis_process": {"OVERVIEWS": "false", "NEIGHBOURS": "6"}}


@needs_qgis
def test_an_extent_for_ortho_photo_is_not_converted_into_the_dem_crs(tmp_path):
    """ortho:photo writes the ortho in the project's CRS; its DEM may be in another. An extent
    drawn in the project's CRS (EPSG:3003) was converted into the DEM's (EPSG:6708), then back
    by the toolbox into the ortho's: the bounding box of a bounding box, metres larger than the
    one drawn, so another grid than the CLI's with the same extent (exit 0). It now goes in its
    own CRS, which the toolbox converts once (not at all here)."""
    import numpy as np
    import rasterio
    from pyproj import Transformer
    from rasterio.transform import from_origin

    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=4, height=3, count=1,
                       dtype="float32", crs="EPSG:6708",
                       transform=from_origin(300_000, 4_800_030, 10, 10)) as dst:
        dst.write(np.zeros((3, 4), "float32"), 1)
    with rasterio.open(tmp_path / "photo.png", "w", driver="PNG", width=4, height=3, count=1,
                       dtype="uint8") as dst:
        dst.write(np.zeros((3, 4), "uint8"), 1)
    drawn = (1_680_000.0, 4_800_000.0, 1_681_000.0, 4_801_000.0)  # in the ortho's EPSG:3003
    got = plugin_values(tmp_path, [{"name": "INPUT", "type": "raster", "role": "photo"},
                                   {"name": "DEM", "type": "raster", "role": "heights"},
                                   {"name": "EXTENT", "type": "extent"}], {"ortho": {
        "INPUT": {"layer": str(tmp_path / "photo.png"), "raster": True},
        "DEM": {"layer": str(tmp_path / "dem.tif"), "raster": True},
        "EXTENT": "1680000,1681000,4800000,4801000 [EPSG:3003]"}})
    assert got["ortho"]["EXTENT"] == "1680000.0,4800000.0,1681000.0,4801000.0 [EPSG:3003]"
    # the old round trip through the DEM's CRS, by pyproj: metres wider than drawn
    there = Transformer.from_crs(3003, 6708, always_xy=True).transform_bounds(*drawn, 21)
    back = Transformer.from_crs(6708, 3003, always_xy=True).transform_bounds(*there, 21)
    assert (back[2] - back[0]) - (drawn[2] - drawn[0]) > 10.0


@needs_qgis
def test_an_extent_typed_without_crs_is_not_given_the_project_crs(tmp_path):
    """EXTENT typed as numbers (processing.run, qgis_process, a model) in a QGIS project in
    EPSG:3857 (a basemap's): where the plugin knew no data CRS (dem:match; ortho:photo), it
    tagged the numbers with the project's CRS, so the toolbox converted them from Web Mercator
    (another area, or refused; exit 2 or a wrong grid) where the CLI takes them in the data's
    CRS. Numbers without CRS now go without one; an extent naming its CRS keeps it."""
    got = pyqgis(tmp_path, """
        QgsProject.instance().setCrs(QgsCoordinateReferenceSystem("EPSG:3857"))
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        spec = {"id": "dem:match", "parameters": [{"name": "EXTENT", "type": "extent"}]}
        alg = ToolboxAlgorithm(spec, "tb")
        alg.initAlgorithm()
        out = {}
        for label, value in (("text", "1680000,1680100,4800000,4800100"),
                             ("rectangle", QgsRectangle(1680000, 4800000, 1680100, 4800100)),
                             ("named", "1680000,1680100,4800000,4800100 [EPSG:3003]")):
            out[label] = alg._value(spec["parameters"][0], {"EXTENT": value}, context,
                                    QgsProcessingFeedback())
        done(out)
        """)
    assert got == {"text": "1680000.0,4800000.0,1680100.0,4800100.0",
                   "rectangle": "1680000.0,4800000.0,1680100.0,4800100.0",
                   "named": "1680000.0,4800000.0,1680100.0,4800100.0 [EPSG:3003]"}


@needs_qgis
def test_an_integer_beyond_32_bits_reaches_the_toolbox(tmp_path):
    """MAX_CELLS=3000000000 from processing.run or a model: QGIS's parameterAsInt is 32-bit and
    gave 0, refused as 'MAX_CELLS must be >= 1, got 0' (exit 2; the CLI takes 3e9). Whole
    numbers now go as they are."""
    got = plugin_values(tmp_path, [{"name": "MAX_CELLS", "type": "integer", "optional": True}],
                        {"int": {"MAX_CELLS": 3_000_000_000}, "float": {"MAX_CELLS": 3e9},
                         "small": {"MAX_CELLS": 7}})
    assert got == {"int": {"MAX_CELLS": "3000000000"}, "float": {"MAX_CELLS": "3000000000"},
                   "small": {"MAX_CELLS": "7"}}


@needs_qgis
def test_a_las_file_reaches_a_point_input_that_reads_point_clouds(tmp_path):
    """dem:idw INPUT=points.las from processing.run or qgis_process (the CLI grids it): QGIS
    cannot open LAS as a vector layer and refused it as 'Could not load source layer for INPUT:
    ... not found' although the file is there. The file now goes to the toolbox as given; a
    parameter without point clouds, or a missing file, is checked by QGIS as before."""
    import laspy
    import numpy as np

    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = [0.01, 0.01, 0.01]
    cloud = laspy.LasData(header)
    cloud.x, cloud.y, cloud.z = np.arange(5.0), np.arange(5.0), np.ones(5)
    cloud.write(tmp_path / "points.las")
    got = pyqgis(tmp_path, f"""
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        out = {{}}
        for clouds in (True, False):
            spec = {{"id": "dem:idw", "parameters": [{{"name": "INPUT", "type": "vector",
                     "optional": True, "point_clouds": clouds}}]}}
            alg = ToolboxAlgorithm(spec, "tb")
            alg.initAlgorithm()
            for label, path in (("las", {str(tmp_path / "points.las")!r}),
                                ("missing", {str(tmp_path / "missing.las")!r})):
                ok, message = alg.checkParameterValues({{"INPUT": path}}, context)
                out[f"{{clouds}} {{label}}"] = [ok, alg._value(spec["parameters"][0],
                                                {{"INPUT": path}}, context,
                                                QgsProcessingFeedback()) if ok else message]
        done(out)
        """)
    assert got["True las"] == [True, str(tmp_path / "points.las")]
    for label in ("True missing", "False las", "False missing"):
        assert got[label][0] is False and "INPUT" in got[label][1], label


@needs_qgis
def test_a_list_given_to_a_text_parameter_is_not_dropped(tmp_path):
    """dem:idw CLASSES=[2] (ground only) from processing.run: QGIS's text of a list is '', so
    the parameter was left out and every class was gridded (exit 0; buildings at 30 m in a
    ground DEM at 10 m). A list now goes as the comma-separated text the CLI takes ('2,9')."""
    got = plugin_values(tmp_path, [{"name": "CLASSES", "type": "string", "optional": True}],
                        {"list": {"CLASSES": [2, 9]}, "one": {"CLASSES": (2,)},
                         "text": {"CLASSES": "2,9"}})
    assert got == {"list": {"CLASSES": "2,9"}, "one": {"CLASSES": "2"},
                   "text": {"CLASSES": "2,9"}}


@needs_qgis
def test_a_crs_defined_in_qgis_reaches_the_toolbox_as_wkt(tmp_path):
    """A CRS from QGIS's Custom Projections (a local Transverse Mercator with its own datum
    shift) is 'USER:100000', which only that QGIS profile knows: the toolbox refused it
    ('is not a CRS PROJ knows', exit 2), as a CRS parameter and as an extent's CRS. It now goes
    as its WKT, which PROJ reads as the same CRS."""
    from pyproj import CRS

    local = ("+proj=tmerc +lat_0=0 +lon_0=11.33 +k=1 +x_0=50000 +y_0=-4700000 +ellps=intl "
             "+towgs84=-104.1,-49.1,-9.9,0.971,-2.917,0.714,-11.68 +units=m +no_defs")
    got = pyqgis(tmp_path, f"""
        registry = QgsApplication.coordinateReferenceSystemRegistry()
        srsid = registry.addUserCrs(QgsCoordinateReferenceSystem.fromProj({local!r}), "local")
        user = QgsCoordinateReferenceSystem(f"USER:{{srsid}}")
        spec = {{"id": "dem:idw", "parameters": [{{"name": "CRS", "type": "crs"}},
                                                 {{"name": "EXTENT", "type": "extent"}}]}}
        alg = ToolboxAlgorithm(spec, "tb")
        alg.initAlgorithm()
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        rect = QgsReferencedRectangle(QgsRectangle(0, 0, 10, 20), user)
        done([user.authid()] + [alg._value(p, {{"CRS": user, "EXTENT": rect}}, context,
                                           QgsProcessingFeedback()) for p in spec["parameters"]])
        """)
    authid, crs, extent = got
    assert authid.startswith("USER:")
    assert CRS.from_user_input(crs).equals(CRS.from_proj4(local), ignore_axis_order=True)
    numbers, bracketed = extent.split(" ", 1)
    assert numbers == "0.0,0.0,10.0,20.0" and bracketed == f"[{crs}]"


@needs_qgis
def test_a_custom_crs_set_on_a_raster_layer_reaches_the_toolbox(tmp_path):
    """A grid without CRS labelled in Layer Properties with a Custom Projections CRS: the VRT
    the plugin writes with the layer's CRS was asked for 'USER:100000', which GDAL cannot read
    (the run failed); it is now written with the CRS's WKT."""
    import numpy as np
    import rasterio
    from pyproj import CRS
    from rasterio.transform import from_origin

    with rasterio.open(tmp_path / "grid.tif", "w", driver="GTiff", width=4, height=3, count=1,
                       dtype="float32", transform=from_origin(0, 30, 10, 10)) as dst:
        dst.write(np.zeros((3, 4), "float32"), 1)
    local = ("+proj=tmerc +lat_0=0 +lon_0=11.33 +k=1 +x_0=50000 +y_0=-4700000 +ellps=intl "
             "+towgs84=-104.1,-49.1,-9.9,0.971,-2.917,0.714,-11.68 +units=m +no_defs")
    got = pyqgis(tmp_path, f"""
        from photogrammetry_toolbox.algorithm import raster_source
        registry = QgsApplication.coordinateReferenceSystemRegistry()
        srsid = registry.addUserCrs(QgsCoordinateReferenceSystem.fromProj({local!r}), "local")
        layer = QgsRasterLayer({str(tmp_path / "grid.tif")!r}, "grid")
        layer.setCrs(QgsCoordinateReferenceSystem(f"USER:{{srsid}}"))
        try:
            done(raster_source(layer, "DEM"))
        except Exception as exc:
            done("error: " + str(exc))
        """)
    assert got.endswith(".vrt"), got
    with rasterio.open(got) as src:
        assert CRS.from_wkt(src.crs.to_wkt()).equals(CRS.from_proj4(local),
                                                     ignore_axis_order=True)
