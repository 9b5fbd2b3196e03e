"""Parameters and parameter-file handling shared by the editing algorithms."""

from __future__ import annotations

from typing import Any

from toolbox.io.parameter_file import ParameterFile, optional_parameter_file, resolve
from toolbox.parameters import File

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
    file: ParameterFile | None = optional_parameter_file(params)
    values, sources = {}, {}
    for name, (attr, key, default) in wanted.items():
        values[attr], sources[attr] = resolve(params.get(name), file, key, default)
    if "precision" in values and sources["precision"] == "file":
        values["precision"] = 10.0 ** -values["precision"]
    if file is not None:
        used = {key for _, key, _ in wanted.values()} | set(COMMON_ENTRIES)
        file.warn_unused(used, feedback, f"{who} (its input is in map coordinates, so a "
                                         "coordinate translation is not applied)"
                         if "coordinate_offset" in file.values else who)
        file.check_unit(crs, feedback)
    return values, sources
