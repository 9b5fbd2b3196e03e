"""A custom import-linter contract (pyproject.toml ``[tool.importlinter]``): no import cycles between
modules, counting every import statement (function-level ones too) and imports of a package's
``__init__`` (``toolbox.report`` importing ``toolbox`` while ``toolbox`` imports the runner)."""

from __future__ import annotations

import grimp
from importlinter import Contract, ContractCheck, fields, output


def import_cycles(graph: grimp.ImportGraph, modules: set[str]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    edges = {m: sorted(graph.find_modules_directly_imported_by(m) & modules) for m in modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []
    for root in sorted(modules):
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            if i < len(edges[node]):
                work.append((node, i + 1))
                nxt = edges[node][i]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    cycles.append(sorted(component))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return cycles


class AcyclicModulesContract(Contract):
    """``type = "acyclic_modules"``, ``packages = [...]``: no module-level import cycle inside them."""

    packages = fields.ListField(subfield=fields.StringField())

    def check(self, graph: grimp.ImportGraph, verbose: bool) -> ContractCheck:
        modules = {m for m in graph.modules
                   if any(m == p or m.startswith(p + ".") for p in self.packages)}
        cycles = import_cycles(graph, modules)
        return ContractCheck(kept=not cycles, metadata={"cycles": cycles})

    def render_broken_contract(self, check: ContractCheck) -> None:
        for cycle in check.metadata["cycles"]:
            output.print_error("import cycle: " + " <-> ".join(cycle))


class ParameterLayerContract(Contract):
    """``type = "parameter_layer"``: no module of ``packages`` imports a module of ``layer``
    (directly, function-level imports included) unless it is one of ``allowed`` (or inside
    one of them). Keeps the domain libraries callable with typed requests: the UI's
    parameter types, algorithm base classes and parameter translations stay at the edge."""

    packages = fields.ListField(subfield=fields.StringField())
    layer = fields.ListField(subfield=fields.StringField())
    allowed = fields.ListField(subfield=fields.StringField())

    def check(self, graph: grimp.ImportGraph, verbose: bool) -> ContractCheck:
        def inside(module: str, names) -> bool:
            return any(module == n or module.startswith(n + ".") for n in names)

        bad = []
        for module in sorted(graph.modules):
            if not inside(module, self.packages) or inside(module, self.allowed):
                continue
            for imported in sorted(graph.find_modules_directly_imported_by(module)):
                if inside(imported, self.layer):
                    bad.append((module, imported))
        return ContractCheck(kept=not bad, metadata={"imports": bad})

    def render_broken_contract(self, check: ContractCheck) -> None:
        for module, imported in check.metadata["imports"]:
            output.print_error(f"{module} imports the parameter layer ({imported})")
