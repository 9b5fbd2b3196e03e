"""Every `toolbox ...` command shown in README.md and docs/algorithms/*.md works when pasted after
`make demo` (run here on a fresh demo folder, through the real CLI entry point)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from click.testing import CliRunner

from toolbox.cli import main

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs" / "algorithms").glob("*.md"))]
COMMAND = re.compile(r"^(?:\.venv/bin/)?toolbox\s+(run|batch|help|list)\b")


def documented_commands() -> list[tuple[str, str]]:
    """(source, command line) of every toolbox run/help/list command in fenced code blocks."""
    commands = []
    for doc in DOCS:
        in_code, pending = False, ""
        for line in doc.read_text().splitlines():
            if line.strip().startswith("```"):
                in_code, pending = not in_code, ""
                continue
            if not in_code:
                continue
            text = (pending + " " + line.strip()) if pending else line.strip()
            if text.endswith("\\"):
                pending = text[:-1].strip()
                continue
            pending = ""
            text = text.split(" #", 1)[0].strip()
            if COMMAND.match(text):
                commands.append((doc.name, text))
    return commands


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory, demo_run):
    import shutil

    base = tmp_path_factory.mktemp("docs")
    shutil.copytree(demo_run[0], base / "demo_out")  # the commands write there
    shutil.copytree(ROOT / "examples", base / "examples")
    return base


def test_docs_have_examples():
    sources = {source for source, _ in documented_commands()}
    assert {"README.md", "dem.md", "orientation.md", "rectify.md", "tin.md", "topology.md",
            "ortho.md", "mosaic.md", "attribution.md", "carto.md"} <= sources


def test_every_documented_command_runs(demo_dir, monkeypatch):
    monkeypatch.chdir(demo_dir)
    runner = CliRunner()
    failures = []
    for source, command in documented_commands():
        if "--scheduler" in command.lower():  # needs a running cluster: see test_dem_distributed
            continue
        args = shlex.split(COMMAND.sub(r"\1", command))
        if args[0] == "run" and "--overwrite" not in args:
            args.insert(1, "--overwrite")
        result = runner.invoke(main, args, catch_exceptions=True)
        if result.exit_code != 0:
            failures.append(f"{source}: {command}\n    -> exit {result.exit_code}: "
                            f"{(result.output or repr(result.exception))[-400:]}")
        elif args[0] == "run":  # and it wrote what it says: every output it names exists
            missing = [path for path in _output_paths(args) if not (demo_dir / path).exists()]
            if missing:
                failures.append(f"{source}: {command}\n    -> exit 0, not written: {missing}")
    assert not failures, "\n".join(failures)


def _output_paths(args: list[str]) -> list[str]:
    """The paths a `run` command line gives its output parameters (files or folders)."""
    from toolbox.registry import get

    algorithm = next(a for a in args[1:] if re.fullmatch(r"\w+:\w+", a))
    params = {p.name: p for p in get(algorithm).parameters}
    return [value for flag, value in zip(args, args[1:]) if flag.startswith("--")
            and (param := params.get(flag[2:].upper())) is not None
            and type(param).__name__.startswith("Output")]


def test_readme_typed_request_example_runs(tmp_path, monkeypatch):
    """The README's library example (typed requests, no runner) runs as pasted, and its DEM of
    the plane z = 200 + 0.1 x holds that plane (IDW of 8 near points of a plane)."""
    import numpy as np
    import rasterio

    text = (ROOT / "README.md").read_text()
    section = text.split("### The libraries, with typed requests", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    with rasterio.open(tmp_path / "dem_idw.tif") as ds:
        z = ds.read(1, masked=True)
        x = ds.transform.c + (np.arange(ds.width) + 0.5) * ds.transform.a - 1688000
    assert z.count() > 0.8 * z.size
    # the neighbours lie within a few metres: their heights, so the IDW mean, within 1 m
    assert np.abs(z - (200 + 0.1 * x[None, :])).max() < 1.0


def test_readme_python_api_names_exist():
    """Every ``toolbox.module.Name`` the README's Python API section names can be imported (a
    rename or a move that leaves the README behind fails here); the check bites: a made-up name
    is refused the same way."""
    import importlib

    section = (ROOT / "README.md").read_text().split("## Python API", 1)[1].split("\n## ", 1)[0]
    names = sorted(set(re.findall(r"`(toolbox(?:\.\w+)+)", section)))
    assert len(names) >= 15

    def resolves(dotted: str) -> bool:
        parts = dotted.split(".")
        for cut in range(len(parts), 0, -1):  # the longest importable module, then attributes
            try:
                obj = importlib.import_module(".".join(parts[:cut]))
            except ImportError:
                continue
            try:
                for attr in parts[cut:]:
                    obj = getattr(obj, attr)
            except AttributeError:
                return False
            return True
        return False

    assert [n for n in names if not resolves(n)] == []
    assert not resolves("toolbox.ortho.run.OrthoOptionz")
    assert not resolves("toolbox.no_such_module.Request")


def _missing_modules(package: str, source: str) -> list[str]:
    """The ``:mod:`` references of a module's docstring (``source``, a module of ``package``)
    that name no module: relative (``.x``) or bare names within the package, else absolute."""
    import ast

    doc = ast.get_docstring(ast.parse(source)) or ""
    missing = []
    for ref in re.findall(r":mod:`~?([\w.]+)`", doc):
        names = [package + ref] if ref.startswith(".") else [f"{package}.{ref}", ref]
        if not any(_module_exists(name) for name in names):
            missing.append(f"{package}: {ref}")
    return missing


def _module_exists(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def test_module_docstrings_name_modules_that_exist():
    """The ``:mod:`` references of every module docstring (toolbox/, algorithms/) name modules
    that exist (stale ones named .codes, .merge, .apply, .io and rectify's .warp); a made-up
    name in one of them is found."""
    files = sorted([*ROOT.glob("toolbox/**/*.py"), *ROOT.glob("algorithms/**/*.py")])
    assert len(files) > 300
    missing = [m for f in files for m in _missing_modules(
        ".".join(f.parent.relative_to(ROOT).parts), f.read_text())]
    assert missing == []
    source = (ROOT / "toolbox" / "ortho" / "__init__.py").read_text()
    bad = source.replace(":mod:`.sensor`", ":mod:`.no_such_module`", 1)
    assert bad != source
    assert _missing_modules("toolbox.ortho", bad) == ["toolbox.ortho: .no_such_module"]


def _documented_outputs() -> dict[str, list[str]]:
    """Output path (as written in the docs) -> the documented commands writing it."""
    from toolbox.registry import get

    outputs: dict[str, list[str]] = {}
    for source, command in documented_commands():
        args = shlex.split(COMMAND.sub(r"\1", command))
        if args[0] != "run":
            continue
        params = {p.name: p for p in get(args[1]).parameters}
        for flag, value in zip(args, args[1:]):
            param = params.get(flag[2:]) if flag.startswith("--") else None
            if param is not None and type(param).__name__.startswith("Output"):
                outputs.setdefault(value, []).append(f"{source}: {args[1]}")
    return outputs


def test_documented_commands_write_new_names(demo_run):
    """Pasted after `make demo` without --overwrite, no documented command is refused because
    its output exists: no two commands write the same file, and none writes one the demo
    wrote (test_every_documented_command_runs passes --overwrite, so it cannot see this)."""
    outputs = _documented_outputs()
    assert len(outputs) > 100
    twice = {path: who for path, who in outputs.items() if len(who) > 1}
    assert not twice, twice
    demo_out = demo_run[0]
    taken = [path for path in outputs if path.startswith("demo_out/")
             and (demo_out / path.removeprefix("demo_out/")).exists()]
    assert not taken, taken


def orthority_examples() -> list[str]:
    """The README's inline commands (in backticks, possibly wrapped) run on Orthority's test
    data: those naming its ``rpc/``, ``ngi/`` or ``odm/`` folders (or ``--IMAGES rpc``)."""
    text = re.sub(r"\n\s*", " ", (ROOT / "README.md").read_text())
    commands = re.findall(r"`(toolbox run [^`]+)`", text)
    return [c for c in commands if re.search(r"(?:^|\s)(?:rpc|ngi|odm)(?:/|\s|$)", c)]


def test_readme_orthority_examples_run(orthority_data, tmp_path, monkeypatch):
    """Pasted in a folder holding Orthority's ``tests/data`` folders (linked here), the README's
    commands on that data run and write their outputs."""
    examples = orthority_examples()
    assert any("ortho:batch --IMAGES rpc" in c for c in examples)
    assert any("orientation:precision" in c for c in examples)
    for name in ("rpc", "ngi", "odm"):
        (tmp_path / name).symlink_to(orthority_data / name)
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    for command in examples:
        args = shlex.split(COMMAND.sub(r"\1", command))
        result = runner.invoke(main, args, catch_exceptions=True)
        assert result.exit_code == 0, (command, result.output[-400:])
        written = [args[k + 1] for k, a in enumerate(args) if a in ("--OUTPUT", "--FOLDER")]
        assert written and all((tmp_path / w).exists() for w in written), command
