"""The import contract of pyproject.toml [tool.importlinter], also run by `make lint`: the framework
and libraries never import algorithms, algorithms never import each other, no import cycles."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

from tests.lint_contracts import import_cycles

ROOT = Path(__file__).resolve().parents[2]


def test_import_contract_is_kept():
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if lint is None:
        pytest.skip("import-linter not installed (pip install -e '.[dev]')")
    proc = subprocess.run([lint, "--no-cache"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:]


def test_cycle_finder_finds_a_cycle_through_a_package_init():
    graph = grimp.ImportGraph()
    for module in ("pkg", "pkg.runner", "pkg.report", "pkg.io"):
        graph.add_module(module)
    graph.add_import(importer="pkg", imported="pkg.runner")
    graph.add_import(importer="pkg.runner", imported="pkg.report")
    graph.add_import(importer="pkg.report", imported="pkg")
    graph.add_import(importer="pkg.report", imported="pkg.io")
    assert import_cycles(graph, set(graph.modules)) == [["pkg", "pkg.report", "pkg.runner"]]
    graph.remove_import(importer="pkg.report", imported="pkg")
    assert import_cycles(graph, set(graph.modules)) == []


def test_parameter_layer_contract_names_a_library_importing_parameters():
    from tests.lint_contracts import ParameterLayerContract

    graph = grimp.ImportGraph()
    for module in ("pkg", "pkg.parameters", "pkg.runner", "pkg.ui", "pkg.ui.grid", "pkg.io",
                   "pkg.terrain.run"):
        graph.add_module(module)
    graph.add_import(importer="pkg.runner", imported="pkg.parameters")
    graph.add_import(importer="pkg.ui.grid", imported="pkg.parameters")
    graph.add_import(importer="pkg.ui.grid", imported="pkg.terrain.run")
    contract = ParameterLayerContract(
        name="t", session_options={},
        contract_options={"packages": ["pkg"], "layer": ["pkg.parameters", "pkg.ui"],
                          "allowed": ["pkg.runner", "pkg.parameters", "pkg.ui"]})
    assert contract.check(graph, verbose=False).kept
    graph.add_import(importer="pkg.terrain.run", imported="pkg.ui.grid")  # a library -> the UI
    check = contract.check(graph, verbose=False)
    assert not check.kept and check.metadata["imports"] == [("pkg.terrain.run", "pkg.ui.grid")]
