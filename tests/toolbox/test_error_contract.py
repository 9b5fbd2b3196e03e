"""The error contract, over EVERY registered algorithm (those that land later too, with no new code).

Valid parameters come from the demo pipeline (toolbox/demo/pipeline/*.yaml, run once per session);
each case then breaks one thing, the way users do: a missing, empty, wrong-type or truncated input,
absurd numbers, an output that is an input (through every destination and --run-report), an output
under a file, in a read-only folder, in a full one, in a folder that does not exist yet. Whatever
the mistake, the CLI ends with exit 2 and ONE line naming the parameter (exit 0 is accepted only
where the mistake can give a valid result: absurd but legal numbers, a truncated text file that is
still readable, a small output that fits), never a traceback; no file is left behind and every input
is byte-identical afterwards.
"""

from __future__ import annotations

import hashlib
import os
import random
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner

import toolbox
from toolbox.batch import REF_RE
from toolbox.cli import main
from toolbox.parameters import (
    Destination,
    File,
    Integer,
    MultipleLayers,
    Number,
    RasterLayer,
    VectorLayer,
)
from toolbox.runner import validate

ALGORITHMS = sorted(a.id for a in toolbox.algorithms() if not a.id.startswith("testing:"))
INPUT_TYPES = (VectorLayer, RasterLayer, File, MultipleLayers)


# -- session data: the demo, run once ---------------------------------------------------------------
@pytest.fixture(scope="session")
def demo(tmp_path_factory):
    """(demo folder, {variable: value}, {algorithm: first demo step's params}, {(step, NAME):
    value})."""
    from toolbox.batch import parse_pipeline, run_pipeline
    from toolbox.demo import demo_pipeline_doc
    from toolbox.demo.samples import make_samples

    out = tmp_path_factory.mktemp("contract_demo")
    variables = {k: str(v) for k, v in make_samples(out / "data").items()} | {"out": str(out)}
    doc = demo_pipeline_doc()
    run_pipeline(parse_pipeline(doc, out, variables, "demo pipeline"), overwrite=True)
    steps: dict[str, dict] = {}
    values = {}
    for raw in doc["steps"]:
        steps.setdefault(raw["algorithm"], raw.get("params") or {})
        for key, value in (raw.get("params") or {}).items():
            values[(raw["name"], key)] = value
    return out, variables, steps, values


def _resolve(value, variables: dict, values: dict):
    """A demo parameter value with ${variable} and ${step.NAME} replaced by demo paths."""
    if isinstance(value, list):
        return [_resolve(v, variables, values) for v in value]
    if not isinstance(value, str):
        return value

    def repl(match):
        step, name = match.group(1), match.group(2)
        if name is None:
            return str(variables[step])
        return str(_resolve(values[(step, name)], variables, values))

    return REF_RE.sub(repl, value)


def _borrowed_steps(alg, steps: dict) -> list[dict]:
    """Other algorithms' demo parameters that may fit ``alg`` (dem:nearest takes
    dem:quadratic's), same group first."""
    names = {p.name for p in alg.parameters}
    required = {p.name for p in alg.parameters if not p.optional}
    fits = [(other.split(":")[0] != alg.group_id(), params) for other, params in steps.items()
            if set(params) <= names and required <= set(params)]
    return [params for _, params in sorted(fits, key=lambda f: f[0])]


