"""The QGIS provider with inputs as QGIS gives them (round 15): each test runs a short PyQGIS
script in Debian's QGIS Python (no Processing framework, no toolbox run unless needed)."""

from __future__ import annotations

import json
import os
import subprocess
import textwrap
from pathlib import Path

import pytest
from test_qgis_provider import PLUGIN, SYSTEM_PYTHON, needs_qgis

PREAMBLE = """
import json, os, sys
os.environ["QT_QPA_PLATFORM"] = "offscreen"
sys.path.insert(0, {plugin!r})
from qgis.core import *
app = QgsApplication([], False); app.initQgis()
from photogrammetry_toolbox.algorithm import ToolboxAlgorithm

def done(value):
    print("RESULT " + json.dumps(value), flush=True)
    os._exit(0)
"""


def pyqgis(tmp_path: Path, body: str, timeout: float = 60):
    """Run ``body`` after the preamble in QGIS's Python; what it passed to ``done``."""
    script = tmp_path / "script.py"
    script.write_text(PREAMBLE.format(plugin=str(PLUGIN)) + textwrap.dedent(body))
    done = subprocess.run([SYSTEM_PYTHON, str(script)], capture_output=True, text=True,
                          timeout=timeout, cwd=tmp_path,
                          env=dict(os.environ, HOME=str(tmp_path), QT_QPA_PLATFORM="offscreen"))
    line = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    assert line, done.stdout[-2000:] + done.stderr[-2000:]
    return json.loads(line[0][len("RESULT "):])


@needs_qgis
def test_a_result_larger_than_the_pipe_does_not_hang_the_run(tmp_path):
    """A toolbox printing more than the pipe's 64 KB on stdout (vector:info of a file with many
    layers and fields) used to block for ever: the plugin read stdout only after the exit."""
    fake = tmp_path / "toolbox"
    fake.write_text("#!/bin/sh\n"
                    "head -c 300000 /dev/zero | tr '\\0' 'x'\n"
                    "echo '{\"type\": \"result\", \"outputs\": {\"INFO\": 1}}' >&2\n")
    fake.chmod(0o755)
    try:
        got = pyqgis(tmp_path, f"""
            alg = ToolboxAlgorithm({{"id": "vector:info", "parameters": []}}, "tb")
            result, errors = alg._run([{str(fake)!r}], QgsProcessingFeedback())
            done({{"outputs": result.get("outputs"), "errors": errors}})
            """, timeout=20)
    except subprocess.TimeoutExpired:
        pytest.fail("the run hung on a 300 KB stdout")
    assert got == {"outputs": {"INFO": 1}, "errors": []}


VALUE_SCRIPT = """
spec = {{"id": "dem:nearest", "parameters": {params!r}}}
alg = ToolboxAlgorithm(spec, "tb")
alg.initAlgorithm()
context = QgsProcessingContext(); context.setProject(QgsProject.instance())
feedback = QgsProcessingFeedback()
out = {{}}
for label, params in {cases!r}.items():
    resolved = {{}}
    for key, value in params.items():
        if isinstance(value, dict) and "layer" in value:  # a project layer, maybe with selection
            layer = QgsRasterLayer(value["layer"], label) if value.get("raster") else \
                QgsVectorLayer(value["layer"], label, value.get("provider", "ogr"))
            QgsProject.instance().addMapLayer(layer)
            if value.get("crs"):  # set in Layer Properties > Source
                layer.setCrs(QgsCoordinateReferenceSystem(value["crs"]))
            if value.get("select"):
                layer.selectByExpression(value["select"])
                value = QgsProcessingFeatureSourceDefinition(layer.id(), True)
            else:
                value = layer
        resolved[key] = value
    try:
        out[label] = {{p["name"]: alg._value(p, resolved, context, feedback)
                      for p in spec["parameters"]}}
    except QgsProcessingException as exc:
        out[label] = {{"error": str(exc)}}
done(out)
"""


