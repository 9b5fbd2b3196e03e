"""The ``toolbox`` command: list, help, run, batch, demo, warmup.

The console script enters at :func:`console`: ``--version``, ``list`` and ``help`` are answered
from the cached spec index without importing click or setting up logging
(:mod:`toolbox.cli.quick`); everything else goes to the click application :data:`main`
(:mod:`toolbox.cli.app`, imported on first use, as are its other names: ``from toolbox.cli
import main`` works as before).
"""

from __future__ import annotations

SUBMODULES = ("app", "helptext", "quick", "terminal")


def console() -> int | None:
    """The ``toolbox`` script (and ``python -m toolbox``): a quick answer when there is one,
    else the click application (which exits itself)."""
    import sys

    from toolbox.cli.quick import answer

    code = answer(sys.argv[1:])
    if code is not None:
        return code
    from toolbox.cli.app import main

    return main(prog_name="toolbox")


def __getattr__(name: str):
    """The click application's names (``main``, ``format_help``, ``setup_logging``...), imported
    on first use (PEP 562)."""
    if name.startswith("__") or name in SUBMODULES:
        raise AttributeError(f"module 'toolbox.cli' has no attribute {name!r}")
    from toolbox.cli import app

    return getattr(app, name)