# -- one case ----------------------------------------------------------------------------------
class Case:
    """Inputs copied into ``in/``, outputs directed into ``out/``; ``run`` checks the contract."""

    def __init__(self, alg_id: str, demo, tmp_path: Path):
        demo_out, variables, steps, values = demo
        self.alg = toolbox.get(alg_id)
        self.root = tmp_path
        self.inputs_dir = tmp_path / "in"
        self.out = tmp_path / "out"
        self.out.mkdir()
        shutil.copytree(demo_out / "data", self.inputs_dir / "data")
        for raw in [steps[alg_id]] if alg_id in steps else _borrowed_steps(self.alg, steps):
            self.params = self._localise(raw, variables, values, demo_out)
            try:
                validate(self.alg, self.params)
                break
            except toolbox.ToolboxError:
                continue
        else:
            pytest.skip(f"{alg_id} has no step in the demo pipeline (add one: it gives the "
                        "error contract its valid parameters)")

    def _localise(self, raw: dict, variables: dict, values: dict, demo_out: Path) -> dict:
        params = {}
        for key, value in raw.items():
            value = _resolve(value, variables, values)
            p = self.alg.parameter(key)
            if isinstance(p, Destination):
                value = str(self.out / Path(str(value)).name)
            elif isinstance(p, INPUT_TYPES):
                value = [self._copy_in(v, demo_out) for v in value] if isinstance(value, list) \
                    else self._copy_in(value, demo_out)
            params[key] = value
        return params

    def _copy_in(self, value: str, demo_out: Path) -> str:
        path = Path(str(value).split("|")[0])
        try:
            rel = path.relative_to(demo_out / "data")
            return str(self.inputs_dir / "data" / rel) + str(value)[len(str(path)):]
        except ValueError:
            target = self.inputs_dir / "produced" / path.name
            target.parent.mkdir(exist_ok=True)
            shutil.copy2(path, target)
            return str(target) + str(value)[len(str(path)):]

    def input_params(self) -> list:
        return [p for p in self.alg.parameters
                if isinstance(p, INPUT_TYPES) and self.params.get(p.name) is not None]

    def destinations(self) -> list:
        return [p for p in self.alg.destinations() if self.params.get(p.name) is not None]

    def args(self, **changes) -> list[str]:
        params = dict(self.params) | changes
        out = []
        for key, value in params.items():
            if value is None:
                continue
            for item in value if isinstance(value, list) else [value]:
                out += [f"--{key}", str(item).lower() if isinstance(item, bool) else str(item)]
        return out

    def snapshot(self) -> dict:
        return {str(p.relative_to(self.root)): hashlib.sha256(p.read_bytes()).hexdigest()
                for p in sorted(self.inputs_dir.rglob("*")) if p.is_file()}

    def run(self, args: list[str], name: str | tuple | None, may_succeed: bool = False,
            words: str | None = None, out_dirs: tuple[Path, ...] = ()) -> str:
        """Run ``toolbox run ID args`` and check the contract; return the error line."""
        before = self.snapshot()
        result = CliRunner().invoke(main, ["run", self.alg.id, *args])
        stderr = result.stderr
        assert "Traceback" not in stderr and "internal error" not in stderr, stderr
        assert result.exit_code in ((0, 2) if may_succeed else (2,)), (args, result.exit_code,
                                                                       stderr, result.exception)
        assert self.snapshot() == before, f"an input was modified by {args}"
        if result.exit_code == 0:
            for folder in (self.out, *out_dirs):  # a success may write: clear for the next case
                for item in folder.iterdir():
                    shutil.rmtree(item) if item.is_dir() else item.unlink()
            return ""
        lines = [line for line in stderr.strip().splitlines() if not line.startswith("WARNING:")
                 and not line.startswith("INFO:")]
        gdal_noise = [line for line in lines if not line.startswith("toolbox:")]
        errors = [line for line in lines if line.startswith("toolbox: error:")]
        assert len(errors) == 1 and len(lines) - len(gdal_noise) == 1, stderr
        if name is not None:  # the parameter (or, from a reader, the file the user gave it)
            names = (name,) if isinstance(name, str) else name
            assert any(n in errors[0] for n in names), (names, errors[0])
        if words is not None:
            assert re.search(words, errors[0], re.I), (words, errors[0])
        for folder in (self.out, *out_dirs):
            left = [str(p) for p in folder.rglob("*")]
            assert left == [], f"{args} left {left}"
        return errors[0]


@pytest.fixture
def case(request, demo, tmp_path):
    return Case(request.param, demo, tmp_path)


def _cases():
    return pytest.mark.parametrize("case", ALGORITHMS, indirect=True)


# -- inputs -------------------------------------------------------------------------------------
@_cases()
def test_missing_empty_and_wrong_type_inputs(case):
    if not case.input_params():
        pytest.skip("no file input")
    for p in case.input_params():
        value = case.params[p.name]
        first = value[0] if isinstance(value, list) else value
        suffix = Path(str(first).split("|")[0]).suffix
        missing = case.root / f"missing{suffix}"
        empty = case.root / f"empty{suffix}"
        empty.write_bytes(b"")
        wrong = case.root / f"wrong{suffix}"
        wrong.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4 if suffix in (
            ".csv", ".txt", ".yaml", ".yml", ".json") else b"x;y\n1;2\n")
        for bad in (missing, empty, wrong):
            case.run(case.args(**{p.name: str(bad)}), (p.name, bad.name))


