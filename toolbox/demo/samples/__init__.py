"""Sample data for the demo and the tests. Each module here has ``make(folder, made) -> dict``
returning ``{variable name: path}``; modules run in name order and see what earlier ones made."""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path


def make_samples(folder: Path) -> dict[str, Path]:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    made: dict[str, Path] = {"data": folder}
    import toolbox.demo.samples as package

    for module in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{package.__name__}.{module.name}")
        made.update(mod.make(folder, made))
    return made
