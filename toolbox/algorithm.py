"""The algorithm contract.

An algorithm is a small class: a declarative spec (id ``group:name``, display name, group, help,
typed parameters, outputs) and a thin :meth:`Algorithm.process` that reads inputs, calls numeric
kernels and writes outputs. The runner validates parameters before ``process`` is called, and
hands over *staged* paths for output files (renamed into place only on success).

Example
-------
>>> from toolbox.algorithm import Algorithm
>>> from toolbox.parameters import Number, OutputRaster
>>> from toolbox.registry import register
>>> @register  # doctest: +SKIP
... class Example(Algorithm):
...     "Long help text: what it does, the method, the formula's source."
...     id = "example:constant"
...     display_name = "Constant raster"
...     group = "Examples"
...     short_help = "Writes a raster of one value."
...     parameters = [Number("VALUE", "the value", default=1.0),
...                   OutputRaster("OUTPUT", "the raster")]
...     def process(self, params, feedback):
...         ...
...         return {"OUTPUT": params["OUTPUT"]}
"""

from __future__ import annotations

import inspect
import logging
import re
import warnings
from typing import Any, ClassVar

from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import Destination, Field, Output, OutputFolder, Parameter

ID_RE = re.compile(r"^[a-z][a-z0-9_]*:[a-z][a-z0-9_]*$")


def _output_spec(dest: Destination) -> dict[str, Any]:
    """A destination as an output: name, type, description, and its file facts (extensions,
    declared layers)."""
    described = dest.describe()
    return {"name": dest.name, "type": dest.type_name, "description": dest.description,
            "optional": dest.optional, "extensions": described.get("extensions", []),
            "layers": described.get("layers", [])}


class Algorithm:
    """Base class of every algorithm. Subclass, fill the spec, implement :meth:`process`."""

    id: ClassVar[str] = ""
    display_name: ClassVar[str] = ""
    group: ClassVar[str] = ""
    short_help: ClassVar[str] = ""
    parameters: ClassVar[list[Parameter]] = []
    outputs: ClassVar[list[Output]] = []
    # the algorithm works in metres (cell sizes, tolerances, slopes, volumes): the runner refuses
    # inputs in a geographic CRS and coordinates far outside their CRS's area of use
    projected_crs_only: ClassVar[bool] = True
    # the units its lengths may be in (:func:`toolbox.io.crs.not_metric`): "metre" (scales,
    # tolerances, photogrammetry), "one" (any one unit for x, y and heights: slopes, volumes),
    # "horizontal" (any one unit for x, y; heights in theirs: gridding, TINs, contours)
    length_units: ClassVar[str] = "metre"
    # its CRS parameter is the CRS of the inputs that name none (so the runner checks their
    # coordinates against its area of use); False where CRS is the output's only
    crs_labels_inputs: ClassVar[bool] = True
    # why a raster output can have no valid cell when the inputs are fine (the runner's refusal
    # names it when the algorithm has no EXTENT, TEMPLATE, MASK or CELL_SIZE to blame)
    empty_output_hint: ClassVar[str | None] = None

    # -- spec --------------------------------------------------------------------------------------
    @classmethod
    def group_id(cls) -> str:
        return cls.id.split(":", 1)[0]

    @classmethod
    def help_text(cls) -> str:
        """The long help: the class docstring."""
        return inspect.cleandoc(cls.__doc__ or cls.short_help)

    @classmethod
    def parameter(cls, name: str) -> Parameter:
        for p in cls.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    @classmethod
    def destinations(cls) -> list[Destination]:
        return [p for p in cls.parameters if isinstance(p, Destination)]

    @classmethod
    def spec(cls) -> dict[str, Any]:
        """Machine-readable description (``toolbox help ID --json``)."""
        return {
            "id": cls.id, "display_name": cls.display_name, "group": cls.group,
            "group_id": cls.group_id(), "short_help": cls.short_help, "help": cls.help_text(),
            "parameters": [p.describe() for p in cls.parameters],
            "outputs": [_output_spec(p) for p in cls.destinations()]
                       + [o.describe() for o in cls.outputs],
        }

    @classmethod
    def rename_deprecated(cls, params: dict[str, Any]) -> dict[str, Any]:
        """``params`` with deprecated parameter names replaced by the current ones (a
        :class:`DeprecationWarning` and a log warning each); both names given is an error."""
        renamed = dict(params)
        for p in cls.parameters:
            for old in p.deprecated_names:
                if old not in renamed:
                    continue
                if p.name in renamed:
                    raise ParameterError(old, f"is the old name of {p.name}; give only {p.name}")
                renamed[p.name] = renamed.pop(old)
                message = f"{cls.id}: parameter {old} is now called {p.name}; use {p.name}"
                warnings.warn(message, DeprecationWarning, stacklevel=3)
                logging.getLogger("toolbox").warning(message)
        return renamed

    @classmethod
    def check_spec(cls) -> None:
        """Raise ``TypeError`` when the declaration is inconsistent (called at registration)."""
        if not ID_RE.match(cls.id or ""):
            raise TypeError(f"{cls.__name__}: id {cls.id!r} must be 'group:name' in lowercase")
        if not (cls.display_name and cls.group and cls.short_help):
            raise TypeError(f"{cls.id}: display_name, group and short_help are required")
        seen: set[str] = set()
        all_names = [n for p in cls.parameters for n in (p.name, *p.deprecated_names)]
        for p in cls.parameters:
            if all_names.count(p.name) > 1 or any(all_names.count(n) > 1
                                                   for n in p.deprecated_names):
                raise TypeError(f"{cls.id}: parameter {p.name} declared twice")
            if isinstance(p, Field) and p.parent not in seen:
                raise TypeError(f"{cls.id}: field {p.name} must come after its layer {p.parent}")
            seen.add(p.name)
        if any(isinstance(p, OutputFolder) for p in cls.parameters) and \
                cls.planned_files is Algorithm.planned_files:
            raise TypeError(f"{cls.id}: an OutputFolder needs planned_files() (the files it "
                            "will hold)")
        for o in cls.outputs:
            if o.name in seen:
                raise TypeError(f"{cls.id}: output {o.name} clashes with a parameter")
            seen.add(o.name)

    # -- behaviour ---------------------------------------------------------------------------------
    def check(self, params: dict[str, Any]) -> None:
        """Cross-parameter checks after each parameter validated; raise :class:`ParameterError`.

        Runs before any work (no file is written yet). The default accepts everything.
        """

    def planned_files(self, params: dict[str, Any]) -> dict[str, list[str]]:
        """The files each destination will write besides its own path, by destination name:
        for an :class:`~toolbox.parameters.OutputFolder` the names of the files it will hold
        (relative to it), for a file destination the extra files beside it (e.g. style
        sidecars). A name may be a glob pattern (``out.gpkg.*.qml``) when the exact names are
        known only while running. The runner checks each before any work, like an output path
        (never an input; existing only with ``--overwrite``). Called after :meth:`check`.
        """
        return {}

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        """Do the work. ``params`` holds validated values; output destinations are staged paths.

        Return a dict of outputs: destination names map to the path written (omit an optional
        destination that was not written); value outputs (statistics) map to JSON-serialisable
        values.
        """
        raise NotImplementedError

    @staticmethod
    def fail(name: str, message: str) -> ParameterError:
        """Shorthand for ``ParameterError(name, message)`` in :meth:`check`."""
        return ParameterError(name, message)
