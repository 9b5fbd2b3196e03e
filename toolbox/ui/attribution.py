"""The attribution algorithms' shared parameters: restitution files, the parameter file and
its values, the declared output layers (light: parameters only, no kernels)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.io.parameter_file import ParameterFile, optional_parameter_file, resolve
from toolbox.parameters import File, Parameter, ValidationContext
from toolbox.parameters.outputs import Layer, OutputVector

CODED = Layer("*", "Geometry", [("code", "string", "restitution code"),
                                ("description", "string", "from the code file"),
                                ("colour", "string", "#rrggbb")],
              "one layer per code (or per geometry type), named after it; styled")
MOVED_VERTICES = Layer("moved_vertices", "Point", [
    ("feature", "string"), ("vertex", "integer"), ("change", "string"), ("dx", "real"),
    ("dy", "real"), ("displacement", "real", "how far it moved")],
    "every vertex the tool moved, added or removed")


def edited_output(description: str) -> OutputVector:
    """The OUTPUT of an editing tool: the edited layer (named like the input's) and the
    ``moved_vertices`` layer."""
    return OutputVector("OUTPUT", description, layers=[CODED, MOVED_VERTICES])


class RestitutionFiles(Parameter):
    """One or more restitution files (repeat the option: one per stereo model, merged): the
    ASCII export, a DXF, or any vector file OGR reads (``path`` or ``path|layername=name``)."""

    type_name = "multiple"

    def validate(self, value: Any, ctx: ValidationContext) -> list[str]:
        items = [value] if isinstance(value, (str, Path)) or hasattr(value, "geometry") \
            else list(value)
        if not items:
            raise self.error("needs at least one restitution file")
        out = []
        for item in items:
            if hasattr(item, "geometry"):  # a GeoDataFrame in Python
                out.append(item)
                continue
            text = str(item)
            path = Path(text.split("|", 1)[0]).expanduser()
            if not path.is_file():
                raise self.error(f"file '{path}' does not exist")
            ctx.input_paths[path.resolve()] = self.name
            out.append(text)
        return out

    def expected(self) -> str:
        return ("restitution file(s): ASCII export (CODE/E N Z/END), DXF or an OGR layer with a "
                "code field; repeat for several models")


#: entries every editing algorithm uses: the unit (checked against the CRS) and the decimals
#: (the grid on which vertices are one shared node)
COMMON_ENTRIES = ("coordinate_unit", "decimals")


def parameter_file_parameter() -> File:
    return File("PARAMETERS", "parameter file ('file dei parametri'); explicit values win",
                optional=True)


def file_values(params: dict[str, Any], wanted: dict[str, tuple[str, str, Any]], who: str,
                feedback: Any, crs: Any = None) -> tuple[dict[str, Any], dict[str, str]]:
    """Resolve ``wanted`` (parameter name -> (attribute, file key, default)) from the explicit
    parameters, the PARAMETERS file and the defaults; warn about the file's other entries.

    The coordinate translation is never applied here: these algorithms read layers already in
    map coordinates (the importers, ``attribution:apply`` and ``topology:*``, apply it); when the
    file gives one it is named in the warning with the others.
    """
    file: ParameterFile | None = optional_parameter_file(params.get("PARAMETERS"))
    values, sources = {}, {}
    for name, (attr, key, default) in wanted.items():
        values[attr], sources[attr] = resolve(params.get(name), file, key, default)
    if file is not None:
        used = {key for _, key, _ in wanted.values()} | set(COMMON_ENTRIES)
        file.warn_unused(used, feedback, f"{who} (its input is in map coordinates, so a "
                                         "coordinate translation is not applied)"
                         if "coordinate_offset" in file.values else who)
        file.check_unit(crs, feedback)
    return values, sources
