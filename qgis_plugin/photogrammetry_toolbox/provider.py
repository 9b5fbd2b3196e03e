"""The Processing provider: one algorithm per toolbox spec, loaded in one call and cached."""

from __future__ import annotations

import sys

from qgis.core import Qgis, QgsApplication, QgsMessageLog, QgsProcessingProvider, QgsSettings

from .toolbox_cli import (
    PROVIDER_ID,
    VERSIONS,
    ToolboxNotFound,
    find_executable,
    load_specs,
    start_warmup,
    toolbox_version,
    warmup_disabled,
)

SETTING = "photogrammetry_toolbox/executable"
LOG_TAG = "Photogrammetry toolbox"


def configured_executable() -> str | None:
    """The executable set in Processing > Options > Providers (or QGIS settings), if any."""
    try:
        from processing.core.ProcessingConfig import ProcessingConfig

        value = ProcessingConfig.getSetting("PHOTOGRAMMETRY_TOOLBOX_EXECUTABLE")
        if value:
            return str(value)
    except ImportError:
        pass
    return QgsSettings().value(SETTING, None) or None


class ToolboxProvider(QgsProcessingProvider):
    def __init__(self):
        super().__init__()
        self.executable = None
        self.problem = None

    def id(self):
        return PROVIDER_ID

    def name(self):
        return "Photogrammetry toolbox"

    def longName(self):
        return "Photogrammetry toolbox (orientation, TIN, DEM, topology, orthophotos, maps)"

    def icon(self):
        return QgsApplication.getThemeIcon("/processingAlgorithm.svg")

    def load(self):
        try:
            from processing.core.ProcessingConfig import ProcessingConfig, Setting

            ProcessingConfig.settingIcons[self.name()] = self.icon()
            ProcessingConfig.addSetting(Setting(
                self.name(), "PHOTOGRAMMETRY_TOOLBOX_EXECUTABLE",
                "Toolbox executable (its own environment, e.g. /path/to/.venv/bin/toolbox)", "",
                valuetype=Setting.FILE))
            ProcessingConfig.readSettings()
        except ImportError:
            pass
        self.refreshAlgorithms()
        return True

    def unload(self):
        try:
            from processing.core.ProcessingConfig import ProcessingConfig

            ProcessingConfig.removeSetting("PHOTOGRAMMETRY_TOOLBOX_EXECUTABLE")
        except ImportError:
            pass

    # the toolbox writes GeoTIFF and GeoPackage: offer only those in the output widgets
    def supportedOutputRasterLayerExtensions(self):
        return ["tif"]

    def supportedOutputVectorLayerExtensions(self):
        return ["gpkg"]

    def defaultRasterFileExtension(self):
        return "tif"

    def defaultVectorFileExtension(self, hasGeometry=True):
        return "gpkg"

    def loadAlgorithms(self):
        from .algorithm import ToolboxAlgorithm

        try:
            self.executable = find_executable(configured_executable())
            specs = load_specs(self.executable)
        except (ToolboxNotFound, ValueError) as exc:
            self.problem = str(exc)
            QgsMessageLog.logMessage(self.problem, LOG_TAG, Qgis.Warning)
            # qgis_process shows no message log: say it where a command-line user looks
            print(f"{LOG_TAG}: {self.problem}", file=sys.stderr)
            return
        self.problem = None
        for spec in specs:
            self.addAlgorithm(ToolboxAlgorithm(spec, self.executable))
        if not warmup_disabled():
            try:
                version = VERSIONS.get(self.executable) or toolbox_version(self.executable)
                start_warmup(self.executable, version)
            except (ToolboxNotFound, OSError):
                pass  # only costs the first run's compile time
