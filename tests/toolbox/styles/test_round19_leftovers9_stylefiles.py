"""One writer of a style beside a one-layer output (toolbox.styles.files.write_layer_style_files)
for attribution's styles and the runner's declared ones: a Shapefile's style names its fields
as the DBF holds them, read from the file (pyogrio.read_info, the independent reference):
by the written order when the writer knows it, else by the 10-character cut."""

from __future__ import annotations

import warnings

import geopandas as gpd
import pyogrio
import shapely

from toolbox.styles import layers as style_layers
from toolbox.styles.model import LayerStyle


def _long_field_style(layer, kind, label="measurement_label"):
    base = style_layers.residuals_style(layer, kind)
    return LayerStyle(layer, "point", base.styles, field="measurement_role", label_field=label)


def test_a_declared_style_on_a_shapefile_names_the_cut_fields(tmp_path, monkeypatch):
    from toolbox.io.vector_write import write_layers

    monkeypatch.setitem(style_layers.STYLES, "long_fields",
                        lambda layer, kind: _long_field_style(layer, kind, "label"))
    frame = gpd.GeoDataFrame({"label": ["a", "b"], "measurement_role": ["control", "check"]},
                             geometry=shapely.points([[0, 0], [1, 1]]), crs=3003)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = write_layers(tmp_path / "r.shp", {"residuals": frame})
    held = [str(f) for f in pyogrio.read_info(out)["fields"]]
    assert held == ["label", "measuremen"]  # GDAL's cut
    written = style_layers.write_declared_style_files(out, [("residuals", "long_fields",
                                                              "Point")])
    assert sorted(p.name for p in written) == ["r.qml", "r.sld"]
    qml = (tmp_path / "r.qml").read_text()
    assert 'attr="measuremen"' in qml and 'fieldName="label"' in qml
    assert "measurement_role" not in qml
    assert "<ogc:PropertyName>measuremen</ogc:PropertyName>" in (tmp_path / "r.sld").read_text()


def test_attribution_styles_follow_the_written_order(tmp_path):
    """With the order written, a second field cut alike gets GDAL's unique name."""
    from toolbox.attribution.output import store_style
    from toolbox.io.vector_write import write_layers
    from toolbox.styles.qml import qml_document

    frame = gpd.GeoDataFrame({"measurement_label": ["a"], "measurement_role": ["check"]},
                             geometry=shapely.points([[0, 0]]), crs=3003)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_layers(tmp_path / "r.shp", {"residuals": frame})
    held = [str(f) for f in pyogrio.read_info(tmp_path / "r.shp")["fields"]]
    assert held == ["measuremen", "measurem_1"]
    style = _long_field_style("residuals", "point")
    embedded = store_style(tmp_path / "r.shp", ["residuals"], "residuals", qml_document(style),
                           None, fields=list(frame.columns[:-1]))
    qml = (tmp_path / "r.qml").read_text()
    assert not embedded and 'attr="measurem_1"' in qml and 'fieldName="measuremen"' in qml
