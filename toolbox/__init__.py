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
from toolbox.feedback import Feedback  # noqa: E402
from toolbox.registry import algorithms, get  # noqa: E402
from toolbox.runner import run, validate  # noqa: E402

__all__ = [
    "AlgorithmNotFoundError", "CanceledError", "ConvergenceError", "Feedback", "InputDataError",
    "OutputExistsError", "ParameterError", "PipelineError", "ToolboxError", "__version__",
    "algorithms", "get", "run", "validate",
]
