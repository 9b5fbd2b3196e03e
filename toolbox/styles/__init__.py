"""One definition of symbology, several renderers.

:mod:`.model` builds a renderer-neutral style per code (geometry kind, RGB, line width, fill,
label) from the code and colour files; :mod:`.qml` and :mod:`.sld` write it for QGIS and for
OGC clients; :mod:`.gpkg` embeds both in a GeoPackage's ``layer_styles`` table the way QGIS does,
so QGIS opens every layer already styled. Map sheets (matplotlib) read the same model.
"""

from toolbox.styles.gpkg import read_layer_styles, write_layer_styles
from toolbox.styles.model import CodeStyle, LayerStyle, layer_style, style_model
from toolbox.styles.qml import qml_document
from toolbox.styles.sld import sld_document

__all__ = ["CodeStyle", "LayerStyle", "layer_style", "style_model", "qml_document",
           "sld_document", "write_layer_styles", "read_layer_styles"]
