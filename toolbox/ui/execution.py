"""Where an algorithm's tiles, photos or blocks run: the SCHEDULER and WORKERS parameters, one
declaration for every algorithm that splits its work (see :mod:`toolbox.executor`)."""

from __future__ import annotations

from typing import Any

from toolbox.parameters import Integer, String

SCHEDULER_HELP = ("Dask scheduler address (tcp://host:8786) to run the work on a cluster; "
                  "default: DASK_SCHEDULER_ADDRESS if set, else local threads ('local' forces "
                  "local threads)")


def scheduler_parameter(what: str = "the tiles") -> String:
    """``SCHEDULER``: a Dask address, 'local', or empty (the environment decides)."""
    return String("SCHEDULER", SCHEDULER_HELP.replace("the work", what), optional=True)


def workers_parameter(default: int | None = None) -> Integer:
    """``WORKERS``: local threads (default: the CPUs available)."""
    return Integer("WORKERS", "local threads (default: the CPUs available)", default=default,
                   optional=default is None, min_value=1)


def executor_of(params: dict[str, Any], workers: int | None = None):
    """The :class:`toolbox.executor.Executor` of an algorithm's SCHEDULER (and WORKERS, when it
    declares one; else ``workers``)."""
    from toolbox.executor import resolve_executor

    return resolve_executor(params.get("SCHEDULER"), params.get("WORKERS") or workers)
