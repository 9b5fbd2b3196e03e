"""Photogrammetry toolbox for QGIS: the toolbox's algorithms in the Processing Toolbox.

The toolbox itself runs out of process (its own Python environment); this plugin needs nothing
beyond QGIS.
"""


def classFactory(iface):  # noqa: N802 - QGIS's name
    from .plugin import ToolboxPlugin

    return ToolboxPlugin(iface)