def plugin_values(tmp_path: Path, params: list[dict], cases: dict) -> dict:
    """The toolbox values the plugin makes of each case's QGIS parameters."""
    return pyqgis(tmp_path, VALUE_SCRIPT.format(params=params, cases=cases))


def _points(path: Path, layer: str, heights: list[float], x0: float = 0.0,
            y0: float = 0.0) -> None:
    import geopandas as gpd
    from shapely.geometry import Point

    gpd.GeoDataFrame({"h": heights}, geometry=[Point(x0 + 10 * i, y0, h) for i, h in
                                               enumerate(heights)], crs="EPSG:3003").to_file(
        path, layer=layer, driver="GPKG")


@needs_qgis
def test_the_layer_and_geometry_type_of_a_qgis_layer_reach_the_toolbox(tmp_path):
    """A GeoPackage layer opened as ``file.gpkg|layerid=1`` (layer b) was read as the file's
    first layer (a): a DEM of the wrong heights, exit 0; a GeoJSON's point sublayer
    (``|geometrytype=Point``) was refused as 'must contain points' (its line went along)."""
    from toolbox.io.vector_points import read_points_xyz

    gpkg = tmp_path / "two layers.gpkg"
    _points(gpkg, "a", [0.0, 1.0, 2.0])
    _points(gpkg, "b", [100.0, 101.0, 102.0])
    mixed = tmp_path / "mixed.geojson"
    features = [{"type": "Feature", "properties": {},
                 "geometry": {"type": "Point", "coordinates": [10.0 * i, 0.0, 5.0 + i]}}
                for i in range(3)]
    features.append({"type": "Feature", "properties": {}, "geometry": {
        "type": "LineString", "coordinates": [[0.0, 5.0, 500.0], [20.0, 5.0, 500.0]]}})
    mixed.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    got = plugin_values(tmp_path, [{"name": "INPUT", "type": "vector"}], {
        "by_id": {"INPUT": {"layer": f"{gpkg}|layerid=1"}},
        "by_name": {"INPUT": {"layer": f"{gpkg}|layername=b"}},
        "points_of_mixed": {"INPUT": {"layer": f"{mixed}|geometrytype=Point"}}})
    for label in ("by_id", "by_name"):
        assert sorted(read_points_xyz(got[label]["INPUT"])[:, 2]) == [100.0, 101.0, 102.0], label
    assert sorted(read_points_xyz(got["points_of_mixed"]["INPUT"])[:, 2]) == [5.0, 6.0, 7.0]


@needs_qgis
def test_an_output_on_the_file_of_a_selected_input_layer_is_refused(tmp_path):
    """'Selected features only' on layer a of data.gpkg, OUTPUT data.gpkg: QGIS handed the
    toolbox a temporary copy, so its 'an input is never overwritten' check could not see it, and
    the user's GeoPackage (layers a and b) was replaced (exit 0). Refused now, nothing run."""
    import pyogrio

    gpkg = tmp_path / "data.gpkg"
    _points(gpkg, "a", [0.0, 1.0, 2.0])
    _points(gpkg, "b", [100.0, 101.0, 102.0])
    fake = tmp_path / "toolbox"  # replaces its OUTPUT, as the toolbox does with --overwrite
    fake.write_text('#!/bin/sh\nwhile [ $# -gt 0 ]; do [ "$1" = --OUTPUT ] && echo x > "$2"; '
                    "shift; done\n")
    fake.chmod(0o755)
    got = pyqgis(tmp_path, f"""
        spec = {{"id": "tin:interpolate", "parameters": [{{"name": "INPUT", "type": "vector"}},
                {{"name": "OUTPUT", "type": "output_vector"}}]}}
        alg = ToolboxAlgorithm(spec, {str(fake)!r})
        alg.initAlgorithm()
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        layer = QgsVectorLayer({str(gpkg) + "|layername=a"!r}, "a", "ogr")
        QgsProject.instance().addMapLayer(layer)
        layer.selectByExpression('"h" < 2')
        params = {{"INPUT": QgsProcessingFeatureSourceDefinition(layer.id(), True),
                   "OUTPUT": {str(gpkg)!r}}}
        try:
            alg.processAlgorithm(params, context, QgsProcessingFeedback())
            done("ran")
        except QgsProcessingException as exc:
            done(str(exc))
        """)
    assert [name for name, _ in pyogrio.list_layers(gpkg)] == ["a", "b"]
    assert got == (f"OUTPUT '{gpkg}' is also the input INPUT; an input is never overwritten: "
                   "choose another output path")


