"""Input files and layers: files, folders, vector and raster layers, fields."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from toolbox.parameters.base import Parameter, ValidationContext, _show, refuse_empty_items


def _refuse_virtual(param: Parameter, value: Any) -> None:
    """Refuse a GDAL virtual path (``/vsizip/...``, ``/vsicurl/...``): inputs are files on disk
    (so that outputs are checked against them and never replace them)."""
    if isinstance(value, (str, Path)) and str(value).startswith("/vsi"):
        raise param.error(f"{_show(str(value))}: GDAL virtual file systems (/vsi...) are not "
                          "supported: unzip (or download) the file first")


def _existing_path(param: Parameter, value: Any) -> Path:
    if not isinstance(value, (str, Path)):
        raise param.error(f"must be a file path, got {_show(value)}")
    _refuse_virtual(param, value)
    path = Path(value).expanduser()
    if not path.exists():
        base, bar, rest = str(value).partition("|")
        if bar and Path(base).expanduser().is_file():  # 'file.gpkg|layername=points'
            raise param.error(f"takes a file, not a layer reference: {_show(str(value))} (the "
                              f"file exists; a GeoPackage is read from its first layer: copy "
                              f"the layer into a file of its own first, e.g. ogr2ogr "
                              f"out.gpkg {Path(base).name} {rest.partition('=')[2] or 'LAYER'})")
        raise param.error(f"file {_show(str(value))} does not exist")
    return path


class File(Parameter):
    """An existing input file, optionally restricted to some extensions (lowercase, with dot)."""

    type_name = "file"
    holds_paths = True

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
    holds_paths = True

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
    ``known_layer``: the layer taken from a file of several given without one, when it has it
    (a toolbox output's layer: see :func:`toolbox.io.vector.open_layer`).
    ``summarise``: a GeoPackage given by its path alone that :func:`toolbox.io.gpkg_summary.
    summarise` describes for certain (points, in the standard library: no numpy, pyogrio or
    shapely) is validated to a :class:`~toolbox.io.gpkg_summary.GpkgSummary` holding that
    description (``vector:info``); any other value as without it.
    """

    type_name = "vector"
    holds_paths = True

    def __init__(self, name: str, description: str = "",
                 geometry_types: Sequence[str] | None = None, default: Any = None,
                 optional: bool = False, point_clouds: bool = False,
                 known_layer: str | None = None, summarise: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.geometry_types = list(geometry_types) if geometry_types else None
        self.point_clouds = point_clouds
        self.known_layer = known_layer
        self.summarise = summarise

    def validate(self, value: Any, ctx: ValidationContext):
        _refuse_virtual(self, value)
        if self.summarise and isinstance(value, (str, Path)) and "|" not in str(value) \
                and str(value).lower().endswith(".gpkg") and Path(value).expanduser().is_file():
            from toolbox.io.gpkg_summary import GpkgSummary, summarise

            path = Path(value).expanduser()
            layers = summarise(path)
            if layers is not None:
                ctx.input_paths[path.resolve()] = self.name
                return GpkgSummary(path, layers)
        from toolbox.io.vector import open_layer

        if self.point_clouds:
            from toolbox.io.pointcloud import PointCloudRef, is_point_cloud_path, open_point_cloud

            if isinstance(value, PointCloudRef) or is_point_cloud_path(value):
                cloud = open_point_cloud(value, self.name)
                ctx.input_paths[cloud.path.resolve()] = self.name
                return cloud
        layer = open_layer(value, self.name, self.known_layer)
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


#: what a raster input is (:class:`RasterLayer`'s ``role``): a photo (read in pixels: no
#: geotransform, GCPs or RPCs are fine), a map raster (an ortho, a base map, a template grid:
#: georeferenced) or heights (a DEM: georeferenced, and the band read holds heights)
RASTER_ROLES = ("photo", "map", "heights")


class RasterLayer(Parameter):
    """A raster GDAL can read (GeoTIFF, JPEG, PNG, ...), validated to a
    :class:`toolbox.io.raster.RasterInfo`.

    ``role`` (one of :data:`RASTER_ROLES`) says what the algorithm reads in
    it: ``"map"`` (the default: an ortho, a base map, a template grid) and ``"heights"`` (a
    DEM) must be georeferenced; a ``"heights"`` band must hold heights, not colours (the
    runner checks the band read, :func:`toolbox.io.raster.require_height_band`); a
    ``"photo"`` is read in pixel coordinates (no geotransform, GCPs or RPCs are fine).
    """

    type_name = "raster"
    holds_paths = True

    def __init__(self, name: str, description: str = "", default: Any = None,
                 optional: bool = False, role: str = "map", **flags):
        super().__init__(name, description, default, optional, **flags)
        if role not in RASTER_ROLES:
            raise ValueError(f"role must be one of {RASTER_ROLES}, got {role!r}")
        self.role = role

    def validate(self, value: Any, ctx: ValidationContext):
        from toolbox.io.raster import open_raster_info

        _refuse_virtual(self, value)
        info = open_raster_info(value, self.name, self.role)
        ctx.input_paths[info.path.resolve()] = self.name
        return info

    def expected(self) -> str:
        return {"photo": "raster file GDAL can read", "map": "georeferenced raster file",
                "heights": "georeferenced raster of heights (DEM)"}[self.role]

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"role": self.role}


