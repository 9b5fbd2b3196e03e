"""Typed algorithm parameters (the QGIS Processing model: UPPERCASE names, defaults, validation).

Each parameter turns a user value (a Python object, or the text given on the command line) into the
normalised value the algorithm receives, or raises :class:`ParameterError` naming the parameter, the
value given and what was expected, e.g. ``CELL_SIZE must be > 0, got -2``. Validation runs once, in
the runner, before any work starts.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.errors import OutputExistsError, ParameterError

_NAME_RE = re.compile(r"^[A-Z][A-Z0-9_]*$")
_TRUE = {"true", "yes", "1", "on", "y", "t"}
_FALSE = {"false", "no", "0", "off", "n", "f"}


def _show(value: Any) -> str:
    """Short representation of a user value for error messages."""
    text = repr(value) if isinstance(value, str) else str(value)
    return text if len(text) <= 120 else text[:117] + "..."


@dataclass
class ValidationContext:
    """What validation of one parameter may need to know about the others."""

    values: dict[str, Any] = field(default_factory=dict)
    input_paths: dict[Path, str] = field(default_factory=dict)  # resolved path -> parameter name
    output_paths: dict[Path, str] = field(default_factory=dict)
    overwrite: bool = False


# Execution settings a GUI shows under "Advanced" in every algorithm that has them.
ADVANCED_NAMES = frozenset({"TILE_SIZE", "WORKERS", "SCHEDULER", "MAX_CELLS"})


class Parameter:
    """Base class: a named, typed algorithm parameter.

    ``description`` is the one-line label, ``help`` an optional longer text (a GUI's tooltip).
    ``optional`` means the value may be left empty (the algorithm then does without it); it is
    separate from ``default``, the value used when none is given. ``advanced`` parameters are
    shown apart (defaults to True for :data:`ADVANCED_NAMES`), ``hidden`` ones not at all.
    ``deprecated_names`` are older names still accepted, with a warning.
    """

    type_name = "any"
    is_output = False

    def __init__(self, name: str, description: str = "", default: Any = None,
                 optional: bool = False, *, help: str = "", advanced: bool | None = None,
                 hidden: bool = False, deprecated_names: Sequence[str] = ()):
        if not _NAME_RE.match(name):
            raise ValueError(f"parameter name {name!r} must be UPPERCASE (A-Z, 0-9, _)")
        self.name = name
        self.description = description
        self.help = help
        self.default = default
        self.optional = optional
        self.advanced = name in ADVANCED_NAMES if advanced is None else advanced
        self.hidden = hidden
        self.deprecated_names = tuple(deprecated_names)

    @property
    def required(self) -> bool:
        """True when the user must give a value (not optional and no default)."""
        return not self.optional and self.default is None

    def error(self, message: str) -> ParameterError:
        return ParameterError(self.name, message)

    def resolve(self, value: Any, ctx: ValidationContext) -> Any:
        """Apply the default, check presence, then :meth:`validate`."""
        if value is None or (isinstance(value, str) and value == "" and not self.is_output):
            if self.default is not None:
                value = self.default
            elif self.optional:
                return None
            else:
                raise self.error(f"is required ({self.expected()})")
        return self.validate(value, ctx)

    def validate(self, value: Any, ctx: ValidationContext) -> Any:
        return value

    def expected(self) -> str:
        """Human description of the accepted values, used in messages and help."""
        return self.type_name

    def describe(self) -> dict[str, Any]:
        """Machine-readable description for ``toolbox help --json``."""
        default = self.default
        if default is not None and not isinstance(default, (str, int, float, bool, list)):
            default = str(default)
        return {"name": self.name, "type": self.type_name, "description": self.description,
                "help": self.help, "default": default, "optional": self.optional,
                "required": self.required, "advanced": self.advanced, "hidden": self.hidden,
                "deprecated_names": list(self.deprecated_names), "expected": self.expected()}


# -- scalars --------------------------------------------------------------------------------------
class Number(Parameter):
    """A real number with an optional range; ``min_exclusive`` makes the lower bound strict."""

    type_name = "number"

    def __init__(self, name: str, description: str = "", default: float | None = None,
                 optional: bool = False, min_value: float | None = None,
                 max_value: float | None = None, min_exclusive: bool = False,
                 max_exclusive: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.min_value, self.max_value = min_value, max_value
        self.min_exclusive, self.max_exclusive = min_exclusive, max_exclusive

    def _convert(self, value: Any) -> float:
        if isinstance(value, bool):
            raise self.error(f"must be a number, got {_show(value)}")
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise self.error(f"must be a number, got {_show(value)}") from None
        if not math.isfinite(number):
            raise self.error(f"must be a finite number, got {_show(value)}")
        return number

    def validate(self, value: Any, ctx: ValidationContext) -> float:
        number = self._convert(value)
        shown = _show(value) if isinstance(value, str) else f"{number:g}"
        if self.min_value is not None:
            if number < self.min_value or (self.min_exclusive and number == self.min_value):
                op = ">" if self.min_exclusive else ">="
                raise self.error(f"must be {op} {self.min_value:g}, got {shown}")
        if self.max_value is not None:
            if number > self.max_value or (self.max_exclusive and number == self.max_value):
                op = "<" if self.max_exclusive else "<="
                raise self.error(f"must be {op} {self.max_value:g}, got {shown}")
        return number

    def expected(self) -> str:
        parts = []
        if self.min_value is not None:
            parts.append(f"{'>' if self.min_exclusive else '>='} {self.min_value:g}")
        if self.max_value is not None:
            parts.append(f"{'<' if self.max_exclusive else '<='} {self.max_value:g}")
        return self.type_name + (" " + " and ".join(parts) if parts else "")

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"min": self.min_value, "max": self.max_value,
                                     "min_exclusive": self.min_exclusive,
                                     "max_exclusive": self.max_exclusive}


class Integer(Number):
    """An integer with an optional range."""

    type_name = "integer"

    def validate(self, value: Any, ctx: ValidationContext) -> int:
        number = self._convert(value)
        if number != int(number):
            raise self.error(f"must be an integer, got {_show(value)}")
        if not abs(number) < 2.0 ** 63:  # what numpy and C code can hold (as a float)
            raise self.error(f"is too large for an integer (at most {2 ** 63 - 1:.3g} in size), "
                             f"got {_show(value)}")
        return int(super().validate(value, ctx))


class Boolean(Parameter):
    """True/false; text accepts true/false, yes/no, 1/0, on/off."""

    type_name = "boolean"

    def validate(self, value: Any, ctx: ValidationContext) -> bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        text = str(value).strip().lower()
        if text in _TRUE:
            return True
        if text in _FALSE:
            return False
        raise self.error(f"must be true or false, got {_show(value)}")

    def expected(self) -> str:
        return "boolean (true/false)"


class String(Parameter):
    type_name = "string"

    def validate(self, value: Any, ctx: ValidationContext) -> str:
        if not isinstance(value, (str, int, float)):
            raise self.error(f"must be text, got {_show(value)}")
        return str(value)


class Enum(Parameter):
    """One of a fixed list of lowercase options (matched case-insensitively)."""

    type_name = "enum"

    def __init__(self, name: str, description: str = "", options: Sequence[str] = (),
                 default: str | None = None, optional: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        if not options:
            raise ValueError(f"{name}: an Enum needs options")
        self.options = list(options)
        if default is not None and default not in self.options:
            raise ValueError(f"{name}: default {default!r} is not among {self.options}")

    def validate(self, value: Any, ctx: ValidationContext) -> str:
        text = str(value).strip()
        for option in self.options:
            if text.lower() == option.lower():
                return option
        raise self.error(f"must be one of {', '.join(self.options)}; got {_show(value)}")

    def expected(self) -> str:
        return "one of " + ", ".join(self.options)

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"options": self.options}


class Crs(Parameter):
    """A coordinate reference system pyproj knows: ``EPSG:3003``, WKT, PROJ string or a CRS."""

    type_name = "crs"

    def validate(self, value: Any, ctx: ValidationContext):
        from toolbox.io.crs import parse_crs

        return parse_crs(value, self.name)

    def expected(self) -> str:
        return "a CRS (e.g. EPSG:3003, WKT or PROJ string)"


@dataclass(frozen=True)
class Extent:
    """A rectangle in map units: (xmin, ymin, xmax, ymax), optionally with its CRS."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float
    crs: Any = None

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (self.xmin, self.ymin, self.xmax, self.ymax)

    @property
    def width(self) -> float:
        return self.xmax - self.xmin

    @property
    def height(self) -> float:
        return self.ymax - self.ymin


class ExtentParameter(Parameter):
    """An extent as ``"xmin,ymin,xmax,ymax"`` (GDAL ``-te`` and shapely/rasterio bounds order),
    optionally followed by ``" [EPSG:3003]"``; or a sequence of four numbers, or an :class:`Extent`.
    """

    type_name = "extent"

    def validate(self, value: Any, ctx: ValidationContext) -> Extent:
        if isinstance(value, Extent):
            numbers, crs = list(value.bounds), value.crs
        else:
            crs = None
            if isinstance(value, str):
                text = value.strip()
                match = re.match(r"^(.*?)\s*\[(.+)\]\s*$", text)
                if match:
                    text, crs_text = match.group(1), match.group(2)
                    from toolbox.io.crs import parse_crs

                    crs = parse_crs(crs_text, self.name)
                parts = [p for p in re.split(r"[,\s]+", text) if p]
            elif isinstance(value, Sequence):
                parts = list(value)
            else:
                parts = []
            try:
                numbers = [float(p) for p in parts]
            except (TypeError, ValueError):
                numbers = []
            if len(numbers) != 4 or not all(math.isfinite(n) for n in numbers):
                raise self.error(f"must be 'xmin,ymin,xmax,ymax', got {_show(value)}")
        xmin, ymin, xmax, ymax = numbers
        if not (xmin < xmax and ymin < ymax):
            raise self.error(
                f"must have xmin < xmax and ymin < ymax (order xmin,ymin,xmax,ymax), got "
                f"{_show(value)}")
        return Extent(xmin, ymin, xmax, ymax, crs)

    def expected(self) -> str:
        return "extent 'xmin,ymin,xmax,ymax [CRS]'"


# -- files and layers -----------------------------------------------------------------------------
def _existing_path(param: Parameter, value: Any) -> Path:
    if not isinstance(value, (str, Path)):
        raise param.error(f"must be a file path, got {_show(value)}")
    path = Path(value).expanduser()
    if not path.exists():
        raise param.error(f"file {_show(str(value))} does not exist")
    return path


class File(Parameter):
    """An existing input file, optionally restricted to some extensions (lowercase, with dot)."""

    type_name = "file"

    def __init__(self, name: str, description: str = "", extensions: Sequence[str] = (),
                 default: Any = None, optional: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.extensions = [e.lower() for e in extensions]

    def validate(self, value: Any, ctx: ValidationContext) -> Path:
        path = _existing_path(self, value)
        if self.extensions and path.suffix.lower() not in self.extensions:
            raise self.error(f"must be a {'/'.join(self.extensions)} file, got {_show(str(value))}")
        if path.is_dir():
            raise self.error(f"must be a file, got the folder {_show(str(value))}")
        ctx.input_paths[path.resolve()] = self.name
        return path

    def expected(self) -> str:
        return "existing file" + (f" ({', '.join(self.extensions)})" if self.extensions else "")

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"extensions": self.extensions}


class Folder(Parameter):
    """An existing input folder (QGIS shows a folder picker)."""

    type_name = "folder"

    def validate(self, value: Any, ctx: ValidationContext) -> Path:
        if not isinstance(value, (str, Path)):
            raise self.error(f"must be a folder path, got {_show(value)}")
        path = Path(value).expanduser()
        if not path.is_dir():
            what = "is a file, not a folder" if path.exists() else "does not exist"
            raise self.error(f"folder {_show(str(value))} {what}")
        return path

    def expected(self) -> str:
        return "existing folder"


class VectorLayer(Parameter):
    """A vector layer OGR can read: ``path`` or a QGIS layer source ``path|layername=name``
    (also ``|layerid=N``, ``|geometrytype=Point``, ``|subset=SQL WHERE``), or a GeoDataFrame in
    Python. ``geometry_types`` restricts the kind: any of point, line, polygon.
    CSV files are read as points from X/Y(/Z) columns (see :mod:`toolbox.io.vector`).
    ``point_clouds=True`` also accepts a LAS/LAZ/COPC file (validated to a
    :class:`toolbox.io.pointcloud.PointCloudRef`; the algorithm must read both kinds).
    """

    type_name = "vector"

    def __init__(self, name: str, description: str = "",
                 geometry_types: Sequence[str] | None = None, default: Any = None,
                 optional: bool = False, point_clouds: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.geometry_types = list(geometry_types) if geometry_types else None
        self.point_clouds = point_clouds

    def validate(self, value: Any, ctx: ValidationContext):
        from toolbox.io.vector import open_layer

        if self.point_clouds:
            from toolbox.io.pointcloud import PointCloudRef, is_point_cloud_path, open_point_cloud

            if isinstance(value, PointCloudRef) or is_point_cloud_path(value):
                cloud = open_point_cloud(value, self.name)
                ctx.input_paths[cloud.path.resolve()] = self.name
                return cloud
        layer = open_layer(value, self.name)
        if layer.path is not None:
            ctx.input_paths[layer.path.resolve()] = self.name
        if self.geometry_types and layer.geometry_kind is not None \
                and layer.geometry_kind not in self.geometry_types:
            raise self.error(f"must be a {'/'.join(self.geometry_types)} layer, got "
                             f"{layer.geometry_type} features in {layer}")
        if self.geometry_types and layer.geometry_kind is None and layer.geometry_type is None:
            raise self.error(f"must be a {'/'.join(self.geometry_types)} layer, but {layer} has "
                             "no geometry (for CSV, name the columns X, Y and optionally Z)")
        return layer

    def expected(self) -> str:
        kinds = "/".join(self.geometry_types) if self.geometry_types else "any"
        return f"vector layer ({kinds}): path or QGIS source 'path|layername=...|subset=...'"

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"geometry_types": self.geometry_types} | \
            ({"point_clouds": True} if self.point_clouds else {})


class RasterLayer(Parameter):
    """A raster GDAL can read (GeoTIFF, JPEG, PNG, ...)."""

    type_name = "raster"

    def validate(self, value: Any, ctx: ValidationContext):
        from toolbox.io.raster import open_raster_info

        info = open_raster_info(value, self.name)
        ctx.input_paths[info.path.resolve()] = self.name
        return info

    def expected(self) -> str:
        return "raster file GDAL can read"


class MultipleLayers(Parameter):
    """Several layers of one kind: a list in Python/YAML, the option repeated on the command line."""

    type_name = "multiple"

    def __init__(self, name: str, description: str = "", layer_type: str = "vector",
                 min_count: int = 1, default: Any = None, optional: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        if layer_type not in ("vector", "raster"):
            raise ValueError("layer_type must be 'vector' or 'raster'")
        self.layer_type, self.min_count = layer_type, min_count
        self._item = (VectorLayer if layer_type == "vector" else RasterLayer)(name)

    def validate(self, value: Any, ctx: ValidationContext) -> list:
        items = [value] if isinstance(value, (str, Path)) else list(value)
        if len(items) < self.min_count:
            raise self.error(f"needs at least {self.min_count} {self.layer_type} layers, "
                             f"got {len(items)}")
        return [self._item.validate(item, ctx) for item in items]

    def expected(self) -> str:
        return f"{self.min_count}+ {self.layer_type} layers (repeat the option)"

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"layer_type": self.layer_type, "min_count": self.min_count}


class Field(Parameter):
    """A field (column) of the vector layer given in parameter ``parent``."""

    type_name = "field"

    def __init__(self, name: str, description: str = "", parent: str = "INPUT",
                 numeric: bool = False, default: Any = None, optional: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.parent, self.numeric = parent, numeric

    def validate(self, value: Any, ctx: ValidationContext) -> str:
        layer = ctx.values.get(self.parent)
        name = str(value)
        if layer is None:
            raise self.error(f"names field {_show(name)} but {self.parent} is not given")
        fields = layer.fields
        if name not in fields:
            matches = [f for f in fields if f.lower() == name.lower()]
            if len(matches) != 1:
                raise self.error(f"field {_show(name)} is not in {layer}; fields are: "
                                 f"{', '.join(fields) or '(none)'}")
            name = matches[0]
        if self.numeric and not layer.is_numeric(name):
            raise self.error(f"field {_show(name)} of {layer} must be numeric, it is "
                             f"{layer.field_types[name]}")
        return name

    def expected(self) -> str:
        return f"{'numeric ' if self.numeric else ''}field of {self.parent}"

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"parent": self.parent, "numeric": self.numeric}


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
