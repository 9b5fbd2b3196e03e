"""The per-user cache file of the algorithm spec index: where it is, whether it is still fresh,
reading and writing it. :mod:`toolbox.registry` builds the index; ``toolbox list`` and ``help``
read it here without importing any algorithm module (:mod:`toolbox.cli.quick`).

Light on purpose (no ``logging``, ``hashlib``, ``json`` or package metadata at import): a fresh
index answers ``toolbox help ID`` in a few milliseconds. The file is a :mod:`marshal` dump (the
format of ``.pyc`` files; it loads about 15 times faster than the same JSON) named by the toolbox
version, the interpreter's cache tag (marshal's format may change between Python versions) and
the environment (``sys.prefix``). Like every per-user cache file it can be deleted at any time.
"""

from __future__ import annotations

import marshal
import os
import sys

from toolbox.cache import sources_stamp  # noqa: F401 - (the registry reads it here)
from toolbox.version import __version__

OWN_PACKAGES = ("toolbox", "algorithms")
#: the folders of an installed distribution: their files change only through an install, which
#: adds or removes entries in that folder (its modification time is in :func:`quick_key`)
INSTALL_FOLDERS = ("site-packages", "dist-packages")


def index_path() -> str:
    """``<user cache>/specs-<version>-<python tag>-<environment>.marshal``: one file per
    environment (two virtual environments sharing the user's cache folder would otherwise
    overwrite each other's index at every call)."""
    import zlib

    from toolbox.cache import user_cache_path

    env = f"{zlib.crc32(sys.prefix.encode()):08x}"
    return user_cache_path(f"specs-{__version__}-{sys.implementation.cache_tag}-{env}.marshal")




def _origin(package: str) -> str | None:
    """Where ``package`` would be imported from (its ``__init__.py``), without importing it:
    ``importlib.util.find_spec`` for a top-level name, without importing ``importlib.util``
    (with ``functools`` and ``collections``, a tenth of a quick ``toolbox help``)."""
    spec = getattr(sys.modules.get(package), "__spec__", None)
    for finder in sys.meta_path if spec is None else ():
        find = getattr(finder, "find_spec", None)
        spec = find(package, None) if find is not None else None
        if spec is not None:
            break
    return getattr(spec, "origin", None)


def _installed(origin: str) -> bool:
    """A package inside ``site-packages`` (a ``pip install .``), not a source tree."""
    return os.path.basename(os.path.dirname(os.path.dirname(origin))) in INSTALL_FOLDERS


def quick_key() -> tuple:
    """A freshness key computed without package metadata: the version, the interpreter, the
    modification times of the ``sys.path`` folders (installing, upgrading or removing a
    distribution, a plugin among them, adds or removes entries there), where ``toolbox`` and
    ``algorithms`` are found and, for a source tree (an editable install, edited in place), the
    stamp of their sources. ``sys.path[0]`` (the script's folder, or the working folder for ``-c``
    and ``-m``: it depends on how the toolbox was started) and the working folder are left out
    (their files come and go; a package found there changes the packages' origins)."""
    cwd = os.getcwd()
    folders = []
    for entry in sys.path[1:]:
        folder = os.path.abspath(entry or cwd)
        if folder == cwd:
            continue
        try:
            folders.append((folder, os.stat(folder).st_mtime_ns))
        except OSError:
            folders.append((folder, None))
    parts: list[object] = [__version__, sys.prefix, sys.implementation.cache_tag, tuple(folders)]
    for package in OWN_PACKAGES:
        origin = _origin(package)
        parts.append(origin)
        if origin and not _installed(origin):
            parts.append(sources_stamp(os.path.dirname(origin)))
    return tuple(parts)


def read_index(path: str | os.PathLike, key: object, field: str = "key") -> dict[str, object] | None:
    """The cached ``{"specs": {id: spec}, "aliases": {old: new}}`` if the file's ``field``
    (``"key"`` or ``"quick"``) equals ``key``, else None (missing, stale or unreadable)."""
    data = _load(path)
    if not isinstance(data, dict) or data.get(field) != key or "specs" not in data:
        return None
    return data


def _load(path: str | os.PathLike) -> object:
    """The object marshalled in the cache file ``path``; None if missing or unreadable."""
    try:
        with open(path, "rb") as file:
            return marshal.loads(file.read())  # marshal.load(file) reads object by object
    except (OSError, ValueError, EOFError, TypeError):
        return None


def fresh_index() -> dict[str, object] | None:
    """The cached index if nothing was installed or edited since it was written, else None."""
    return read_index(index_path(), quick_key(), field="quick")


def checked_path() -> str:
    """``<user cache>/checked-...marshal``: which of our packages passed
    :func:`toolbox.registry.check_own_package` under which :func:`quick_key`."""
    return index_path().replace(os.sep + "specs-", os.sep + "checked-")


def packages_checked(package: str, key: object = None) -> bool:
    """``package`` passed the metadata check under the current :func:`quick_key` (``key``,
    computed if not given: nothing installed, removed or edited since, the packages' origins
    the same)."""
    data = _load(checked_path())
    return isinstance(data, dict) and data.get("key") == (quick_key() if key is None else key) \
        and package in data.get("packages", ())


def remember_checked(package: str, key: object = None) -> None:
    """Record that ``package`` passed the check under :func:`quick_key` (``key``, computed if
    not given), with those recorded under the same key; a cache folder that cannot be written
    only costs the check again."""
    from toolbox.errors import OutputWriteError
    from toolbox.io.staging import atomic_path

    key = quick_key() if key is None else key
    path, packages = checked_path(), {package}
    data = _load(path)
    if isinstance(data, dict) and data.get("key") == key:
        packages |= set(data.get("packages", ()))
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with atomic_path(path, "package check") as staged:
            staged.write_bytes(marshal.dumps({"key": key, "packages": sorted(packages)}))
    except (OSError, OutputWriteError):
        pass


def write_index(path: str | os.PathLike, key: object, specs: dict[str, dict], aliases: dict[str, str],
                quick: object = None) -> bool:
    """Write the index atomically; False when the cache folder cannot be written (it only costs
    speed). ``specs`` must hold JSON values only (the index serves ``help --json``)."""
    from toolbox.errors import OutputWriteError
    from toolbox.io.staging import atomic_path

    data = {"key": key, "quick": quick, "specs": specs, "aliases": aliases}
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with atomic_path(path, "spec index") as staged:
            staged.write_bytes(marshal.dumps(data))
    except (OSError, OutputWriteError):
        return False
    return True
