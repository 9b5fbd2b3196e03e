"""Path values of parameters made absolute: a pipeline's (relative to its file's folder) and a
run report's (relative to the folder the run was started in)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any


def absolute_paths(value: Any, base_dir: str | Path | None = None,
                   comma_separated: bool = False) -> Any:
    """``value`` (a path, a list of them, or with ``comma_separated`` a text of comma-separated
    paths) with each relative file path made absolute against ``base_dir`` (default: the
    current folder). A layer reference keeps its ``|layername=...`` part; GDAL's ``/vsi...``
    and ``DRIVER:...`` names, ``<...>`` placeholders and values that are no path (numbers,
    empty text) are left as given."""
    if isinstance(value, list):
        return [absolute_paths(v, base_dir) for v in value]
    if comma_separated and isinstance(value, str) and "," in value:
        return ",".join(absolute_paths(v.strip(), base_dir) for v in value.split(",")
                        if v.strip())
    if not isinstance(value, (str, Path)) or not str(value):
        return value
    text = str(value)
    head, sep, tail = text.partition("|")
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    if text.startswith(("<", "/vsi")) or Path(head).expanduser().is_absolute() \
            or (":" in head and not (base / head).exists()):
        return value
    return (str(base / head) if base_dir is not None else os.path.abspath(head)) + sep + tail