@_cases()
def test_truncated_inputs(case):
    if not case.input_params():
        pytest.skip("no file input")
    for p in case.input_params():
        value = case.params[p.name]
        first = Path(str(value[0] if isinstance(value, list) else value).split("|")[0])
        cut = case.root / f"cut_{p.name}{first.suffix}"
        data = first.read_bytes()
        cut.write_bytes(data[: max(1, len(data) * 2 // 3)])
        layer = str(value[0] if isinstance(value, list) else value)[len(str(first)):]
        case.run(case.args(**{p.name: str(cut) + layer}), None, may_succeed=True)


@_cases()
def test_absurd_numbers(case):
    numbers = [p for p in case.alg.parameters if isinstance(p, Number)]
    if not numbers:
        pytest.skip("no number parameter")
    rng = random.Random(case.alg.id)  # a sample per algorithm, the same on every run
    for p in rng.sample(numbers, min(2, len(numbers))):
        value = rng.choice(["1e308", "-1e308", "nan", "1e-320"] if not isinstance(p, Integer)
                           else ["-1", "1e12", "0.5"])
        case.run(case.args(**{p.name: value}), p.name, may_succeed=True)


# -- outputs ------------------------------------------------------------------------------------
@_cases()
def test_output_equal_to_an_input_is_refused(case):
    """Through every destination (via '..' and via a symlink) and --run-report, with
    --overwrite: refused, the input intact."""
    files = []
    for p in case.input_params():
        value = case.params[p.name]
        files += [str(v).split("|")[0] for v in (value if isinstance(value, list) else [value])]
    if not files:
        pytest.skip("no file input")
    link = case.root / "link_to_input"
    checked = 0
    for dest in case.destinations():
        victim = next((f for f in files if not dest.extensions
                       or Path(f).suffix.lower() in dest.extensions), None)
        if victim is None:
            continue  # no input of that extension: an output of this type cannot be one
        victim = Path(victim)
        dotted = f"{victim.parent}/../{victim.parent.name}/{victim.name}"
        case.run(case.args(**{dest.name: dotted}) + ["--overwrite"], dest.name)
        link.symlink_to(victim)
        try:
            case.run(case.args(**{dest.name: str(link)}) + ["--overwrite"], dest.name)
        finally:
            link.unlink()
        checked += 1
    for path in files:
        case.run(case.args() + ["--overwrite", "--run-report", path], "--run-report")


@_cases()
def test_output_folder_mistakes(case):
    dests = case.destinations()
    if not dests:
        pytest.skip("no output file")
    dest = dests[0]
    name = Path(case.params[dest.name]).name
    a_file = case.out.parent / "a_file"
    a_file.write_text("not a folder")
    case.run(case.args(**{dest.name: str(a_file / name)}), dest.name, out_dirs=())
    case.run(case.args(**{dest.name: str(case.out / ("n" * 300 + Path(name).suffix))}),
             dest.name)
    # a run that fails leaves no folder it created
    numbers = [p for p in case.alg.parameters if isinstance(p, Number)
               and p.min_value is not None]
    inputs = case.input_params()
    if numbers:
        bad = {numbers[0].name: str(numbers[0].min_value - 1)}
        expect = numbers[0].name
    elif inputs:
        bad = {inputs[0].name: str(case.root / "missing.gpkg")}
        expect = inputs[0].name
    else:
        return
    case.run(case.args(**bad, **{dest.name: str(case.out / "new" / "deeper" / name)}), expect)


def _mount_tmpfs(folder: Path, options: str) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                          capture_output=True)
    return proc.returncode == 0


@_cases()
def test_read_only_and_full_output_folders(case):
    dests = case.destinations()
    if not dests:
        pytest.skip("no output file")
    for options, words in (("ro,size=64k", "read-only|cannot write"),
                           ("size=4k", "no space left on device")):
        folder = case.root / f"mnt_{options.split(',')[0]}"
        folder.mkdir()
        if not _mount_tmpfs(folder, options):
            pytest.skip("needs root to mount a small tmpfs (read-only / full output folder)")
        try:
            for dest in dests[:1]:  # the first output: the runner's checks are per run
                target = folder / Path(case.params[dest.name]).name
                changes = {dest.name: str(target)}
                case.run(case.args(**changes), dest.name, may_succeed=options.startswith("size"),
                         words=words, out_dirs=(folder,))
        finally:
            subprocess.run(["umount", str(folder)], check=True)