@needs_qgis
def test_numbers_given_as_text_reach_the_toolbox_as_typed(tmp_path):
    """qgis_process REFERENCE_Z=250,5 (a decimal comma): QGIS reads text it cannot parse as the
    default, else 0, and tin:volume measured against the plane z = 0 (exit 0). The text now
    goes to the toolbox as typed (the CLI refuses '250,5' with exit 2); numbers stay numbers."""
    params = [{"name": "REFERENCE_Z", "type": "number", "optional": True},
              {"name": "NEIGHBOURS", "type": "integer", "optional": True, "default": 12}]
    got = plugin_values(tmp_path, params, {
        "comma": {"REFERENCE_Z": "250,5", "NEIGHBOURS": "4,5"},
        "text": {"REFERENCE_Z": " 250.5 ", "NEIGHBOURS": "8"},
        "numbers": {"REFERENCE_Z": 250.5, "NEIGHBOURS": 8},
        "empty": {"REFERENCE_Z": "", "NEIGHBOURS": None}})
    assert got["comma"] == {"REFERENCE_Z": "250,5", "NEIGHBOURS": "4,5"}
    assert got["text"] == {"REFERENCE_Z": "250.5", "NEIGHBOURS": "8"}
    assert got["numbers"] == {"REFERENCE_Z": "250.5", "NEIGHBOURS": "8"}
    assert got["empty"] == {"REFERENCE_Z": None, "NEIGHBOURS": None}


@needs_qgis
def test_an_extent_drawn_in_another_crs_reaches_the_toolbox_in_the_data_crs(tmp_path):
    """'Use map canvas extent' on a canvas in EPSG:3857 (a basemap) for points in EPSG:3003 was
    refused ('reproject the inputs to one CRS first', exit 2: the inputs are in one CRS). It is
    transformed into the layer's CRS (or the CRS parameter's), as QGIS's own algorithms do."""
    from pyproj import Transformer

    gpkg = tmp_path / "points.gpkg"
    _points(gpkg, "points", [1.0, 2.0, 3.0], 1_500_000.0, 5_000_000.0)
    to_web = Transformer.from_crs(3003, 3857, always_xy=True)
    xmin, ymin, xmax, ymax = to_web.transform_bounds(1_500_000, 5_000_000, 1_501_000, 5_001_000)
    drawn = f"{xmin!r},{xmax!r},{ymin!r},{ymax!r} [EPSG:3857]"  # QGIS's order
    params = [{"name": "INPUT", "type": "vector"}, {"name": "CRS", "type": "crs"},
              {"name": "EXTENT", "type": "extent"}]
    got = plugin_values(tmp_path, params, {
        "layer": {"INPUT": {"layer": str(gpkg)}, "EXTENT": drawn},
        "crs": {"INPUT": {"layer": str(gpkg)}, "EXTENT": drawn, "CRS": "EPSG:32632"},
        "same": {"INPUT": {"layer": str(gpkg)}, "EXTENT": "1,3,2,4 [EPSG:3003]"}})
    for label, epsg in (("layer", 3003), ("crs", 32632)):
        numbers, crs = got[label]["EXTENT"].split(" ")
        assert crs == f"[EPSG:{epsg}]"
        truth = Transformer.from_crs(3857, epsg, always_xy=True).transform_bounds(
            xmin, ymin, xmax, ymax, densify_pts=21)
        assert [float(v) for v in numbers.split(",")] == pytest.approx(truth, abs=0.01)
    assert got["same"]["EXTENT"] == "1.0,2.0,3.0,4.0 [EPSG:3003]"
    # ortho:photo: a photo's CRS (here QGIS's EPSG:4326 label of a jpg) is not the data's: the DEM's
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    with rasterio.open(tmp_path / "photo.png", "w", driver="PNG", width=4, height=3, count=1,
                       dtype="uint8") as dst:
        dst.write(np.zeros((3, 4), "uint8"), 1)
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", width=4, height=3, count=1,
                       dtype="float32", crs="EPSG:3003",
                       transform=from_origin(1_500_000, 5_000_030, 10, 10)) as dst:
        dst.write(np.zeros((3, 4), "float32"), 1)
    photo = plugin_values(tmp_path, [{"name": "INPUT", "type": "raster", "role": "photo"},
                                     {"name": "DEM", "type": "raster", "role": "heights"},
                                     {"name": "EXTENT", "type": "extent"}], {"ortho": {
        "INPUT": {"layer": str(tmp_path / "photo.png"), "raster": True, "crs": "EPSG:4326"},
        "DEM": {"layer": str(tmp_path / "dem.tif"), "raster": True}, "EXTENT": drawn}})
    # nor is the DEM's (round 18: the ortho's CRS is the project's): the extent goes in its own
    # CRS and the toolbox takes its bounding box in the ortho's CRS
    assert photo["ortho"]["EXTENT"] == f"{xmin!r},{ymin!r},{xmax!r},{ymax!r} [EPSG:3857]"


