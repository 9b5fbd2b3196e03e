"""Registry: a built-in algorithm ``group:name`` is the class decorated with :func:`register` in
the module ``algorithms/group/name.py`` (one file per id, found by its path: no other list to keep);
third-party algorithms come in through the ``toolbox.algorithms`` entry-point group
(``"myplugin:tool" = "mypackage.tool:Tool"``).

- :func:`get` imports the module of one algorithm only (``toolbox run``);
- :func:`algorithms` imports every one (Python API);
- :func:`spec_index` answers ``toolbox list`` / ``help`` from a per-user cached index of the specs,
  so that they import no algorithm module while the installed sources are unchanged.

The import names ``toolbox`` and ``algorithms`` are also used by unrelated packages: before an
entry point into either is loaded, the package must be the one of our distribution
(:func:`check_own_package`), otherwise :class:`ForeignPackageError`. Renamed ids stay reachable
through :data:`ALIASES` (an id is never reused).
"""

from __future__ import annotations

import functools
import importlib.util
import json
import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlparse

from toolbox.errors import AlgorithmNotFoundError, ToolboxError
from toolbox.spec_cache import (
    OWN_PACKAGES,
    index_path,
    packages_checked,
    quick_key,
    read_index,
    remember_checked,
    sources_stamp,
    write_index,
)
from toolbox.version import __version__

if TYPE_CHECKING:  # imported where used: a cached `toolbox list` / `help` needs no spec classes
    from importlib.metadata import EntryPoint  # nor the package metadata

    from toolbox.algorithm import Algorithm

log = logging.getLogger("toolbox")

ENTRY_POINT_GROUP = "toolbox.algorithms"
DISTRIBUTION = "photogrammetry-toolbox"
ALIASES: dict[str, str] = {"raster:hillshade": "dem:hillshade"}  # old id -> current id

_registry: dict[str, type[Algorithm]] = {}
_indexed: set[str] = set()  # built-in ids and ids loaded through an entry point (the spec index)
_loaded_all = False


class ForeignPackageError(ToolboxError):
    """An ``algorithms`` or ``toolbox`` package that is not part of photogrammetry-toolbox."""


def register(cls: type[Algorithm]) -> type[Algorithm]:
    """Class decorator adding an algorithm to the registry (checks its spec)."""
    cls.check_spec()
    existing = _registry.get(cls.id)
    if existing is not None and existing is not cls and (
            existing.__module__, existing.__qualname__) != (cls.__module__, cls.__qualname__):
        raise TypeError(f"algorithm id {cls.id!r} is registered twice "
                        f"({existing.__module__} and {cls.__module__})")
    _registry[cls.id] = cls
    return cls


# -- who owns 'toolbox' and 'algorithms' ------------------------------------------------------------
def _editable_root(dist) -> Path | None:
    """The project folder of an editable (``pip install -e``) install, else None."""
    text = dist.read_text("direct_url.json")
    if not text:
        return None
    info = json.loads(text)
    if not info.get("dir_info", {}).get("editable") or not info.get("url", "").startswith("file:"):
        return None
    return Path(_url2pathname(urlparse(info["url"]).path)).resolve()


def _url2pathname(path: str) -> str:
    """``urllib.request.url2pathname`` without importing ``urllib.request`` (it pulls in
    ``http.client``, ``ssl`` and ``email``: about 20 ms of every ``toolbox list`` and ``help``)."""
    if os.name == "nt":
        from nturl2path import url2pathname

        return url2pathname(path)
    from urllib.parse import unquote

    return unquote(path)


def _record_hash_matches(path: Path, file_hash) -> bool:
    if file_hash is None or file_hash.mode != "sha256":
        return True
    import base64
    import hashlib

    digest = base64.urlsafe_b64encode(hashlib.sha256(path.read_bytes()).digest()).rstrip(b"=")
    return digest.decode() == file_hash.value


def entry_points(group: str):
    """``importlib.metadata.entry_points``, imported on first use (with ``email``, about a
    quarter of a cached ``toolbox help``)."""
    from importlib import metadata

    return metadata.entry_points(group=group)


def distribution(name: str):
    """``importlib.metadata.distribution``, imported on first use."""
    from importlib import metadata

    return metadata.distribution(name)


