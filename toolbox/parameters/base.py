"""The parameter base class and what validation of one parameter may know of the others."""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.errors import ParameterError

_NAME_RE = re.compile(r"^[A-Z][A-Z0-9_]*$")
_TRUE = {"true", "yes", "1", "on", "y", "t"}
_FALSE = {"false", "no", "0", "off", "n", "f"}


def _show(value: Any) -> str:
    """Short representation of a user value for error messages."""
    text = repr(value) if isinstance(value, str) else str(value)
    return text if len(text) <= 120 else text[:117] + "..."


_SPECIAL_FILES = ((stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket"),
                  (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def special_file(value: Any) -> tuple[str, str] | None:
    """``(path, what)`` when ``value`` (a path, ``path|layername=...``, comma-separated paths, or
    a list of them) names a named pipe, a socket or a device: opening one blocks until another
    program writes to it (GDAL's open of a FIFO never returns) or reads endless bytes."""
    for item in value if isinstance(value, (list, tuple)) else [value]:
        if not isinstance(item, (str, os.PathLike)):
            continue
        text = os.fspath(item)
        if not isinstance(text, str):
            continue
        for candidate in dict.fromkeys([text, text.partition("|")[0], *text.split(",")]):
            try:
                mode = os.stat(os.path.expanduser(candidate.strip())).st_mode
            except (OSError, ValueError):
                continue
            for test, what in _SPECIAL_FILES:
                if test(mode):
                    return candidate.strip(), what
    return None


def _blank(item: Any) -> bool:
    """Whether a list item names nothing: None or text of blanks."""
    return item is None or (isinstance(item, str) and not item.strip())


def refuse_empty_items(param: Parameter, items: Sequence[Any], value: Any,
                       expected: str | None = None) -> None:
    """Refuse a list of paths with an empty item (``--LAYERS ''``, ``[a.gpkg, '', b.gpkg]``,
    ``'a.tif,,b.tif'``): one line naming the parameter, the value and what was expected, where
    an item left out would silently do without it. The one check of every list-of-files
    parameter (:class:`~toolbox.parameters.sources.MultipleLayers`, a ``String(paths=True)``'s
    comma-separated list)."""
    empty = [i for i, item in enumerate(items, 1) if _blank(item)]
    if empty:
        where = f"an empty item {empty[0]}" if len(empty) == 1 else \
            f"empty items {', '.join(map(str, empty))}"
        raise param.error(f"has {where} of {len(items)} in {_show(value)}; expected "
                          f"{expected or param.expected()}, none empty")


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
    holds_paths = False  # the value is a path or paths (files, folders, layers, outputs)

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
        if self.holds_paths and not self.is_output:  # before anything opens it
            special = special_file(value)
            if special is not None:
                kind = "folder" if self.type_name == "folder" else "regular file"
                raise self.error(f"{_show(special[0])} is {special[1]}; give a {kind}")
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

