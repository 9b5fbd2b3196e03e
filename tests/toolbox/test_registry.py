"""Registry: a built-in is the module algorithms/<group>/<name>.py, plugins come in through the
entry-point group, one module imported per run, list/help
from the cached spec index, and a foreign ``algorithms`` package is refused before it runs."""

from __future__ import annotations

import ast
import base64
import hashlib
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from toolbox import registry, spec_cache

ROOT = Path(__file__).resolve().parents[2]


def registered_in_sources() -> dict[str, str]:
    """id -> "module:Class" of every @register'ed class under algorithms/, read from the source."""
    found = {}
    for path in sorted((ROOT / "algorithms").rglob("*.py")):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef) and any(
                    getattr(d, "id", None) == "register" for d in node.decorator_list):
                ident = next(n.value.value for n in node.body if isinstance(n, ast.Assign)
                             and getattr(n.targets[0], "id", None) == "id")
                module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
                found[ident] = f"{module}:{node.name}"
    return found


def test_every_module_registers_the_id_of_its_path():
    """One registration: algorithms/<group>/<name>.py holds the class of id 'group:name'."""
    in_sources = registered_in_sources()
    assert len(in_sources) >= 43
    by_path = {i: f"{m}:{in_sources[i].split(':')[1]}" for i, m in registry.builtin_modules().items()
               if i in in_sources}
    assert by_path == in_sources, "a module algorithms/group/name.py must register 'group:name'"
    assert set(registry.builtin_modules()) == set(in_sources), "a module without its algorithm"
    for algorithm_id in in_sources:
        assert registry.get(algorithm_id).id == algorithm_id


def test_built_ins_are_not_entry_points_too():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"].get(
        "entry-points", {}).get(registry.ENTRY_POINT_GROUP, {})
    assert not set(declared) & set(registered_in_sources())


def python(code: str, tmp_path: Path, **env) -> subprocess.CompletedProcess:
    environ = os.environ | {"XDG_CACHE_HOME": str(tmp_path / "cache")} | env
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=tmp_path, env=environ, timeout=300)


LOADED = ("import sys; print(sorted(m for m in sys.modules if m.startswith('algorithms.') "
          "or m in ('numba', 'geopandas', 'scipy', 'rasterio', 'pandas')))")


def test_get_imports_one_algorithm_module(tmp_path):
    proc = python("import toolbox; toolbox.get('orientation:intersect');" + LOADED, tmp_path)
    assert proc.returncode == 0, proc.stderr
    modules = [m for m in eval(proc.stdout) if m.startswith("algorithms.")]
    assert modules == ["algorithms.orientation", "algorithms.orientation.intersect"]


def test_list_and_help_read_the_cached_index_without_importing_algorithms(tmp_path):
    first = python("from toolbox.registry import spec_index; n = len(spec_index()); "
                   "print(n)", tmp_path)
    assert first.returncode == 0, first.stderr
    assert int(first.stdout) >= 23
    cached = list((tmp_path / "cache" / "photogrammetry-toolbox").glob("specs-*.marshal"))
    assert len(cached) == 1
    second = python("from toolbox.registry import spec_index, get_spec; spec_index(); "
                    "get_spec('dem:idw');" + LOADED, tmp_path)
    assert second.returncode == 0, second.stderr
    assert eval(second.stdout) == []  # no algorithm module, no heavy library