def _belongs_to_distribution(name: str, init_file: Path) -> bool:
    from importlib.metadata import PackageNotFoundError

    try:
        dist = distribution(DISTRIBUTION)
    except PackageNotFoundError:  # a source tree on sys.path: the two packages sit side by side
        return init_file.parent.parent == Path(__file__).resolve().parent.parent
    root = _editable_root(dist)
    if root is not None:
        return init_file.is_relative_to(root)
    for record in dist.files or ():
        if record.as_posix() == f"{name}/__init__.py":
            return (Path(dist.locate_file(record)).resolve() == init_file
                    and _record_hash_matches(init_file, record.hash))
    return False


def _checked_now(name: str, init_file: Path, key: object) -> bool:
    if not _belongs_to_distribution(name, init_file):
        return False
    remember_checked(name, key)
    return True


@functools.cache
def check_own_package(name: str) -> Path:
    """The folder of package ``name`` (``toolbox`` or ``algorithms``) after checking that it belongs
    to the photogrammetry-toolbox distribution; :class:`ForeignPackageError` otherwise.

    Found without importing the package, so a foreign one never runs. The package metadata is
    not read again (30-50 ms, about a tenth of a small ``toolbox run``) while the spec index is
    fresh (it was written after this check passed) or this package's last check is (recorded
    by :func:`toolbox.spec_cache.remember_checked`): both keys change with the packages' origins
    and whenever a distribution is installed or removed (:func:`toolbox.spec_cache.quick_key`).
    """
    spec = importlib.util.find_spec(name)
    init_file = Path(spec.origin).resolve() if spec is not None and spec.origin else None
    key = quick_key()
    if init_file is None or not (read_index(index_path(), key, field="quick") is not None
                                 or packages_checked(name, key)
                                 or _checked_now(name, init_file, key)):
        where = init_file.parent if init_file is not None else "nowhere (a namespace package)"
        raise ForeignPackageError(
            f"the '{name}' package found at {where} is not part of {DISTRIBUTION} (another "
            f"package uses the name '{name}'); refusing to load algorithms from it: uninstall "
            "that package or use a separate virtual environment")
    return init_file.parent


# -- entry points -----------------------------------------------------------------------------------
def _entry_points() -> dict[str, EntryPoint]:
    found: dict[str, EntryPoint] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep)
    return found


def _is_own(ep: EntryPoint) -> bool:
    return _top_package(ep) in OWN_PACKAGES


def _top_package(ep: EntryPoint) -> str:
    return getattr(ep, "value", "").split(":", 1)[0].split(".", 1)[0]


def _load(ep: EntryPoint) -> type[Algorithm] | None:
    """Import one entry point and register its class. A broken third-party plugin is skipped with a
    warning; a broken built-in is a bug and raises."""
    if _is_own(ep):
        check_own_package(_top_package(ep))
        obj = ep.load()
    else:
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must not break the toolbox
            log.warning("plugin %s could not be loaded: %s", ep.name, exc)
            return None
    from toolbox.algorithm import Algorithm

    if not (isinstance(obj, type) and issubclass(obj, Algorithm)):
        log.warning("entry point %s = %s is not an Algorithm class; skipped", ep.name, ep.value)
        return None
    if _is_own(ep) and ep.name != obj.id:
        raise TypeError(f"entry point {ep.name!r} names {obj.id!r}: the name must be the id")
    existing = _registry.get(obj.id)
    if existing is None:
        register(obj)
    elif existing is not obj and not _is_own(ep):
        log.warning("plugin %s: id %s is already taken by %s; skipped", ep.name, obj.id,
                    existing.__module__)
        return None
    _indexed.add(obj.id)
    return obj


# -- built-ins: algorithms/<group>/<name>.py ---------------------------------------------------------
@functools.cache
def builtin_modules() -> dict[str, str]:
    """``{"group:name": "algorithms.group.name"}`` for every module file under ``algorithms/``."""
    root = check_own_package("algorithms")
    found = {}
    for group in sorted(p for p in root.iterdir() if p.is_dir() and (p / "__init__.py").exists()):
        for module in sorted(group.glob("*.py")):
            if not module.name.startswith("_"):
                found[f"{group.name}:{module.stem}"] = f"algorithms.{group.name}.{module.stem}"
    return found