class MultipleLayers(Parameter):
    """Several layers of one kind: a list in Python/YAML, the option repeated on the command line."""

    type_name = "multiple"
    holds_paths = True

    def __init__(self, name: str, description: str = "", layer_type: str = "vector",
                 min_count: int = 1, default: Any = None, optional: bool = False,
                 role: str = "map", **flags):
        super().__init__(name, description, default, optional, **flags)
        if layer_type not in ("vector", "raster"):
            raise ValueError("layer_type must be 'vector' or 'raster'")
        self.layer_type, self.min_count = layer_type, min_count
        self._item = VectorLayer(name) if layer_type == "vector" else RasterLayer(name, role=role)

    def resolve(self, value: Any, ctx: ValidationContext) -> Any:
        """As :meth:`Parameter.resolve`, but an empty text (``--LAYERS ''``) is one empty item,
        refused, not "no layers" (the sheet was drawn without the layer)."""
        if isinstance(value, str) and not value.strip():
            refuse_empty_items(self, [value], value)
        return super().resolve(value, ctx)

    def validate(self, value: Any, ctx: ValidationContext) -> list:
        items = [value] if isinstance(value, (str, Path)) else list(value)
        refuse_empty_items(self, items, value)
        if self.layer_type == "raster":  # a folder (ortho:batch's FOLDER): its GeoTIFFs
            items = [f for item in items for f in self._folder_rasters(item)]
        if len(items) < self.min_count:
            raise self.error(f"needs at least {self.min_count} {self.layer_type} layers, "
                             f"got {len(items)}")
        return [self._item.validate(item, ctx) for item in items]

    def _folder_rasters(self, item: Any) -> list:
        """``item``, or the GeoTIFFs of the folder ``item`` names (sorted by name; hidden
        files left), as ortho:batch writes its orthos into FOLDER."""
        if not isinstance(item, (str, Path)) or not Path(item).expanduser().is_dir():
            return [item]
        folder = Path(item).expanduser()
        files = sorted(f for f in folder.iterdir() if f.is_file() and not
                       f.name.startswith(".") and f.suffix.lower() in (".tif", ".tiff"))
        if not files:
            raise self.error(f"the folder {_show(str(item))} holds no GeoTIFF (.tif)")
        return [str(f) for f in files]

    def expected(self) -> str:
        return f"{self.min_count}+ {self.layer_type} layers (repeat the option)" + (
            ", or a folder of GeoTIFFs" if self.layer_type == "raster" else "")

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"layer_type": self.layer_type, "min_count": self.min_count} \
            | ({"role": self._item.role} if self.layer_type == "raster" else {})


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
                raise self.error(f"field {_show(name)} is not in {layer}; "
                                 f"{self._fields_are(layer)}")
            name = matches[0]
        if self.numeric and not layer.is_numeric(name):
            raise self.error(f"field {_show(name)} of {layer} must be numeric, it is "
                             f"{layer.field_types[name]}")
        return name

    def _fields_are(self, layer) -> str:
        """The layer's fields, as a message lists them; a CSV's X/Y/Z columns included, said
        to be read as the point geometry (the layer's fields leave them out: "fields are:
        (none)" on an x,y,z CSV sent the user looking for columns they could see)."""
        coordinates = list(getattr(layer, "coordinate_columns", []))
        if not coordinates:
            return f"fields are: {', '.join(layer.fields) or '(none)'}"
        axes = "X, Y, Z"[:3 * len(coordinates) - 2]
        text = (f"columns are: {', '.join(coordinates + layer.fields)} ({', '.join(coordinates)}"
                f" read as the points' {axes}, not as fields")
        if len(coordinates) == 3 and self.name.endswith("Z_FIELD"):
            text += f"; leave {self.name} out for the heights of {coordinates[2]}"
        return text + ")"

    def expected(self) -> str:
        return f"{'numeric ' if self.numeric else ''}field of {self.parent}"

    def describe(self) -> dict[str, Any]:
        return super().describe() | {"parent": self.parent, "numeric": self.numeric}

