"""Optional dependencies (the ``[project.optional-dependencies]`` extras of pyproject.toml).

The core install runs every algorithm; an extra adds an option: ``triangle`` (Shewchuk's
Triangle, non-commercial licence), ``dask`` (a Dask cluster as ``SCHEDULER``), ``bench``
(psutil, for the benchmarks). :func:`require` imports one and, when it is missing, raises a
:class:`~toolbox.errors.ToolboxError` that names the extra to install.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from toolbox.errors import ToolboxError

PACKAGE = "photogrammetry-toolbox"


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """``import module`` or raise ``ToolboxError("<purpose> needs ... pip install '...[extra]'")``."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ToolboxError(f"{purpose} needs the optional package '{module.split('.')[0]}': "
                           f"pip install '{PACKAGE}[{extra}]'") from None