def _load_builtin(algorithm_id: str) -> None:
    """Import the module of a built-in id; it must register exactly that id."""
    importlib.import_module(builtin_modules()[algorithm_id])
    if algorithm_id not in _registry:
        raise TypeError(f"{builtin_modules()[algorithm_id]} registers no algorithm {algorithm_id!r} "
                        "(a module algorithms/group/name.py holds the algorithm 'group:name')")
    _indexed.add(algorithm_id)


def discover() -> None:
    """Import every algorithm module once (built-in and plugins)."""
    global _loaded_all
    if not _loaded_all:
        for algorithm_id in builtin_modules():
            _load_builtin(algorithm_id)
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            _load(ep)
        _loaded_all = True


def algorithms() -> list[type[Algorithm]]:
    """Every registered algorithm, sorted by id (imports every algorithm module)."""
    discover()
    return [_registry[k] for k in sorted(_registry)]


def _not_found(algorithm_id: str, known) -> AlgorithmNotFoundError:
    import difflib

    close = difflib.get_close_matches(algorithm_id, list(known), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else "; run 'toolbox list' to see them"
    return AlgorithmNotFoundError(f"no algorithm {algorithm_id!r}{hint}")


def get(algorithm_id: str) -> type[Algorithm]:
    """The algorithm class for ``algorithm_id`` (aliases resolved), importing only its module.

    Raises :class:`AlgorithmNotFoundError` suggesting close ids.
    """
    key = ALIASES.get(algorithm_id, algorithm_id)
    if key in _registry:
        return _registry[key]
    if key in builtin_modules():
        _load_builtin(key)
        return _registry[key]
    ep = _entry_points().get(key)
    if ep is not None and _load(ep) is not None and key in _registry:
        return _registry[key]
    discover()  # a plugin whose entry-point name is not its id
    if key in _registry:
        return _registry[key]
    raise _not_found(algorithm_id, _registry)


# -- the spec index (list / help without importing algorithm modules) ------------------------------
def _index_key(eps: dict[str, EntryPoint]) -> str:
    """Changes whenever a spec may have changed: version, entry points, plugin versions, the
    modification times of our sources (an editable install is edited in place)."""
    parts: list[Any] = [__version__]
    for name in sorted(eps):
        ep = eps[name]
        dist = getattr(ep, "dist", None)
        parts.append((name, ep.value, getattr(dist, "name", None), getattr(dist, "version", None)))
    for package in OWN_PACKAGES:
        parts.append(sources_stamp(check_own_package(package)))
    import hashlib

    return hashlib.sha256(json.dumps(parts).encode()).hexdigest()


def spec_index() -> dict[str, dict]:
    """Spec (:meth:`Algorithm.spec`) of every algorithm by id, sorted by id.

    Read from the per-user cache (:mod:`toolbox.spec_cache`) when its key still matches (first
    a key that needs no package metadata, :func:`~toolbox.spec_cache.quick_key`, then one of the
    entry points and our sources), else built by importing every algorithm and cached. The
    specs are JSON values (as ``help --json`` prints them). Algorithms registered in this process
    without an entry point (scripts, tests) are added from their classes.
    """
    path = index_path()
    quick = quick_key()
    cached = read_index(path, quick, field="quick")  # nothing installed or edited since
    if cached is None:
        key = _index_key(_entry_points())  # the built-ins are in the sources' stamp
        cached = read_index(path, key)
        if cached is None:
            discover()
            built = {i: _registry[i].spec() for i in sorted(_indexed)}
            cached = {"specs": json.loads(json.dumps(built))}
        if not write_index(path, key, cached["specs"], ALIASES, quick):
            log.debug("spec index not cached in %s", path)
    specs = cached["specs"]
    extra = {i: cls.spec() for i, cls in _registry.items() if i not in specs}
    merged = specs | extra
    return {i: merged[i] for i in sorted(merged)}


def get_spec(algorithm_id: str) -> dict:
    """The spec of one algorithm (aliases resolved) from :func:`spec_index`."""
    index = spec_index()
    key = ALIASES.get(algorithm_id, algorithm_id)
    if key not in index:
        raise _not_found(algorithm_id, index)
    return index[key]
