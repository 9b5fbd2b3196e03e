"""Photogrammetric cartography toolbox: algorithms from oriented photos and restitution linework
to map deliverables (GeoPackage, GeoTIFF).

Python API::

    import toolbox
    toolbox.run("dem:idw", {"INPUT": "points.gpkg", "CELL_SIZE": 2, "OUTPUT": "dem.tif"})
"""

from __future__ import annotations

from toolbox.cache import configure_numba_cache
from toolbox.version import __version__

configure_numba_cache()  # before any numba import: compiled kernels go to the per-user cache

from toolbox.errors import (  # noqa: E402
    AlgorithmNotFoundError,
    CanceledError,
    ConvergenceError,
    InputDataError,
    OutputExistsError,
    ParameterError,
    PipelineError,
    ToolboxError,
)

# imported on first use (PEP 562): ``toolbox --version`` and ``toolbox help`` need neither the
# runner nor the registry's imports (importlib.metadata, the parameter types, GDAL staging)
_LAZY = {"Feedback": "toolbox.feedback", "algorithms": "toolbox.registry",
         "get": "toolbox.registry", "run": "toolbox.runner", "validate": "toolbox.runner"}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'toolbox' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))

__all__ = [
    "AlgorithmNotFoundError", "CanceledError", "ConvergenceError", "Feedback", "InputDataError",
    "OutputExistsError", "ParameterError", "PipelineError", "ToolboxError", "__version__",
    "algorithms", "get", "run", "validate",
]
