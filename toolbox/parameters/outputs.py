"""What an algorithm writes (destinations and the layers of a GeoPackage) and returns."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toolbox.errors import OutputExistsError
from toolbox.parameters.base import _NAME_RE, Parameter, ValidationContext, _show

# -- declared layers of an output GeoPackage ------------------------------------------------------
GEOMETRY_TYPES = ("Point", "LineString", "Polygon", "MultiPoint", "MultiLineString",
                  "MultiPolygon", "GeometryCollection", "Geometry")  # OGR names; + " Z" for 3D
FIELD_TYPES = ("string", "integer", "real", "boolean", "date", "datetime", "json")


@dataclass(frozen=True)
class LayerField:
    """A main attribute of a declared layer: name, type (one of :data:`FIELD_TYPES`), meaning."""

    name: str
    type: str = "string"
    description: str = ""

    def __post_init__(self):
        if self.type not in FIELD_TYPES:
            raise ValueError(f"field {self.name}: type {self.type!r} is not one of {FIELD_TYPES}")


@dataclass(frozen=True)
class Layer:
    """A layer an :class:`OutputVector` writes.

    ``geometry_type`` is an OGR name of :data:`GEOMETRY_TYPES`, with ``" Z"`` when 3D, or None
    for a table without geometry. ``fields`` are the main attributes, as :class:`LayerField` or
    ``(name, type[, description])`` tuples. ``name`` may hold a parameter in braces
    (``"{OPERATION}"``: the layer is named after that parameter's value). ``optional`` layers are
    written only in some runs (said in ``description``); ``style`` names a default style.
    """

    name: str
    geometry_type: str | None
    fields: Sequence[LayerField | tuple] = ()
    description: str = ""
    optional: bool = False
    style: str | None = None

    def __post_init__(self):
        if self.geometry_type is not None and \
                self.geometry_type.removesuffix(" Z") not in GEOMETRY_TYPES:
            raise ValueError(f"layer {self.name}: geometry type {self.geometry_type!r} is not one "
                             f"of {GEOMETRY_TYPES} (optionally with ' Z')")
        object.__setattr__(self, "fields", tuple(
            f if isinstance(f, LayerField) else LayerField(*f) for f in self.fields))

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "geometry_type": self.geometry_type,
                "fields": [{"name": f.name, "type": f.type, "description": f.description}
                           for f in self.fields],
                "description": self.description, "optional": self.optional, "style": self.style}


# -- destinations (outputs the user names) --------------------------------------------------------
class Destination(Parameter):
    """An output file the algorithm writes; also a declared output of the algorithm.

    ``layers`` declares the layers of a vector output (:class:`Layer`: name, geometry type, main
    fields), for a GUI and the docs; the runner does not enforce them (a test does).
    """

    is_output = True
    holds_paths = True
    extensions: Sequence[str] = ()

    def __init__(self, name: str, description: str = "", default: Any = None,
                 optional: bool = False, layers: Sequence[Layer] = (), **flags):
        super().__init__(name, description, default, optional, **flags)
        self.layers = list(layers)

    def validate(self, value: Any, ctx: ValidationContext) -> Path:
        if not isinstance(value, (str, Path)) or str(value).strip() == "":
            raise self.error(f"must be an output file path, got {_show(value)}")
        path = Path(value).expanduser()
        if self.extensions and path.suffix.lower() not in self.extensions:
            raise self.error(f"must end with {' or '.join(self.extensions)}, got "
                             f"{_show(str(value))}")
        resolved = path.resolve()
        if resolved in ctx.input_paths:
            raise self.error(f"{_show(str(value))} is also the input {ctx.input_paths[resolved]};"
                             " an input is never overwritten: choose another output path")
        if resolved in ctx.output_paths:
            raise self.error(f"{_show(str(value))} is also the output "
                             f"{ctx.output_paths[resolved]}")
        if path.is_dir():
            raise self.error(f"{_show(str(value))} is a folder, expected a file path")
        if path.exists() and not ctx.overwrite:
            raise OutputExistsError(self.name, f"{_show(str(value))} exists; pass --overwrite "
                                    "(OVERWRITE=True in Python) to replace it")
        ctx.output_paths[resolved] = self.name
        return path

    def expected(self) -> str:
        return f"output path ({', '.join(self.extensions)})" if self.extensions else "output path"

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"extensions": list(self.extensions),
                                     "layers": [layer.describe() for layer in self.layers]}


class OutputVector(Destination):
    """An output vector file; its extension picks the format (see :mod:`toolbox.io.vector`):
    ``.gpkg`` GeoPackage (the default: every layer in one file), ``.fgb`` FlatGeobuf,
    ``.parquet`` GeoParquet, ``.shp`` Shapefile, ``.geojson`` GeoJSON (one layer per file: the
    first layer in the path given, the others in ``<stem>_<layer><ext>`` beside it)."""

    type_name = "output_vector"
    #: the keys of toolbox.io.vector.VECTOR_DRIVERS (not imported here: ``help`` stays light)
    extensions = (".gpkg", ".fgb", ".parquet", ".shp", ".geojson")
    formats = "GeoPackage, FlatGeobuf, GeoParquet, Shapefile, GeoJSON"

    def validate(self, value: Any, ctx: ValidationContext) -> Path:
        if isinstance(value, (str, Path)) and str(value).strip() \
                and Path(value).suffix.lower() not in self.extensions:
            suffix = Path(value).suffix or "(no extension)"
            raise self.error(f"must be a vector file ending with {', '.join(self.extensions)} "
                             f"({self.formats}), got {_show(str(value))} with extension "
                             f"{_show(suffix)}")
        suffix = Path(value).suffix if isinstance(value, (str, Path)) else ""
        if suffix.lower() == ".shp" and suffix != ".shp":  # GDAL would write t.shp for t.SHP
            raise self.error(f"must end with '.shp' in lower case (GDAL names a Shapefile's "
                             f"files .shp, .shx, .dbf), got {_show(str(value))}")
        return super().validate(value, ctx)

    def expected(self) -> str:
        return f"output vector path ({', '.join(self.extensions)}; .gpkg by default)"


class OutputRaster(Destination):
    """An output GeoTIFF."""

    type_name = "output_raster"
    extensions = (".tif", ".tiff")


class OutputFile(Destination):
    """An output file of the given extensions (CSV, JSON, PDF...)."""

    type_name = "output_file"

    def __init__(self, name: str, description: str = "", extensions: Sequence[str] = (),
                 default: Any = None, optional: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.extensions = tuple(e.lower() for e in extensions)


class OutputFolder(Destination):
    """An output folder and the files it will hold (e.g. one per map sheet or per photo).

    The algorithm names those files in :meth:`~toolbox.algorithm.Algorithm.planned_files`; the
    runner checks each like an output path before any work (never an input, by path or inode;
    an existing one only with ``--overwrite``), hands the algorithm an empty staged folder and,
    on success, moves its files into this folder (other files already there are left alone).
    A failed or interrupted run leaves none of them.
    """

    type_name = "output_folder"

    def validate(self, value: Any, ctx: ValidationContext) -> Path:
        if not isinstance(value, (str, Path)) or str(value).strip() == "":
            raise self.error(f"must be an output folder path, got {_show(value)}")
        path = Path(value).expanduser()
        resolved = path.resolve()
        if resolved in ctx.input_paths:
            raise self.error(f"{_show(str(value))} is the input {ctx.input_paths[resolved]}; "
                             "expected a folder path")
        if path.exists() and not path.is_dir():
            raise self.error(f"{_show(str(value))} is a file, expected a folder path")
        ctx.output_paths[resolved] = self.name
        return path

    def expected(self) -> str:
        return "output folder path"


# -- value outputs (returned, not written) ---------------------------------------------------------
VALUE_TYPES = ("number", "integer", "string", "boolean", "json", "file")


class Output:
    """A value an algorithm returns besides its files: its type is one of :data:`VALUE_TYPES`
    (``json``: an object or list of statistics; ``file``: a path); ``dict``, ``list`` mean json."""

    def __init__(self, name: str, description: str = "", type_name: str = "json"):
        if not _NAME_RE.match(name):
            raise ValueError(f"output name {name!r} must be UPPERCASE")
        type_name = "json" if type_name in ("dict", "list") else type_name
        if type_name not in VALUE_TYPES:
            raise ValueError(f"output {name}: type {type_name!r} is not one of {VALUE_TYPES}")
        self.name, self.description, self.type_name = name, description, type_name

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "type": self.type_name, "description": self.description}
