"""A declared style beside a Shapefile output names the fields as GDAL wrote them: two long
field names sharing their first 10 characters are held as ``measuremen`` and ``measurem_1``;
the style beside the file guessed the cut name (``measuremen``) for both, so its classes read
the label's column. Now the names GDAL wrote, read back after writing, map the style's fields;
the .qml's field names are checked against the .dbf's (pyogrio.read_info) and against the
column holding the style's values."""

from __future__ import annotations

import re

import geopandas as gpd
import pyogrio
import shapely

import toolbox
from tests.helpers_cli import register_testing
from toolbox.parameters import Layer, OutputVector
from toolbox.styles import layers as style_layers
from toolbox.styles.model import LayerStyle


def long_field_style(layer, kind):
    base = style_layers.residuals_style(layer, kind)
    return LayerStyle(layer, "point", base.styles, field="measurement_role",
                      label_field="measurement_label")


def test_a_declared_style_names_the_second_cut_field_as_gdal_wrote_it(tmp_path, monkeypatch):
    monkeypatch.setitem(style_layers.STYLES, "long_fields", long_field_style)

    def process(self, params, feedback):
        from toolbox.io.vector_write import write_layers

        frame = gpd.GeoDataFrame({"measurement_label": ["p1", "p2"],
                                  "measurement_role": ["control", "check"]},
                                 geometry=shapely.points([[0, 0], [1, 1]]), crs=3003)
        write_layers(params["OUTPUT"], {"residuals": frame})
        return {}

    register_testing("shpstyle", OutputVector("OUTPUT", "points", layers=[
        Layer("residuals", "Point", [("measurement_label", "string"),
                                     ("measurement_role", "string")], style="long_fields")]),
        process)
    out = tmp_path / "r.shp"
    toolbox.run("testing:shpstyle", {"OUTPUT": out})
    held = [str(f) for f in pyogrio.read_info(out)["fields"]]
    assert held == ["measuremen", "measurem_1"]  # GDAL's names
    qml = (tmp_path / "r.qml").read_text()
    attrs = re.findall(r'<renderer-v2[^>]* attr="([^"]*)"', qml)
    labels = re.findall(r'fieldName="([^"]*)"', qml)
    assert attrs and labels and set(attrs + labels) <= set(held), (attrs, labels)
    table = pyogrio.read_dataframe(out)
    assert set(table[attrs[0]]) == {"control", "check"}  # the classes read the role column
    assert set(table[labels[0]]) == {"p1", "p2"}  # the labels the label column
    sld = (tmp_path / "r.sld").read_text()
    assert re.findall(r"<ogc:PropertyName>([^<]*)</ogc:PropertyName>", sld) and \
        set(re.findall(r"<ogc:PropertyName>([^<]*)</ogc:PropertyName>", sld)) <= set(held)
    assert "<ogc:PropertyName>measurem_1</ogc:PropertyName>" in sld