@needs_qgis
def test_a_crs_set_on_the_layer_in_qgis_reaches_the_toolbox(tmp_path):
    """A Shapefile without .prj (or with a wrong one), its CRS set in QGIS's layer properties:
    the toolbox read the file, so the DEM had no CRS (exit 0) or the data were refused as lying
    outside the .prj's area of use ('label the data with its true CRS': they were). The toolbox
    now reads a copy with the layer's CRS; a layer whose CRS is its file's is not copied."""
    import pyogrio

    gpkg = tmp_path / "points.gpkg"
    _points(gpkg, "points", [1.0, 2.0, 3.0], 1_500_000.0, 5_000_000.0)
    shp = tmp_path / "points.shp"
    pyogrio.write_dataframe(pyogrio.read_dataframe(gpkg), shp)
    (tmp_path / "points.prj").unlink()
    wrong = tmp_path / "wrong.shp"
    pyogrio.write_dataframe(pyogrio.read_dataframe(gpkg).set_crs(3004, allow_override=True),
                            wrong)
    got = plugin_values(tmp_path, [{"name": "INPUT", "type": "vector"}], {
        "no_prj": {"INPUT": {"layer": str(shp), "crs": "EPSG:3003"}},
        "wrong_prj": {"INPUT": {"layer": str(wrong), "crs": "EPSG:3003"}},
        "as_filed": {"INPUT": {"layer": str(gpkg)}},
        "qgis_default": {"INPUT": {"layer": str(shp), "crs": "EPSG:4326"}}})
    assert got["qgis_default"]["INPUT"].split("|")[0] == str(shp)
    for label in ("no_prj", "wrong_prj"):
        value = got[label]["INPUT"]
        assert pyogrio.read_info(value.split("|")[0])["crs"] == "EPSG:3003", label
        assert sorted(pyogrio.read_dataframe(value.split("|")[0]).geometry.z) == [1, 2, 3]
    assert got["as_filed"]["INPUT"].split("|")[0] == str(gpkg)


