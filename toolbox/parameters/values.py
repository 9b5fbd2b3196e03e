"""Scalar parameters: numbers, booleans, strings, choices, CRS and extents."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from toolbox.io.text import is_number
from toolbox.parameters.base import (
    _FALSE,
    _TRUE,
    Parameter,
    ValidationContext,
    _show,
    refuse_empty_items,
)


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
    """Text. ``paths=True``: a file or folder path, or several separated by commas (a pipeline
    resolves relative ones against its folder, a run report records them absolute); an
    ``os.PathLike`` (``pathlib.Path``) is taken as its path."""

    type_name = "string"

    def __init__(self, name: str, description: str = "", default: Any = None,
                 optional: bool = False, *, paths: bool = False, **flags):
        super().__init__(name, description, default, optional, **flags)
        self.paths = paths
        self.holds_paths = paths

    def validate(self, value: Any, ctx: ValidationContext) -> str:
        if self.paths and isinstance(value, os.PathLike):  # a pathlib.Path from the Python API
            return os.fspath(value)
        if not isinstance(value, (str, int, float)):
            raise self.error(f"must be text{' or a path' if self.paths else ''}, got "
                             f"{_show(value)}")
        if self.paths and isinstance(value, str) and "," in value \
                and not os.path.exists(os.path.expanduser(value)):
            refuse_empty_items(self, value.split(","), value,
                               "a path, or several separated by commas")
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


_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
#: four numbers, then (after a space or comma) a CRS that is not a number: "... EPSG:3003"
_BARE_CRS = re.compile(rf"^\s*({_NUMBER})(?:\s*,\s*|\s+)({_NUMBER})(?:\s*,\s*|\s+)"
                       rf"({_NUMBER})(?:\s*,\s*|\s+)({_NUMBER})(?:\s*,\s*|\s+)(\S.*?)\s*$")
EXTENT_FORMS = "'xmin,ymin,xmax,ymax', optionally followed by its CRS: " \
    "'xmin,ymin,xmax,ymax EPSG:3003' (or '... [EPSG:3003]')"


class ExtentParameter(Parameter):
    """An extent as ``"xmin,ymin,xmax,ymax"`` (GDAL ``-te`` and shapely/rasterio bounds order),
    optionally followed by its CRS, ``" EPSG:3003"`` or ``" [EPSG:3003]"``; or a sequence of
    four numbers, or an :class:`Extent`.

    The help of the bracketed form read ``xmin,ymin,xmax,ymax [CRS]``, which reads as "an
    optional CRS": ``"... EPSG:32633"`` was refused (exit 2), only ``"... [EPSG:32633]"`` (the
    brackets typed, QGIS's own extent text) was taken. Both are now.
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
                bare = None if match else _BARE_CRS.match(text)
                if bare is not None and is_number(bare.group(5)):
                    bare = None  # five numbers: refused below
                if match or bare:
                    from toolbox.io.crs import parse_crs

                    if match:
                        text, crs_text = match.group(1), match.group(2)
                    else:
                        text, crs_text = ",".join(bare.groups()[:4]), bare.group(5)
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
                raise self.error(f"must be {EXTENT_FORMS}, got {_show(value)}")
        xmin, ymin, xmax, ymax = numbers
        if not (xmin < xmax and ymin < ymax):
            raise self.error(
                f"must have xmin < xmax and ymin < ymax (order xmin,ymin,xmax,ymax), got "
                f"{_show(value)}")
        return Extent(xmin, ymin, xmax, ymax, crs)

    def expected(self) -> str:
        return "extent 'xmin,ymin,xmax,ymax' or 'xmin,ymin,xmax,ymax EPSG:nnnn'"