def test_index_is_rebuilt_when_a_source_changes(tmp_path, monkeypatch):
    """Through spec_index only: an index marked with a fake spec under the current full key (and
    no quick key, so that the full key decides) is served; once a source changes it is rebuilt."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert "x:y" not in registry.spec_index()  # built and cached
    path = spec_cache.index_path()
    key = spec_cache.read_index(path, spec_cache.quick_key(), field="quick")["key"]
    assert spec_cache.write_index(path, key, {"x:y": {"id": "x:y"}}, {})
    assert spec_cache.read_index(path, key + "0") is None
    assert "x:y" in registry.spec_index()  # the marked index is what the key serves
    source = ROOT / "algorithms" / "vector" / "info.py"
    st = source.stat()
    try:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
        rebuilt = registry.spec_index()
    finally:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert "x:y" not in rebuilt and "vector:info" in rebuilt


def test_index_matches_the_classes(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    index = registry.spec_index()
    for alg in registry.algorithms():
        assert json.loads(json.dumps(alg.spec())) == index[alg.id]


def test_foreign_algorithms_package_is_refused_before_it_runs(tmp_path):
    foreign = tmp_path / "foreign" / "algorithms"
    foreign.mkdir(parents=True)
    marker = tmp_path / "foreign_code_ran"
    (foreign / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    subprocess.run([sys.executable, "-m", "toolbox.cli", "list"], capture_output=True, check=True,
                   cwd=tmp_path, env=os.environ | {"XDG_CACHE_HOME": str(tmp_path / "cache")})
    # a fresh spec index of the environment without the foreign package: not trusted for it
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "vector:info"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300,
                          env=os.environ | {"PYTHONPATH": str(tmp_path / "foreign"),
                                            "XDG_CACHE_HOME": str(tmp_path / "cache")})
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "'algorithms' package found at" in lines[0]
    assert "is not part of photogrammetry-toolbox" in lines[0] and str(foreign) in lines[0]
    assert not marker.exists()


def test_package_check_is_remembered_until_the_key_changes(tmp_path, monkeypatch):
    """`toolbox run` without a spec index (never a `toolbox list`) read the package metadata in
    every process; a passed check is now recorded under the quick key and trusted until it
    changes (a source edited here; an install, the test above)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    calls = []

    def belongs(name, init_file):
        calls.append(name)
        return True

    monkeypatch.setattr(registry, "_belongs_to_distribution", belongs)
    check = registry.check_own_package.__wrapped__  # without the per-process cache
    assert check("algorithms") == ROOT / "algorithms"
    assert calls == ["algorithms"]
    assert check("algorithms") == ROOT / "algorithms" and calls == ["algorithms"]
    check("toolbox")  # recorded beside the first
    assert calls == ["algorithms", "toolbox"]
    assert spec_cache.packages_checked("algorithms") and spec_cache.packages_checked("toolbox")
    source = ROOT / "algorithms" / "vector" / "info.py"
    st = source.stat()
    try:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
        assert not spec_cache.packages_checked("algorithms")
        check("algorithms")
    finally:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert calls == ["algorithms", "toolbox", "algorithms"]


def test_remembered_check_does_not_cover_a_foreign_package(tmp_path):
    """A check passed in the clean environment is not trusted once another 'algorithms'
    package comes first on the path (its origin is in the key)."""
    foreign = tmp_path / "foreign" / "algorithms"
    foreign.mkdir(parents=True)
    marker = tmp_path / "foreign_code_ran"
    (foreign / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    cache = {"XDG_CACHE_HOME": str(tmp_path / "cache")}
    clean = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "vector:info"],
                           capture_output=True, text=True, cwd=tmp_path, timeout=300,
                           env=os.environ | cache)
    assert clean.returncode == 2 and "INPUT" in clean.stderr  # past the package check
    assert list((tmp_path / "cache" / "photogrammetry-toolbox").glob("checked-*.marshal"))
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "vector:info"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300,
                          env=os.environ | cache | {"PYTHONPATH": str(tmp_path / "foreign")})
    assert proc.returncode == 2
    assert "is not part of photogrammetry-toolbox" in proc.stderr and str(foreign) in proc.stderr
    assert not marker.exists()


class FakeDist:
    """A non-editable install: RECORD lists algorithms/__init__.py with its hash."""

    def __init__(self, site: Path, digest: str):
        from importlib.metadata import PackagePath

        record = PackagePath("algorithms/__init__.py")
        record.hash = type("Hash", (), {"mode": "sha256", "value": digest})()
        self.files, self.site = [record], site

    def read_text(self, name):
        return None

    def locate_file(self, path):
        return self.site / path


