"""Every third-party package the toolbox imports (toolbox/, algorithms/) is declared in
pyproject.toml (core or an extra) and has a row in README.md's "Dependencies and why" table, and
every declared package is used: an import is mapped to its distribution by the installed
metadata (``importlib.metadata.packages_distributions``), not by a list kept here."""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from functools import lru_cache
from importlib.metadata import packages_distributions
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# declared but never imported, each for a reason the README's table gives
NOT_IMPORTED = {"lazrs": "laspy's LAZ codec, loaded by laspy"}
DEV_TOOLS = {"pytest", "pytest-xdist", "ruff", "import-linter", "photogrammetry-toolbox"}


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement(text: str) -> set[str]:
    """The distributions a requirement names: ``dask[distributed]`` is dask and distributed (a
    package's extra named as the package it installs); the toolbox's own extras are not."""
    name = _norm(re.split(r"[\[<>=!~ ;]", text, maxsplit=1)[0])
    extras = re.match(r"[^\[]*\[([^\]]*)\]", text)
    if extras is None or name == "photogrammetry-toolbox":
        return {name}
    return {name} | {_norm(e) for e in extras.group(1).split(",")}


@lru_cache
def _imported_distributions(folders: tuple[str, ...]) -> dict[str, set[str]]:
    """Distribution -> files importing it, for the absolute imports of ``folders``."""
    owners = packages_distributions()
    found: dict[str, set[str]] = {}
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.split(".")[0]
                    if top in sys.stdlib_module_names or top in ("toolbox", "algorithms", "tests"):
                        continue
                    for dist in owners.get(top, [f"<no distribution for {top}>"]):
                        found.setdefault(_norm(dist), set()).add(
                            str(path.relative_to(ROOT)))
    return found


def _declared() -> tuple[set[str], set[str], set[str]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {n for r in project["dependencies"] for n in _requirement(r)}
    extras = project["optional-dependencies"]
    dev = {n for r in extras.pop("dev") for n in _requirement(r)}
    optional = {n for group in extras.values() for r in group for n in _requirement(r)}
    return core, optional, dev


def _readme_table() -> set[str]:
    section = (ROOT / "README.md").read_text().split("## Dependencies and why", 1)[1]
    names = set()
    for line in section.strip().split("\n\n", 1)[0].splitlines():
        cells = line.split("|")
        if len(cells) < 3 or cells[1].strip() in ("package", "---"):
            continue
        for item in cells[1].split(","):
            names |= _requirement(item.strip())
    return names


def test_every_import_is_declared_and_documented():
    core, optional, _ = _declared()
    imported = _imported_distributions(("toolbox", "algorithms"))
    undeclared = {d: sorted(f)[:2] for d, f in imported.items() if d not in core | optional}
    assert not undeclared, f"imported but not in pyproject.toml: {undeclared}"
    undocumented = sorted(set(imported) - _readme_table())
    assert not undocumented, f"imported but not in the README's dependency table: {undocumented}"


def test_every_declared_package_is_used_and_documented():
    core, optional, dev = _declared()
    used = set(_imported_distributions(("toolbox", "algorithms")))
    unused = sorted((core | optional) - used - set(NOT_IMPORTED))
    assert not unused, f"declared in pyproject.toml, never imported: {unused}"
    used_by_tests = set(_imported_distributions(("tests",)))
    unused_dev = sorted(dev - used_by_tests - DEV_TOOLS - core - optional)
    assert not unused_dev, f"[dev] packages no test imports: {unused_dev}"
    table = _readme_table()
    assert not (core | optional | dev) - table - {"photogrammetry-toolbox"}, \
        sorted((core | optional | dev) - table)


def test_the_check_bites():
    """The mapping finds what it must: pandas through geopandas' use, cv2 as its wheel's name."""
    imported = _imported_distributions(("toolbox", "algorithms"))
    assert "opencv-python-headless" in imported and "pyyaml" in imported
    assert "pandas" in imported and "affine" in imported
    assert "dask" in _readme_table() and "opencv-python-headless" in _readme_table()
