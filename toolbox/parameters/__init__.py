"""Typed algorithm parameters (the QGIS Processing model: UPPERCASE names, defaults, validation).

Each parameter turns a user value (a Python object, or the text given on the command line) into the
normalised value the algorithm receives, or raises :class:`ParameterError` naming the parameter, the
value given and what was expected, e.g. ``CELL_SIZE must be > 0, got -2``. Validation runs once, in
the runner, before any work starts.

Four modules of one concern each: :mod:`~toolbox.parameters.base` (the base class),
:mod:`~toolbox.parameters.values` (numbers, choices, CRS, extents), :mod:`~toolbox.parameters.sources`
(input files and layers) and :mod:`~toolbox.parameters.outputs` (what an algorithm writes and
returns). Every name stays importable from ``toolbox.parameters``.
"""

from toolbox.parameters.base import ADVANCED_NAMES, Parameter, ValidationContext
from toolbox.parameters.outputs import (
    FIELD_TYPES,
    GEOMETRY_TYPES,
    VALUE_TYPES,
    Destination,
    Layer,
    LayerField,
    Output,
    OutputFile,
    OutputFolder,
    OutputRaster,
    OutputVector,
)
from toolbox.parameters.sources import Field, File, Folder, MultipleLayers, RasterLayer, VectorLayer
from toolbox.parameters.values import Boolean, Crs, Enum, Extent, ExtentParameter, Integer, Number, String

__all__ = ["ADVANCED_NAMES", "FIELD_TYPES", "GEOMETRY_TYPES", "VALUE_TYPES", "Boolean", "Crs",
           "Destination", "Enum", "Extent", "ExtentParameter", "Field", "File", "Folder",
           "Integer", "Layer", "LayerField", "MultipleLayers", "Number", "Output", "OutputFile",
           "OutputFolder", "OutputRaster", "OutputVector", "Parameter", "RasterLayer", "String",
           "ValidationContext", "VectorLayer"]