@pytest.mark.parametrize("same_content", [True, False])
def test_wheel_install_checks_record_hash(tmp_path, monkeypatch, same_content):
    init = tmp_path / "algorithms" / "__init__.py"
    init.parent.mkdir()
    init.write_text("# ours\n")
    ours = b"# ours\n" if same_content else b"# an overwritten copy\n"
    digest = base64.urlsafe_b64encode(hashlib.sha256(ours).digest()).rstrip(b"=").decode()
    monkeypatch.setattr(registry, "distribution", lambda name: FakeDist(tmp_path, digest))
    # private on purpose: check_own_package reads the real package's origin, not a fake wheel's
    assert registry._belongs_to_distribution("algorithms", init.resolve()) is same_content
    assert registry._belongs_to_distribution("toolbox", init.resolve()) is False


HEAVY = ("numba", "geopandas", "pandas", "rasterio", "pyogrio", "cv2", "triangle", "dask", "scipy",
         "skimage", "matplotlib")
# Algorithms still heavy at import through library modules (none left). Never grow this set.
KNOWN_HEAVY: set[str] = set()


def test_framework_and_algorithm_modules_import_nothing_heavy(tmp_path):
    """`toolbox run` pays for the kernels an algorithm uses, inside process(), not at import."""
    modules = sorted(v.split(":")[0] for k, v in registered_in_sources().items()
                     if k not in KNOWN_HEAVY)
    code = ("import sys, importlib, toolbox, toolbox.cli, toolbox.runner, toolbox.report\n"
            f"for m in {modules!r}: importlib.import_module(m)\n"
            f"print(sorted(h for h in {HEAVY!r} if h in sys.modules))")
    proc = python(code, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert eval(proc.stdout) == [], "move these imports into process() or a function"


def test_quick_index_key_follows_installs_and_sources(tmp_path, monkeypatch):
    """The key read before any package metadata changes when a sys.path folder gains an entry
    (a distribution installed there) and when a source of ours changes."""
    site = tmp_path / "site"
    site.mkdir()
    import sys

    monkeypatch.setattr(sys, "path", [sys.path[0], str(site), *sys.path[1:]])  # [0]: the script's
    key = spec_cache.quick_key()
    assert spec_cache.quick_key() == key
    os.utime(site, ns=(1, 1))
    (site / "plugin-1.0.dist-info").mkdir()
    assert spec_cache.quick_key() != key
    key = spec_cache.quick_key()
    source = ROOT / "algorithms" / "vector" / "info.py"
    st = source.stat()
    try:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
        assert spec_cache.quick_key() != key
    finally:
        os.utime(source, ns=(st.st_atime_ns, st.st_mtime_ns))


def test_quick_key_of_an_installed_package_follows_its_folder(tmp_path, monkeypatch):
    """In site-packages (``pip install .``) our files change only through an install, which adds
    or removes entries in that folder: the key follows the folder, not every file (no walk over
    the sources at each `toolbox help`); a source tree is stamped file by file (test above)."""
    site = tmp_path / "lib" / "site-packages"
    package = site / "algorithms"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "info.py").write_text("")
    monkeypatch.setattr(sys, "path", [sys.path[0], str(site), *sys.path[1:]])
    origin = spec_cache._origin
    monkeypatch.setattr(spec_cache, "_origin", lambda name: str(package / "__init__.py")
                        if name == "algorithms" else origin(name))
    key = spec_cache.quick_key()
    os.utime(package / "info.py", ns=(1, 1))
    assert spec_cache.quick_key() == key
    os.utime(site, ns=(1, 1))
    (site / "photogrammetry_toolbox-0.1.1.dist-info").mkdir()  # an install
    assert spec_cache.quick_key() != key
