"""Registry: discovers every algorithm under the ``algorithms`` package and in the
``toolbox.algorithms`` entry-point group (third-party providers), without a hand-kept list.

Modules are imported on first use (``toolbox list`` / ``run`` / ``help``), not at ``import toolbox``.
Renamed ids stay reachable through :data:`ALIASES` (an id is never reused).
"""

from __future__ import annotations

import difflib
import importlib
import logging
import pkgutil
from importlib.metadata import entry_points

from toolbox.algorithm import Algorithm
from toolbox.errors import AlgorithmNotFoundError

log = logging.getLogger("toolbox")

ENTRY_POINT_GROUP = "toolbox.algorithms"
ALIASES: dict[str, str] = {"raster:hillshade": "dem:hillshade"}  # old id -> current id

_registry: dict[str, type[Algorithm]] = {}
_discovered = False


def register(cls: type[Algorithm]) -> type[Algorithm]:
    """Class decorator adding an algorithm to the registry (checks its spec)."""
    cls.check_spec()
    existing = _registry.get(cls.id)
    if existing is not None and existing is not cls and (
            existing.__module__, existing.__qualname__) != (cls.__module__, cls.__qualname__):
        raise TypeError(f"algorithm id {cls.id!r} is registered twice "
                        f"({existing.__module__} and {cls.__module__})")
    _registry[cls.id] = cls
    return cls


def _import_builtin() -> None:
    import algorithms

    for module in pkgutil.walk_packages(algorithms.__path__, "algorithms."):
        importlib.import_module(module.name)


def _import_plugins() -> None:
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must not break the toolbox
            log.warning("plugin %s could not be loaded: %s", ep.name, exc)
            continue
        if isinstance(obj, type) and issubclass(obj, Algorithm) and obj.id not in _registry:
            register(obj)


def discover() -> None:
    """Import built-in algorithm modules and plugins once."""
    global _discovered
    if not _discovered:
        _import_builtin()
        _import_plugins()
        _discovered = True


def algorithms() -> list[type[Algorithm]]:
    """Every registered algorithm, sorted by id."""
    discover()
    return [_registry[k] for k in sorted(_registry)]


def get(algorithm_id: str) -> type[Algorithm]:
    """The algorithm class for ``algorithm_id`` (aliases resolved).

    Raises :class:`AlgorithmNotFoundError` suggesting close ids.
    """
    discover()
    key = ALIASES.get(algorithm_id, algorithm_id)
    if key in _registry:
        return _registry[key]
    close = difflib.get_close_matches(algorithm_id, list(_registry), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else "; run 'toolbox list' to see them"
    raise AlgorithmNotFoundError(f"no algorithm {algorithm_id!r}{hint}")
