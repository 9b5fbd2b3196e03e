"""Parameters whose default comes from the parameter file ('file dei parametri'), else from the
one table :data:`toolbox.io.parameter_file.DEFAULTS` (the help says which, from that table)."""

from __future__ import annotations

from typing import Any

from toolbox.io.parameter_file import DEFAULTS
from toolbox.parameters import Number


def file_backed(name: str, description: str, key: str, **options: Any) -> Number:
    """An optional Number >= 0 (``options`` may narrow it) whose help names its default: the
    parameter file's entry ``key``, else ``DEFAULTS[key]`` (``decimals``: a precision of
    10^-decimals, > 0)."""
    if key == "decimals":
        text = f"10^-decimals of the parameter file, else {10.0 ** -DEFAULTS[key]:g}"
        options.setdefault("min_exclusive", True)
    else:
        text = f"parameter file, else {DEFAULTS[key]:g}"
    return Number(name, f"{description} [default: {text}]", optional=True,
                  **({"min_value": 0} | options))