@needs_qgis
def test_output_layers_are_loaded_with_their_own_style(tmp_path):
    """carto:contours and attribution:apply embed their style as the layer's default in the
    GeoPackage; Processing loads result layers without it (as Postprocessing.py does below), so
    the index contours and the coded layers came in as one plain symbol. The provider's
    post-processor now loads the layer's own style."""
    import geopandas as gpd
    from shapely.geometry import LineString

    gpkg = tmp_path / "out.gpkg"
    gpd.GeoDataFrame({"index": [0, 1]}, geometry=[LineString([(0, 0), (1, 1)]),
                                                  LineString([(0, 1), (1, 2)])],
                     crs="EPSG:3003").to_file(gpkg, layer="contours", driver="GPKG")
    got = pyqgis(tmp_path, f"""
        styled = QgsVectorLayer({str(gpkg) + "|layername=contours"!r}, "c", "ogr")
        root = QgsRuleBasedRenderer.Rule(None)
        for expression in ('"index" = 1', '"index" = 0'):
            root.appendChild(QgsRuleBasedRenderer.Rule(
                QgsSymbol.defaultSymbol(styled.geometryType()), 0, 0, expression))
        styled.setRenderer(QgsRuleBasedRenderer(root))
        styled.saveStyleToDatabase("contours", "", True, "")
        del styled
        alg = ToolboxAlgorithm({{"id": "carto:contours", "parameters": []}}, "tb")
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        alg._load_layers({{"name": "OUTPUT"}}, {str(gpkg)!r}, context)
        renderers = {{}}
        for uri, details in context.layersToLoadOnCompletion().items():
            layer = QgsProcessingUtils.mapLayerFromString(uri, context)  # as Postprocessing.py
            if details.postProcessor():
                details.postProcessor().postProcessLayer(layer, context, QgsProcessingFeedback())
            renderers[uri.rsplit("=", 1)[1]] = layer.renderer().type()
        done(renderers)
        """)
    assert got == {"contours": "RuleRenderer"}


