"""README.md read as a newcomer would (round twenty): every algorithm has a shell example, the
pipeline excerpt is the example file's, the inline `toolbox help`/`list` commands and the Python
blocks run as pasted, and the demo's quoted bundle line gives the numbers the demo prints.
(The fenced `toolbox ...` commands run in test_docs_examples.py.)"""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from toolbox.cli import main
from toolbox.registry import get

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def _fenced(language: str) -> list[str]:
    return re.findall(rf"^\s*```{language}\n(.*?)^\s*```", README, re.S | re.M)


def _joined(block: str) -> str:
    return re.sub(r"\\\n\s*", " ", block)


def test_every_algorithm_has_a_shell_example():
    """`toolbox list`'s every id is run by a fenced `toolbox run` of the README (its "Examples,
    one per algorithm"): attribution:align/merge/sample, dem:aspect and orientation:resection
    had none, orientation:fiducials only an inline one."""
    import json
    import subprocess
    import sys

    # a fresh process: this one holds the test-only algorithms other tests registered
    listed = subprocess.run([sys.executable, "-m", "toolbox", "list", "--json"],
                            capture_output=True, text=True, check=True)
    ids = {a["id"] for a in json.loads(listed.stdout)}
    assert len(ids) >= 56
    shown = {get(i).id for block in _fenced("(?:sh|bash)")
             for i in re.findall(r"toolbox run (\w+:\w+)", _joined(block))}
    assert sorted(ids - shown) == []


def test_pipeline_excerpt_is_the_example_file():
    """The README's YAML excerpt holds the example pipeline's variables and first steps as
    they are (its idw step had lost NEIGHBOURS, its hillshade step AZIMUTH)."""
    excerpt = yaml.safe_load(_fenced("yaml")[0])
    pipeline = yaml.safe_load((ROOT / "examples" / "demo_pipeline.yaml").read_text())
    assert excerpt["variables"] == pipeline["variables"]
    assert excerpt["steps"] == pipeline["steps"][:len(excerpt["steps"])]


def test_inline_help_and_list_commands_run():
    """Inline `toolbox help ...`/`toolbox list` commands of the prose run (exit 0; ID: an
    algorithm's id); one said `toolbox help --json`, which is refused without an id."""
    text = re.sub(r"\n\s*", " ", README)
    commands = re.findall(r"`(toolbox (?:help|list)\b[^`]*)`", text)
    assert len(commands) >= 4
    runner = CliRunner()
    failed = [(c, r.exit_code) for c in commands if (r := runner.invoke(
        main, [w if w != "ID" else "dem:idw" for w in shlex.split(c)[1:]])).exit_code != 0]
    assert failed == []


@pytest.fixture
def readme_folder(tmp_path, demo_run, monkeypatch):
    """A folder holding the demo's data as `demo_out/data` (what the Python blocks read)."""
    shutil.copytree(demo_run[0] / "data", tmp_path / "demo_out" / "data")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_python_api_blocks_run(readme_folder, capsys):
    """The "Python API" block (run, progress callback, the caught error) and the fiducial-mark
    block (it draws its own scan) run as pasted and print what they say."""
    blocks = _fenced("python")
    api = next(b for b in blocks if 'toolbox.run("dem:hillshade"' in b)
    fiducials = next(b for b in blocks if '"orientation:fiducials"' in b)
    exec(compile(api, "README.md", "exec"), {})
    printed = capsys.readouterr().out
    assert (readme_folder / "shade.tif").exists() and (readme_folder / "shade.json").exists()
    assert "100.0%" in printed and "INPUT file 'missing.tif' does not exist" in printed
    exec(compile(fiducials, "README.md", "exec"), {})
    printed = capsys.readouterr().out
    assert "'marks_missing': 0" in printed and (readme_folder / "scan_interior.json").exists()


def test_quoted_bundle_line_is_the_demos(demo_run):
    """The README quotes the line the demo prints for siena_bundle; its numbers are the ones
    the demo gives (it quoted 0.012 / 0.013 / 0.088 m and 0.42 m where the demo prints
    0.011 / 0.009 / 0.047 m and 0.30 m)."""
    quoted = re.sub(r"\s+", " ", re.search(r"`(siena_bundle: against.*?)`", README, re.S)[1])
    printed = next(line.strip() for line in demo_run[1].splitlines()
                   if line.strip().startswith("siena_bundle: against"))
    number = r"\d+(?:\.\d+)?"
    head = quoted.split("...")[0]
    assert printed.startswith(re.split(number, head)[0])
    for pattern in (r"ground at most (N) / (N) / (N) m", r"back-projection at most (N) µm",
                    r"centres at most (N) m \((N) of their std\)"):
        pattern = pattern.replace("N", number)
        want, got = re.search(pattern, quoted), re.search(pattern, printed)
        assert want and got, pattern
        for a, b in zip(want.groups(), got.groups()):
            assert abs(float(a) - float(b)) <= max(0.15 * float(b), 0.002), (pattern, a, b)
