"""QGIS plugin entry: registers the Processing provider (also inside qgis_process)."""

from __future__ import annotations

from qgis.core import QgsApplication


class ToolboxPlugin:
    def __init__(self, iface=None):
        self.iface = iface
        self.provider = None

    def initProcessing(self):
        from .provider import ToolboxProvider

        self.provider = ToolboxProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):
        self.initProcessing()

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
