"""One QGIS Processing algorithm per toolbox spec, generated: no algorithm logic lives here.

Parameters are mapped from the spec's types; values are converted to the toolbox's text form
and the toolbox CLI runs in its own process (``toolbox run ID --progress json``), its progress
and messages relayed to QGIS's feedback, Cancel ending it (the toolbox then leaves nothing
behind). Multi-layer GeoPackage outputs have every layer loaded into the project.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import threading

from qgis.core import (
    NULL,
    QgsCoordinateReferenceSystem,
    QgsMapLayer,
    QgsProcessing,
    QgsProcessingAlgorithm,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeatureSourceDefinition,
    QgsProcessingLayerPostProcessorInterface,
    QgsProcessingOutputNumber,
    QgsProcessingOutputString,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterEnum,
    QgsProcessingParameterExtent,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterField,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProcessingUtils,
    QgsProperty,
    QgsProviderRegistry,
    QgsRectangle,
    QgsReferencedRectangle,
    QgsVectorFileWriter,
    QgsVectorLayer,
)
from qgis.PyQt.QtCore import QVariant

from .toolbox_cli import EXTENT_HELP, clean_help, command_line, parse_progress, qgis_id, short_label

VECTOR_FORMATS = ["gpkg", "shp", "fgb", "geojson", "parquet", "csv", "dxf", "sqlite"]


ERROR_PREFIX = "toolbox: error: "  # the CLI's one-line error on stderr


def _add_error(errors: list, text: str) -> None:
    """Append an error once: the toolbox says it on stderr and, with --progress json, as a
    message record too (QGIS showed it twice, besides the exception)."""
    if text and text not in errors:
        errors.append(text)


def _filter(extensions) -> str:
    exts = [e.lstrip(".") for e in (extensions or [])]
    if not exts:
        return "All files (*.*)"
    return f"Files ({' '.join('*.' + e for e in exts)})"


def make_parameter(p: dict):
    """The QGIS parameter definition of one spec parameter (None for a type not mapped)."""
    name, kind = p["name"], p["type"]
    full = p.get("description") or name
    desc = "Extent [EXTENT]" if kind == "extent" and name == "EXTENT" else short_label(name, full)
    optional = bool(p.get("optional"))
    default = p.get("default")
    if kind in ("number", "integer"):
        number_type = QgsProcessingParameterNumber.Integer if kind == "integer" else \
            QgsProcessingParameterNumber.Double
        param = QgsProcessingParameterNumber(name, desc, number_type, default, optional)
        if p.get("min") is not None:
            param.setMinimum(p["min"])
        if p.get("max") is not None:
            param.setMaximum(p["max"])
    elif kind == "boolean":
        param = QgsProcessingParameterBoolean(name, desc, bool(default), optional)
    elif kind == "enum":
        options = list(p.get("options") or [])
        index = options.index(default) if default in options else None
        param = QgsProcessingParameterEnum(name, desc, options, False, index, optional)
    elif kind == "crs":
        param = QgsProcessingParameterCrs(name, desc, default, optional)
    elif kind == "extent":
        param = QgsProcessingParameterExtent(name, desc, None, optional)
    elif kind == "file":
        param = QgsProcessingParameterFile(name, desc, QgsProcessingParameterFile.File, "",
                                           default, optional, _filter(p.get("extensions")))
    elif kind == "folder":
        param = QgsProcessingParameterFile(name, desc, QgsProcessingParameterFile.Folder, "",
                                           default, optional)
    elif kind == "vector":
        # any vector layer or table: the toolbox also reads points from CSV coordinate columns,
        # which QGIS opens as tables; the toolbox checks the geometry type itself
        param = QgsProcessingParameterFeatureSource(name, desc, [QgsProcessing.TypeVector], None,
                                                    optional)
    elif kind == "raster":
        param = QgsProcessingParameterRasterLayer(name, desc, None, optional)
    elif kind == "multiple":
        # rasters: any raster layers; vectors: files (the toolbox's multi-vector inputs also take
        # text exports QGIS cannot open as layers, e.g. restitution files)
        layer_type = QgsProcessing.TypeRaster if p.get("layer_type") == "raster" else \
            QgsProcessing.TypeFile
        param = QgsProcessingParameterMultipleLayers(name, desc, layer_type, None, optional)
        param.setMinimumNumberInputs(int(p.get("min_count") or 1))
    elif kind == "field":
        field_type = QgsProcessingParameterField.Numeric if p.get("numeric") else \
            QgsProcessingParameterField.Any
        param = QgsProcessingParameterField(name, desc, None, p.get("parent"), field_type,
                                            False, optional)
    elif kind == "output_raster":
        param = QgsProcessingParameterRasterDestination(name, desc, None, optional)
    elif kind == "output_vector":
        param = QgsProcessingParameterFileDestination(name, desc, "GeoPackage (*.gpkg)", None,
                                                      optional)
    elif kind == "output_folder":
        param = QgsProcessingParameterFolderDestination(name, desc, None, optional)
    elif kind == "output_file":
        param = QgsProcessingParameterFileDestination(name, desc, _filter(p.get("extensions")),
                                                      None, optional)
    else:  # string and anything new: free text the toolbox validates
        param = QgsProcessingParameterString(name, desc, None if default is None else
                                             str(default), False, optional)
    if kind.startswith("output_") and optional:
        # as the CLI: an optional output is written only when asked for (QGIS's dialog would
        # otherwise create each one as a temporary file: ortho:photo's OCCLUSION_MASK without
        # OCCLUSION was then refused, extra rasters computed and loaded)
        param.setCreateByDefault(False)
    flags = param.flags()
    if p.get("advanced"):
        flags |= QgsProcessingParameterDefinition.FlagAdvanced
    if p.get("hidden"):
        flags |= QgsProcessingParameterDefinition.FlagHidden
    param.setFlags(flags)
    details = [full] + [t for t in (p.get("help"), p.get("expected")) if t and t != full]
    if kind == "extent":
        details = [t.replace("xmin,ymin,xmax,ymax", "extent") for t in details] + [EXTENT_HELP]
    param.setHelp(clean_help("\n\n".join(details)))
    return param


def extent_names_crs(value) -> bool:
    """False for an extent value without a CRS of its own: numbers as text or a QgsRectangle."""
    if isinstance(value, QgsReferencedRectangle):
        return True
    if isinstance(value, QgsRectangle):
        return False
    if isinstance(value, str):
        text = value.strip()
        return "[" in text or not re.fullmatch(r"[-+.,\deE\s]*", text)  # or a layer's id
    return True


def crs_text(crs) -> str:
    """A CRS as the toolbox reads it: its authority id, else its WKT (a CRS defined in QGIS's
    Custom Projections is 'USER:100000', which only this QGIS profile knows)."""
    authid = crs.authid()
    if authid and not authid.upper().startswith("USER:"):
        return authid
    return crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED)


def point_cloud_file(p: dict, value) -> str | None:
    """A LAS/LAZ file given to a parameter that reads point clouds (QGIS cannot open it as a
    vector layer: the toolbox reads it itself), else None."""
    if not p.get("point_clouds") or not isinstance(value, str):
        return None
    path = value.strip()
    return path if path.lower().endswith((".las", ".laz")) and os.path.isfile(path) else None


def crs_set_in_qgis(layer) -> bool:
    """True when the layer's CRS in QGIS is not its file's: set in Layer Properties (a file
    without or with a wrong .prj). A file without CRS that QGIS shows in a geographic CRS is left
    alone: that is how QGIS labels such files with its default CRS (EPSG:4326), and the toolbox
    works in metres."""
    provider = layer.dataProvider()
    crs = layer.crs()
    if provider is None or not crs.isValid() or crs == provider.crs():
        return False
    return provider.crs().isValid() or not crs.isGeographic()


def layer_file(layer) -> tuple[str, dict]:
    """The local file a map layer reads ("" when none: memory, database, web, /vsi...) and the
    parts of its source URI (QGIS's decodeUri: path, layerName, layerId, geometryType...)."""
    if layer is None:
        return "", {}
    parts = dict(QgsProviderRegistry.instance().decodeUri(layer.providerType(), layer.source()))
    path = str(parts.get("path") or "")
    if parts.get("vsiPrefix") or path.startswith("/vsi"):  # inside a .zip...: not a plain file
        return "", parts
    return (path if path and os.path.exists(path) else ""), parts


FID_COLUMN = "toolbox_copy_fid"


def qgis_would_copy(layer, selected_only: bool) -> bool:
    """True when QGIS hands the toolbox a temporary copy of the layer rather than its file (as
    parameterAsCompatibleSourceLayerPath decides): a selection, a filter, another provider than
    OGR, a file inside a .zip, or a format the toolbox does not read."""
    if selected_only or layer.providerType() != "ogr" or layer.subsetString():
        return True
    file = layer_file(layer)[0]
    return not file or os.path.splitext(file)[1].lstrip(".").lower() not in VECTOR_FORMATS


def fid_would_clash(layer) -> bool:
    """True when the layer has a 'fid' field that is not a unique integer key: QGIS's temporary
    GeoPackage copy would take it as its primary key and drop every feature whose value repeats
    (or is not an integer), with no error (a CSV with a FID column of codes)."""
    index = layer.fields().lookupField("fid")
    if index < 0 or index in layer.primaryKeyAttributes():
        return False  # none, or a GeoPackage's own key
    if layer.fields().at(index).type() not in (QVariant.Int, QVariant.LongLong, QVariant.UInt,
                                               QVariant.ULongLong):
        return True
    values = layer.uniqueValues(index)
    return NULL in values or len(values) < layer.featureCount()


def copy_for_toolbox(layer, name: str, selected_only: bool, context) -> str:
    """A temporary GeoPackage of the layer (its selection only, if asked), in its QGIS CRS, whose
    primary key is a column of its own: a 'fid' field stays an attribute, every feature kept."""
    path = QgsProcessingUtils.generateTempFilename(f"{name}.gpkg")
    options = QgsVectorFileWriter.SaveVectorOptions()
    options.driverName = "GPKG"
    options.layerName = name
    options.fileEncoding = "UTF-8"
    options.layerOptions = [f"FID={FID_COLUMN}"]
    options.onlySelectedFeatures = selected_only
    error, message, *_ = QgsVectorFileWriter.writeAsVectorFormatV3(
        layer, path, context.transformContext(), options)
    if error != QgsVectorFileWriter.NoError:
        raise QgsProcessingException(f"{name}: cannot copy the layer for the toolbox: {message}")
    return f"{path}|layername={name}"


def raster_source(layer, name: str, role: str | None = None) -> str:
    """What the toolbox reads for a raster layer: its source, or a VRT of it when that source
    is not a whole file the toolbox can open (one raster table of a GeoPackage,
    ``GPKG:file:table``; any GDAL subdataset), or when the layer's CRS was set in QGIS (a grid
    without .prj) and is not its file's: the VRT then carries the layer's CRS."""
    provider = layer.dataProvider()
    if layer.providerType() != "gdal" or provider is None:
        return layer.source()
    crs = layer.crs()
    relabelled = role != "photo" and crs_set_in_qgis(layer)  # a photo's pixels have no CRS
    file = layer_file(layer)[0]
    part_of_file = bool(file) and os.path.abspath(file) != os.path.abspath(layer.source())
    if not (relabelled or part_of_file):
        return layer.source()
    from osgeo import gdal

    vrt = QgsProcessingUtils.generateTempFilename(f"{name}.vrt")
    options = {"outputSRS": crs_text(crs)} if relabelled else {}
    done = gdal.Translate(vrt, layer.source(), format="VRT", **options)
    if done is None:
        raise QgsProcessingException(f"{name}: cannot read the raster layer '{layer.source()}' "
                                     f"(GDAL: {gdal.GetLastErrorMsg()})")
    done = None
    return vrt


class DefaultStyle(QgsProcessingLayerPostProcessorInterface):
    """Loads an output layer's own style (the GeoPackage's layer_styles default, or a .qml beside
    the file): Processing loads result layers without it (and then applies its own)."""

    kept: list = []  # QGIS holds no reference to a Python post-processor: keep it alive

    @classmethod
    def create(cls):
        if len(cls.kept) > 256:
            del cls.kept[:128]
        cls.kept.append(cls())
        return cls.kept[-1]

    def postProcessLayer(self, layer, context, feedback):  # noqa: N802 - QGIS's name
        message, loaded = layer.loadDefaultStyle()
        if loaded:
            layer.triggerRepaint()


class ToolboxAlgorithm(QgsProcessingAlgorithm):
    """A toolbox algorithm seen from QGIS."""

    def __init__(self, spec: dict, executable: str):
        super().__init__()
        self.spec = spec
        self.executable = executable

    # -- identity ------------------------------------------------------------------------------
    def createInstance(self):
        return ToolboxAlgorithm(self.spec, self.executable)

    def name(self):
        return qgis_id(self.spec["id"])

    def displayName(self):
        return self.spec.get("display_name") or self.spec["id"]

    def group(self):
        return self.spec.get("group") or self.spec["id"].split(":")[0]

    def groupId(self):
        return self.spec.get("group_id") or self.spec["id"].split(":")[0]

    def shortDescription(self):
        return self.spec.get("short_help", "")

    def shortHelpString(self):
        return clean_help(self.spec.get("help") or self.spec.get("short_help") or "")

    def tags(self):
        return [self.spec["id"], self.groupId()]

    # -- parameters ----------------------------------------------------------------------------
    def initAlgorithm(self, config=None):
        for p in self.spec.get("parameters", []):
            self.addParameter(make_parameter(p))
        outputs = [self.parameterDefinition(p["name"]) for p in self.spec.get("parameters", [])
                   if p["type"].startswith("output_")]
        if outputs and all(o.flags() & QgsProcessingParameterDefinition.FlagOptional
                           for o in outputs):
            outputs[0].setCreateByDefault(True)  # one at least (carto:sheet's PDF), as before
        destinations = {p["name"] for p in self.spec.get("parameters", [])}
        for out in self.spec.get("outputs", []):
            if out["name"] in destinations or out["type"].startswith("output_"):
                continue
            if out["type"] in ("number", "integer"):
                self.addOutput(QgsProcessingOutputNumber(out["name"], out.get("description", "")))
            else:
                self.addOutput(QgsProcessingOutputString(out["name"], out.get("description", "")))

    def _value(self, p: dict, parameters, context, feedback):
        """The toolbox text form of one parameter's value (None when not set)."""
        name, kind = p["name"], p["type"]
        if parameters.get(name) is None:
            return None
        if kind in ("number", "integer") and isinstance(parameters[name], str):
            # text (qgis_process, scripts) goes as typed, for the toolbox to check: QGIS reads
            # what it cannot parse ('250,5', '4.5' for an integer) as the default, else 0
            return parameters[name].strip() or None
        if kind == "integer" and isinstance(parameters[name], (int, float)) and \
                not isinstance(parameters[name], bool):
            number = parameters[name]
            if float(number).is_integer():  # QGIS's int is 32-bit: 3e9 (MAX_CELLS) became 0
                return str(int(number))
            return repr(number)  # 4.5 from a model's number: QGIS rounded it to 5
        if kind == "boolean" and isinstance(parameters[name], str) and parameters[name].strip():
            # text goes as typed, read by the toolbox as the CLI reads it: QGIS reads any text
            # but '0' and 'false' as true ('no', 'off' ran with the option on)
            return parameters[name].strip()
        if kind == "number":
            return repr(self.parameterAsDouble(parameters, name, context))
        if kind == "integer":
            return str(self.parameterAsInt(parameters, name, context))
        if kind == "boolean":
            return "true" if self.parameterAsBoolean(parameters, name, context) else "false"
        if kind == "enum":
            return list(p.get("options") or [])[self.parameterAsEnum(parameters, name, context)]
        if kind == "crs":
            crs = self.parameterAsCrs(parameters, name, context)
            if crs.isValid():
                return crs_text(crs)
            # text QGIS cannot read as a CRS ('EPSG:999999', a typo) goes as typed, for the
            # toolbox to refuse: QGIS gives an invalid CRS, and the run went on without it
            given = parameters[name]
            return given.strip() or None if isinstance(given, str) else None
        if kind == "extent":
            rect = self.parameterAsExtent(parameters, name, context)
            if rect.isNull():
                return None
            # an extent typed without CRS is in the data's, as for the CLI and QGIS's own
            # algorithms: not the QGIS project's (parameterAsExtentCrs's fallback), which the
            # toolbox then converted from (dem:match, ortho:photo in an EPSG:3857 project)
            crs = self.parameterAsExtentCrs(parameters, name, context) if \
                extent_names_crs(parameters[name]) else QgsCoordinateReferenceSystem()
            target = self._data_crs(parameters, context)
            if crs.isValid() and target is not None and crs != target:
                # drawn on a canvas in another CRS (a basemap's): into the data's, as QGIS's own
                # algorithms do (the toolbox refuses an extent in another CRS than its inputs)
                rect = self.parameterAsExtent(parameters, name, context, target)
                crs = target
            tail = f" [{crs_text(crs)}]" if crs.isValid() else ""
            return f"{rect.xMinimum()!r},{rect.yMinimum()!r},{rect.xMaximum()!r}," \
                   f"{rect.yMaximum()!r}{tail}"
        if kind in ("file", "folder"):
            return self.parameterAsFile(parameters, name, context) or None
        if kind == "vector":
            cloud = point_cloud_file(p, parameters[name])
            return cloud or self._vector_source(parameters, name, context, feedback)
        if kind == "raster":
            layer = self.parameterAsRasterLayer(parameters, name, context)
            return None if layer is None else raster_source(layer, name, p.get("role"))
        if kind == "multiple":
            if p.get("layer_type") != "raster":
                return self._vector_files(parameters, name, context, feedback)
            return [raster_source(layer, name, p.get("role")) for layer in
                    self.parameterAsLayerList(parameters, name, context)]
        if kind == "field":
            return self.parameterAsString(parameters, name, context) or None
        if kind == "output_raster":
            return self.parameterAsOutputLayer(parameters, name, context)
        if kind in ("output_vector", "output_file", "output_folder"):
            return self.parameterAsFileOutput(parameters, name, context)
        if isinstance(parameters[name], (list, tuple)):  # CLASSES=[2, 9]: QGIS's text was ''
            return ",".join(str(v).strip() for v in parameters[name]) or None
        return self.parameterAsString(parameters, name, context) or None

    def _vector_source(self, parameters, name, context, feedback):
        """The toolbox source of one vector layer value (a file, a layer of it, or a copy)."""
        # a CRS set on the layer in QGIS (a Shapefile without or with a wrong .prj) is not
        # in its file: then the toolbox reads a copy QGIS writes with the layer's CRS
        vector = self._vector_layer(parameters, name, context)
        relabelled = vector is not None and crs_set_in_qgis(vector)
        value = parameters.get(name)
        selected = isinstance(value, QgsProcessingFeatureSourceDefinition) and \
            value.selectedFeaturesOnly
        if vector is not None and (relabelled or qgis_would_copy(vector, selected)) and \
                fid_would_clash(vector):
            return copy_for_toolbox(vector, name, selected, context)
        path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
            parameters, name, context, [] if relabelled else VECTOR_FORMATS, "gpkg", feedback)
        if not path:
            return None
        if "|" in path:
            return path
        # QGIS hands over the layer's own file when it needs no copy: keep which layer of it
        # (layerid= when the URI has no name) and which geometry type (a GeoJSON/DXF
        # sublayer), or the toolbox reads the file's first layer, all geometries
        file, parts = layer_file(vector)
        own = bool(file) and os.path.abspath(file) == os.path.abspath(path)
        if layer:
            path += f"|layername={layer}"
        elif own and parts.get("layerId") not in (None, ""):
            path += f"|layerid={parts['layerId']}"
        if own and parts.get("geometryType"):
            path += f"|geometrytype={parts['geometryType']}"
        return path

    def _vector_files(self, parameters, name, context, feedback) -> list[str]:
        """A multiple-files input: each file as given, and each project layer (an object, a
        layer id or name from a model or the console, a memory layer) as the toolbox reads it
        (a path stays as given):
        QGIS's file list gave '' for a layer object (the toolbox then drew without it) and the
        layer id for an id (refused as a missing file)."""
        files = list(self.parameterAsFileList(parameters, name, context))
        raw = parameters.get(name)
        raw = list(raw) if isinstance(raw, (list, tuple)) else [raw]
        if len(raw) != len(files):
            return files
        out = []
        for item, file in zip(raw, files):
            by_id = isinstance(item, str) and item and not os.path.exists(item.split("|")[0])
            layer = item if isinstance(item, QgsMapLayer) else (
                QgsProcessingUtils.mapLayerFromString(item, context, False) if by_id else None)
            if isinstance(layer, QgsVectorLayer):
                file = self._vector_source({name: layer}, name, context, feedback) or file
            out.append(file)
        return out

    def checkParameterValues(self, parameters, context):  # noqa: N802 - QGIS's name
        """QGIS's checks, but a LAS/LAZ file given to a point input that reads point clouds
        (dem:* INPUT) passes: QGIS cannot open it as a vector layer and refused it as 'not
        found', while the CLI reads it."""
        clouds = {p["name"] for p in self.spec.get("parameters", [])
                  if point_cloud_file(p, parameters.get(p["name"]))}
        if clouds:
            parameters = {k: (None if k in clouds else v) for k, v in parameters.items()}
        return super().checkParameterValues(parameters, context)

    # -- running -------------------------------------------------------------------------------
    def processAlgorithm(self, parameters, context, feedback):
        values = {p["name"]: self._value(p, parameters, context, feedback)
                  for p in self.spec.get("parameters", [])}
        self._check_outputs_are_not_inputs(parameters, context, values)
        args = command_line(self.executable, self.spec["id"], values)
        feedback.pushCommandInfo(shlex.join(args))  # pasted in a shell: runs as shown
        result, errors = self._run(args, feedback)
        outputs = dict(result.get("outputs") or {})
        for p in self.spec.get("parameters", []):
            if p["type"].startswith("output_") and values.get(p["name"]):
                outputs.setdefault(p["name"], values[p["name"]])
                if p["type"] == "output_vector":
                    self._load_layers(p, outputs[p["name"]], context)
        for key, value in list(outputs.items()):
            if isinstance(value, (dict, list)):
                outputs[key] = json.dumps(value)
        return outputs

    def _data_crs(self, parameters, context):
        """The CRS the toolbox works in: the CRS parameter's, else the first input layer's with
        one (None when unknown). Only the parameter named CRS says it: another CRS parameter
        is something else (carto:sheet's GRID_CRS, a second CRS ticked along the frame)."""
        given = [p for p in self.spec.get("parameters", [])
                 if parameters.get(p["name"]) not in (None, "")]
        for p in given:
            if p["type"] == "crs" and p["name"] == "CRS":
                crs = self.parameterAsCrs(parameters, p["name"], context)
                if crs.isValid():
                    return crs
        for p in given:
            if p["type"] == "vector":
                layer = self._vector_layer(parameters, p["name"], context)
            elif p["type"] == "raster" and p.get("role") not in ("photo", "heights"):
                # a photo's pixels have no map CRS; a DEM read for heights may be in another
                # CRS than the output (ortho:photo's is the project's): converted into the
                # DEM's, the extent was converted back by the toolbox, a larger bounding box
                # (unknown here: the toolbox converts it into the output's CRS itself)
                layer = self.parameterAsRasterLayer(parameters, p["name"], context)
            else:
                continue
            provider = layer.dataProvider() if layer is not None else None
            if provider is not None and layer.crs().isValid() and (
                    provider.crs().isValid() or crs_set_in_qgis(layer)):
                return layer.crs()  # not QGIS's own label of a file without CRS
        return None

    def _vector_layer(self, parameters, name, context):
        """The map layer of a vector parameter, also when given with 'Selected features only'
        (a source definition, for which parameterAsVectorLayer answers None)."""
        value = parameters.get(name)
        if isinstance(value, QgsProcessingFeatureSourceDefinition):
            source = value.source
            source = source.staticValue() if isinstance(source, QgsProperty) else source
            return QgsProcessingUtils.mapLayerFromString(str(source), context)
        return self.parameterAsVectorLayer(parameters, name, context)

    def _input_files(self, parameters, context):
        """(parameter name, file) of every input layer read from a local file."""
        for p in self.spec.get("parameters", []):
            name, kind = p["name"], p["type"]
            if parameters.get(name) in (None, ""):
                continue
            if kind == "vector":
                layers = [self._vector_layer(parameters, name, context)]
            elif kind == "raster":
                layers = [self.parameterAsRasterLayer(parameters, name, context)]
            elif kind == "multiple" and p.get("layer_type") == "raster":
                layers = self.parameterAsLayerList(parameters, name, context)
            else:
                continue  # files and folders go to the toolbox as given: it checks them itself
            for layer in layers:
                path = layer_file(layer)[0]
                if path:
                    yield name, path

    def _check_outputs_are_not_inputs(self, parameters, context, values) -> None:
        """An output on an input layer's file is refused before anything runs: QGIS hands the
        toolbox a temporary copy of a layer with a selection or a filter, so the toolbox's own
        check cannot see that the output would replace the user's file."""
        outputs = [(p["name"], values.get(p["name"])) for p in self.spec.get("parameters", [])
                   if p["type"] in ("output_raster", "output_vector", "output_file")]
        outputs = [(name, str(path)) for name, path in outputs if path]
        if not outputs:
            return
        for in_name, in_path in self._input_files(parameters, context):
            for out_name, out_path in outputs:
                if os.path.realpath(out_path) == os.path.realpath(in_path):
                    raise QgsProcessingException(
                        f"{out_name} '{out_path}' is also the input {in_name}; an input is never "
                        "overwritten: choose another output path")

    def _run(self, args, feedback):
        process = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True, bufsize=1)
        state = {"result": {}, "errors": [], "stdout": []}

        def read_stderr():
            for line in process.stderr:
                item = parse_progress(line)
                if item is None:
                    text = line.strip()
                    if text.startswith(ERROR_PREFIX):  # the error: raised once, at the end
                        _add_error(state["errors"], text[len(ERROR_PREFIX):])
                    elif text:
                        state["errors"].append(text)
                        feedback.pushConsoleInfo(line.rstrip())
                    continue
                kind = item.get("type")
                if kind == "progress" and item.get("percent") is not None:
                    feedback.setProgress(float(item["percent"]))
                elif kind == "message":
                    text, level = str(item.get("text", "")), item.get("level", "info")
                    if level == "error":  # raised at the end (shown once, not also here)
                        _add_error(state["errors"], text)
                    elif level == "warning":
                        feedback.pushWarning(text)
                    else:
                        feedback.pushInfo(text)
                elif kind == "result":
                    state["result"] = item

        def read_stdout():  # read as it comes: a result over the pipe's 64 KB would block
            state["stdout"].append(process.stdout.read())  # the toolbox (and QGIS) for ever

        reader = threading.Thread(target=read_stderr, daemon=True)
        reader.start()
        out_reader = threading.Thread(target=read_stdout, daemon=True)
        out_reader.start()
        while True:
            try:
                process.wait(timeout=0.2)
                break
            except subprocess.TimeoutExpired:
                if feedback.isCanceled():
                    process.terminate()  # SIGTERM: the toolbox cancels and removes its outputs
                    try:
                        process.wait(timeout=30)
                    except subprocess.TimeoutExpired:
                        process.kill()
                    break
        reader.join(timeout=5)
        out_reader.join(timeout=5)
        for stream in (process.stdout, process.stderr):
            stream.close()
        for line in "".join(state["stdout"]).splitlines():
            item = parse_progress(line)
            if item and item.get("type") == "result":
                state["result"] = item
        if feedback.isCanceled():
            raise QgsProcessingException(f"{self.spec['id']}: canceled")
        if process.returncode != 0:
            for earlier in state["errors"][:-1]:  # the last is the exception's message
                feedback.reportError(earlier)
            message = state["errors"][-1] if state["errors"] else f"exit {process.returncode}"
            raise QgsProcessingException(f"{self.spec['id']}: {message}")
        return state["result"], state["errors"]

    def _load_layers(self, param: dict, path: str, context) -> None:
        """Every layer of an output loads into the project on completion: all the layers of a
        GeoPackage; with a one-layer format (.shp...) the file and the toolbox's sibling files of
        the other layers (``<stem>_<layer>.shp``, as the spec names them)."""
        from osgeo import ogr

        files = [path]
        stem, suffix = os.path.splitext(path)
        if suffix.lower() not in (".gpkg", ".sqlite"):
            spec = next((o for o in self.spec.get("outputs", []) if o.get("name") == param["name"]),
                        {})
            files += [f"{stem}_{layer['name']}{suffix}" for layer in (spec.get("layers") or [])[1:]
                      if os.path.exists(f"{stem}_{layer['name']}{suffix}")]
        for file in files:
            ds = ogr.Open(file)
            if ds is None:
                continue
            names = [ds.GetLayer(i).GetName() for i in range(ds.GetLayerCount())]
            ds = None
            for layer_name in names:
                if layer_name == "layer_styles":  # the styles table QGIS reads, not a layer
                    continue
                details = QgsProcessingContext.LayerDetails(layer_name, context.project(),
                                                            param["name"])
                details.setPostProcessor(DefaultStyle.create())
                context.addLayerToLoadOnCompletion(f"{file}|layername={layer_name}", details)