@needs_qgis
def test_a_crs_set_on_a_raster_layer_in_qgis_reaches_the_toolbox(tmp_path):
    """An ASCII-grid DEM without .prj, its CRS set in QGIS: dem:slope read the file and wrote a
    slope raster without CRS (exit 0; with a geographic CRS set it would have taken degrees for
    metres). The toolbox now reads a VRT of the same cells carrying the layer's CRS."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    heights = np.arange(12, dtype="float32").reshape(3, 4) * 2.5
    grid = tmp_path / "dem.asc"
    with rasterio.open(grid, "w", driver="AAIGrid", width=4, height=3, count=1,
                       dtype="float32", transform=from_origin(1_500_000, 5_000_030, 10, 10)) as dst:
        dst.write(heights, 1)
    for sidecar in tmp_path.glob("dem.prj"):
        sidecar.unlink()
    tif = tmp_path / "dem.tif"
    with rasterio.open(tif, "w", driver="GTiff", width=4, height=3, count=1, dtype="float32",
                       crs="EPSG:3003", transform=from_origin(1_500_000, 5_000_030, 10, 10)) as dst:
        dst.write(heights, 1)
    got = plugin_values(tmp_path, [{"name": "INPUT", "type": "raster"}], {
        "set_in_qgis": {"INPUT": {"layer": str(grid), "raster": True, "crs": "EPSG:3003"}},
        "its_own": {"INPUT": {"layer": str(tif), "raster": True}},
        "qgis_default": {"INPUT": {"layer": str(grid), "raster": True, "crs": "EPSG:4326"}}})
    with rasterio.open(got["set_in_qgis"]["INPUT"]) as src:
        assert src.crs.to_epsg() == 3003
        assert src.transform == from_origin(1_500_000, 5_000_030, 10, 10)
        assert np.array_equal(src.read(1), heights)
    assert got["its_own"]["INPUT"] == str(tif)
    # QGIS's own label of a file without CRS ('use a default CRS': EPSG:4326) is not passed on
    assert got["qgis_default"]["INPUT"] == str(grid)
    # nor any CRS on a photo (pixels): ortho:photo, rectify:image read it as it is
    photo = plugin_values(tmp_path, [{"name": "INPUT", "type": "raster", "role": "photo"}], {
        "photo": {"INPUT": {"layer": str(grid), "raster": True, "crs": "EPSG:3003"}}})
    assert photo["photo"]["INPUT"] == str(grid)


@needs_qgis
def test_one_raster_table_of_a_geopackage_reaches_the_toolbox(tmp_path):
    """A raster table of a GeoPackage holding two (QGIS's source 'GPKG:file.gpkg:table') was
    refused as 'file ... does not exist' (exit 2). The toolbox now reads a VRT of that table."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    gpkg = tmp_path / "rasters.gpkg"
    tables = {"first": np.full((3, 4), 1.0, "float32"), "second": np.full((3, 4), 2.0, "float32")}
    for i, (table, cells) in enumerate(tables.items()):
        options = {"RASTER_TABLE": table} | ({"APPEND_SUBDATASET": "YES"} if i else {})
        with rasterio.open(gpkg, "w", driver="GPKG", width=4, height=3, count=1,
                           dtype="float32", crs="EPSG:3003", **options,
                           transform=from_origin(1_500_000, 5_000_030, 10, 10)) as dst:
            dst.write(cells, 1)
    got = plugin_values(tmp_path, [{"name": "INPUT", "type": "raster"}], {
        "second": {"INPUT": {"layer": f"GPKG:{gpkg}:second", "raster": True}}})
    from toolbox.io.raster import open_raster_info

    open_raster_info(got["second"]["INPUT"], "INPUT", "DEM")  # the toolbox takes it
    with rasterio.open(got["second"]["INPUT"]) as src:
        assert src.crs.to_epsg() == 3003
        assert np.array_equal(src.read(1), tables["second"])


@needs_qgis
def test_a_fid_column_of_codes_keeps_every_feature(tmp_path):
    """A delimited-text CSV with a FID column of repeating codes: QGIS's temporary GeoPackage
    copy took FID as its primary key and dropped every feature whose FID repeated (dem:nearest
    made its DEM of 7 of 25 points, exit 0). Every feature now reaches the toolbox, FID kept as
    an attribute; with 'Selected features only' the selection is what it gets. The CSV given as
    a file path (OGR reads it as a table) still goes to the toolbox as the file."""
    import pyogrio

    rows = [(k % 7, 1_500_000 + 10 * (k // 5), 5_000_000 + 10 * (k % 5), float(k))
            for k in range(25)]
    csv = tmp_path / "points.csv"
    csv.write_text("FID,X,Y,Z\n" + "".join(f"{f},{x},{y},{z}\n" for f, x, y, z in rows))
    uri = (f"file://{csv}?type=csv&xField=X&yField=Y&zField=Z&crs=EPSG:3003&detectTypes=yes"
           "&geomType=point")
    got = plugin_values(tmp_path, [{"name": "INPUT", "type": "vector"}], {
        "all": {"INPUT": {"layer": uri, "provider": "delimitedtext"}},
        "selected": {"INPUT": {"layer": uri, "provider": "delimitedtext", "select": '"Z" < 10'}},
        "file": {"INPUT": str(csv)}})
    assert got["file"]["INPUT"] == str(csv)  # not copied: the toolbox reads X, Y, Z itself
    frame = pyogrio.read_dataframe(got["all"]["INPUT"].split("|")[0])
    assert sorted(frame.geometry.z) == [r[3] for r in rows]
    assert sorted(frame["FID"]) == sorted(r[0] for r in rows)
    assert frame.crs.to_epsg() == 3003
    selected = pyogrio.read_dataframe(got["selected"]["INPUT"].split("|")[0])
    assert sorted(selected.geometry.z) == [float(k) for k in range(10)]


@needs_qgis
def test_every_layer_of_a_shapefile_output_is_loaded(tmp_path):
    """topology:build_areas with OUTPUT areas.shp writes its arcs, nodes and errors beside it
    (areas_arcs.shp...): only areas.shp was loaded into the project. Every layer the spec names
    and the toolbox wrote is now loaded; a file of no spec layer is not."""
    import geopandas as gpd
    from shapely.geometry import Point

    for stem in ("areas", "areas_arcs", "areas_nodes", "areas_mine"):
        gpd.GeoDataFrame({"id": [1]}, geometry=[Point(0, 0)], crs="EPSG:3003").to_file(
            tmp_path / f"{stem}.shp")
    layers = [{"name": name} for name in ("areas", "arcs", "nodes", "errors_points")]
    got = pyqgis(tmp_path, f"""
        spec = {{"id": "topology:build_areas", "parameters": [],
                 "outputs": [{{"name": "OUTPUT", "type": "output_vector", "layers": {layers!r}}}]}}
        alg = ToolboxAlgorithm(spec, "tb")
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        alg._load_layers({{"name": "OUTPUT"}}, {str(tmp_path / "areas.shp")!r}, context)
        done(sorted(uri.split("|")[0] for uri in context.layersToLoadOnCompletion()))
        """)
    assert got == [str(tmp_path / f"{stem}.shp") for stem in ("areas", "areas_arcs",
                                                                 "areas_nodes")]


@needs_qgis
def test_the_logged_command_runs_as_shown_when_pasted_in_a_shell(tmp_path):
    """The log showed the command joined by spaces: pasted in a terminal, a path with a space
    split in two and '|layername=b' piped into a command 'layername=b'. It is quoted now."""
    import shlex

    fake = tmp_path / "toolbox"
    fake.write_text("#!/bin/sh\nexit 0\n")
    fake.chmod(0o755)
    gpkg = tmp_path / "my data.gpkg"
    _points(gpkg, "b", [1.0, 2.0, 3.0])
    got = pyqgis(tmp_path, f"""
        class Log(QgsProcessingFeedback):
            commands = []
            def pushCommandInfo(self, text):
                self.commands.append(text)
        spec = {{"id": "vector:info", "parameters": [{{"name": "INPUT", "type": "vector"}}]}}
        alg = ToolboxAlgorithm(spec, {str(fake)!r})
        alg.initAlgorithm()
        context = QgsProcessingContext(); context.setProject(QgsProject.instance())
        alg.processAlgorithm({{"INPUT": {str(gpkg) + "|layername=b"!r}}}, context, Log())
        done(Log.commands)
        """)
    assert shlex.split(got[0]) == [str(fake), "run", "vector:info", "--progress", "json",
                                   "--overwrite", "--INPUT", f"{gpkg}|layername=b"]


@needs_qgis
def test_an_error_is_shown_once_without_the_cli_prefix(tmp_path):
    """The toolbox says its error on stderr ("toolbox: error: ...") and, with --progress json,
    as a message record: QGIS's log showed it twice (an error line and console text) besides
    the exception, which carried the "toolbox: error:" prefix. Now the exception says it once."""
    fake = tmp_path / "toolbox"
    fake.write_text("#!/bin/sh\n"
                    "echo '{\"type\": \"message\", \"level\": \"error\", \"text\": "
                    "\"CELL_SIZE must be > 0, got -1\"}' >&2\n"
                    "echo 'toolbox: error: CELL_SIZE must be > 0, got -1' >&2\n"
                    "exit 2\n")
    fake.chmod(0o755)
    got = pyqgis(tmp_path, f"""
        class Log(QgsProcessingFeedback):
            def __init__(self):
                super().__init__(); self.lines = []
            def reportError(self, text, fatal=False):
                self.lines.append(("error", text))
            def pushConsoleInfo(self, text):
                self.lines.append(("console", text))
        alg = ToolboxAlgorithm({{"id": "dem:idw", "parameters": []}}, "tb")
        log = Log()
        try:
            alg._run([{str(fake)!r}], log)
            done({{"raised": None}})
        except QgsProcessingException as exc:
            done({{"raised": str(exc), "log": log.lines}})
        """, timeout=20)
    assert got["raised"] == "dem:idw: CELL_SIZE must be > 0, got -1", got
    assert got["log"] == [], got
