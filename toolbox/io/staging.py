"""Atomic outputs: write into a hidden temporary folder beside the final file, move on success.

A failed or canceled run leaves nothing behind (also the output folders it created); a
successful one moves each output into place. Without ``overwrite`` the move is a hard link that
fails when the target appeared meanwhile (another run wrote it), so a run never replaces a file
it did not mean to. The staged file keeps the final file name, so drivers and layer names that
derive from it are unaffected.

Staging folders are named ``.NAME.PID-START-MACHINE.RANDOM.part`` (:func:`_mkdtemp`: the
process's id and start time, a tag of the host and of its boot): after a run killed by SIGKILL
(which no program can catch), the next run writing into the same folder removes the staging
folders there of runs of this host and boot whose process is gone (or whose id now names a
process started at another time); another host's (a container, a cluster node on shared
storage) are left alone: its processes cannot be seen from here (:func:`staging_leftovers`).

An output *folder* is staged whole (``.FOLDER.PID.RANDOM.part/FOLDER``): on success each file it
holds is moved into the final folder one by one, with the same checks as a file output (never
onto an input, an existing file only with ``overwrite``); other files of the final folder are left
alone (an existing output folder in a folder the run may not write to is staged inside itself:
``FOLDER/.FOLDER.PID.RANDOM.part/FOLDER``). A commit that fails midway undoes the moves done so
far (replaced files are restored), so a run writes all of its files or none. Commits into one
folder take turns (an ``flock`` on the folder), so two runs writing the same files leave one
run's files, never a mix of both.

Every file moved is a dataset (a GeoTIFF, a ``.shp``, a per-layer ``<stem>_<layer>.shp``) or a
file GDAL reads with one (:func:`dataset_files`: ``.aux.xml``, ``-wal``, a Shapefile's
``.dbf``/``.prj``/``.qix``): each replaces an existing file only with ``overwrite``, except a
leftover of a dataset that does not exist (its ``.aux.xml``, ``-wal``, ``.qix``: no one's). The
files GDAL would read with a new dataset that the run does not write are removed first, so a new
file never meets an old index, PAM file or write-ahead log.
"""

from __future__ import annotations

import errno
import functools
import hashlib
import os
import re
import shutil
import signal
import socket
import tempfile
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from toolbox.errors import OutputExistsError, OutputWriteError, ParameterError

try:
    import fcntl
except ImportError:  # Windows: no flock (commits into one folder are then not serialised)
    fcntl = None

SQLITE_JOURNALS = ("-wal", "-shm", "-journal")  # a GeoPackage's, while SQLite has it open
# files GDAL/OGR keep beside a dataset, named after its whole name (a.tif.aux.xml, x.gpkg-wal)
SIDECAR_SUFFIXES = (".aux.xml", ".ovr", ".msk", *SQLITE_JOURNALS)
# a Shapefile's files, named after its stem; GDAL reads all but .qmd (QGIS's metadata)
SHAPEFILE_PARTS = (".shp", ".shx", ".dbf", ".prj", ".cpg", ".qix", ".sbn", ".sbx", ".qmd")
SHAPEFILE_ONLY = (".shx", ".qix", ".sbn", ".sbx")  # meaningless without their .shp
WORLD_FILES = (".tfw", ".tifw", ".jgw", ".pgw", ".wld")
STYLE_SIDECARS = (".qml", ".sld")  # a layer's default style in QGIS, named after its stem


_FINAL_OF: dict[Path, Path] = {}  # staged path -> final path, while a run is staged
#: the final paths every commit of a run (``OutputStaging(record=True)``) of this process moved
#: into place, in order: what a command interrupted after a commit (a batch's steps done) names
COMMITTED: list[Path] = []
_HELD: list[int | None] = [0, None]  # sections signals wait for (all threads), the signal held
_HELD_LOCK = threading.Lock()  # threads commit too (ortho:batch's photos)


def hold_signal(signum: int) -> bool:
    """For a signal handler: True while files are moved into place, a failed commit undone or a
    staging folder removed (the signal is then raised once that is done, so an interruption
    never leaves half a commit, half an undo or half a staging folder), else False."""
    if not _HELD[0]:  # read without the lock: a handler must not wait for one
        return False
    if _HELD[1] is None:
        _HELD[1] = signum
    if _HELD[0]:
        return True
    _HELD[1] = None  # the last section (another thread's) ended meanwhile: raise it now
    return False


#: the signals a section holds in the main thread whatever handler is installed (Python's
#: default one raises KeyboardInterrupt at once: toolbox.run from a script or a notebook)
HELD_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                     if hasattr(signal, name))
_MAIN_DEPTH = [0]  # sections open in the main thread (handlers installed by the outermost)


def _hold_in_main_thread() -> dict[int, object]:
    """In the main thread, outside any other section: a handler that holds each of
    :data:`HELD_SIGNALS` (:func:`hold_signal`) instead of the installed one, which is returned
    to be put back; elsewhere nothing (a handler can only be set from the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    _MAIN_DEPTH[0] += 1
    if _MAIN_DEPTH[0] > 1:
        return {}
    saved: dict[int, object] = {}

    def hold(signum, frame):
        if hold_signal(signum):
            return
        previous = saved.get(signum)  # the section just ended: what the signal did before
        if callable(previous):
            previous(signum, frame)
        elif previous != signal.SIG_IGN:
            signal.signal(signum, signal.SIG_DFL)
            signal.raise_signal(signum)

    for signum in HELD_SIGNALS:
        try:
            previous = signal.getsignal(signum)
            if previous is None:  # a handler set from C: not ours to replace
                continue
            saved[signum] = previous
            signal.signal(signum, hold)
        except (ValueError, OSError):  # not the main interpreter
            saved.pop(signum, None)
    return saved


def _release_in_main_thread(saved: dict[int, object]) -> None:
    if threading.current_thread() is not threading.main_thread():
        return
    _MAIN_DEPTH[0] -= 1
    for signum, previous in saved.items():
        signal.signal(signum, previous)


@contextmanager
def _signals_held():
    """Signals that :func:`hold_signal` kept wait for the end of the block, then are raised.

    The command line's handler asks :func:`hold_signal` itself; in the main thread the block
    also installs a holding handler for SIGINT, SIGTERM and SIGHUP, so a Ctrl-C during a commit
    of :func:`toolbox.run` called from Python (default handler: KeyboardInterrupt at once) waits
    too, then reaches the handler that was installed before."""
    with _HELD_LOCK:
        _HELD[0] += 1
    saved = _hold_in_main_thread()
    try:
        yield
    finally:
        with _HELD_LOCK:
            _HELD[0] -= 1
            signum = _HELD[1] if not _HELD[0] else None
            if signum is not None:
                _HELD[1] = None
        _release_in_main_thread(saved)
        if signum is not None:
            signal.raise_signal(signum)


def final_path(path: str | Path) -> Path:
    """The final path of ``path`` when it is (inside) a staged output, else ``path``: what an
    algorithm names in a listing it writes (e.g. the files of its output folder)."""
    path = Path(path).absolute()
    for staged, final in _FINAL_OF.items():
        if path == staged or staged in path.parents:
            return final / path.relative_to(staged)
    return path


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    except OverflowError:
        return False
    return True


#: bytes of a staging folder's name besides the final name: ".", ".PID" (7 digits at most),
#: "-START" (20 digits at most), "-MACHINE" (12), "." + mkdtemp's 8 random characters, ".part"
_STAGING_EXTRA = 1 + 8 + 21 + 13 + 9 + 5
_NAME_MAX = 255  # bytes of one path component on every common filesystem
#: a staging folder of any output: the final name, the PID, then (since round 17) the start
#: time of the process and the tag of its machine (:func:`machine_tag`); without them, an older
#: version's (judged by the PID alone)
_ANY_STAGING = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)(?:-(?P<start>\d+)-(?P<tag>[0-9a-f]{12}))?"
                          r"\.[^.-]+\.part$", re.DOTALL)
FOREIGN_AGE = 86400.0  # seconds after which another machine's staging folder is warned about


def staging_name(name: str) -> str:
    """The part of a staging folder's name naming the final file ``name``: ``name`` itself, or
    its head when the folder's name would pass the 255-byte limit of a file name (a final name
    of 233 to 255 bytes is a valid name, so its staging folder must be one too)."""
    raw = os.fsencode(name)
    limit = _NAME_MAX - _STAGING_EXTRA
    if len(raw) <= limit:
        return name
    head = raw[:limit]
    while head:  # cut at a character boundary
        try:
            head.decode("utf-8")
            break
        except UnicodeDecodeError:
            head = head[:-1]
    return os.fsdecode(head)


def _staging_pattern(name: str) -> re.Pattern:
    return re.compile(r"^\." + re.escape(staging_name(name))
                      + r"\.(\d+)(?:-\d+-[0-9a-f]{12})?\.[^.-]+\.part$")


def _read(path: str) -> str:
    try:
        with open(path) as f:
            return f.read().strip()
    except OSError:
        return ""


@functools.lru_cache(maxsize=1)
def machine_tag() -> str:
    """12 hex digits naming where this process's id means something: 6 for the host
    (``socket.gethostname()``), 6 for its boot (Linux's boot id) and PID namespace (two
    containers of one host, each with its own process ids, get two tags)."""
    host = hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:6]
    try:
        pid_ns = os.readlink("/proc/self/ns/pid")
    except OSError:
        pid_ns = ""
    boot = f"{_read('/proc/sys/kernel/random/boot_id')}\0{pid_ns}"
    return host + hashlib.sha1(boot.encode()).hexdigest()[:6]


def process_start(pid: int) -> int | None:
    """When process ``pid`` started, as a number that differs for another process given the same
    id later: clock ticks since boot (Linux's /proc/PID/stat, field 22: exact), else psutil's
    create time in hundredths of a second; None when unknown (no such process, no way to tell).
    /proc comes first: psutil derives its time there from a boot time that the kernel shifts
    with clock corrections, so two processes may see the same start a second apart."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
        return int(stat[stat.rindex(b")") + 2:].split()[19])  # fields after "pid (comm)"
    except (OSError, ValueError, IndexError):
        pass
    try:
        import psutil

        return int(psutil.Process(pid).create_time() * 100)
    except Exception:  # not installed, no such process, access denied
        return None


def _mkdtemp(final: Path, folder: Path) -> Path:
    """A new staging folder for ``final`` in ``folder`` (:func:`staging_name`), its name
    recording this process: id, start time (0: unknown), machine (:func:`machine_tag`)."""
    pid = os.getpid()
    owner = f"{pid}-{process_start(pid) or 0}-{machine_tag()}"
    return Path(tempfile.mkdtemp(prefix=f".{staging_name(final.name)}.{owner}.",
                                 suffix=".part", dir=folder))


def _run_gone(match: re.Match) -> bool | None:
    """Whether the run that made the staging folder ``match`` names has ended: True (its
    process is gone, or its id now names a process started at another time), False (running),
    None (another machine's, or this one's before a restart: nothing here can tell)."""
    pid = int(match.group("pid"))
    if match.group("tag") is None:  # an older version's name: the process id alone
        return not _pid_alive(pid)
    if match.group("tag") != machine_tag():
        return None
    if not _pid_alive(pid):
        return True
    recorded = int(match.group("start"))
    now = process_start(pid)
    return bool(recorded and now is not None and now != recorded)


def staging_leftovers(folders: list[Path], names: tuple[str, ...] = ()
                      ) -> tuple[list[Path], list[tuple[Path, float]]]:
    """The staging folders of any output in ``folders`` (:data:`_ANY_STAGING`): those of runs
    that ended without removing them (killed by SIGKILL, a crash: :func:`_run_gone`), and,
    with their age in seconds, those of another machine not changed for :data:`FOREIGN_AGE`
    (left alone: a run there may still write them; the user may know it does not). A folder
    named by an older version (the PID alone: no machine to tell) is judged only when it
    stages one of the final names ``names``, as that version did."""
    gone, foreign = [], []
    own = {staging_name(name) for name in names}
    for folder in folders:
        try:
            entries = list(folder.iterdir()) if folder.is_dir() else []
        except OSError:
            continue
        for entry in entries:
            match = _ANY_STAGING.match(entry.name)
            if not match or entry.is_symlink() or not entry.is_dir() or (
                    match.group("tag") is None and match.group("name") not in own):
                continue
            verdict = _run_gone(match)
            if verdict:
                gone.append(entry)
            elif verdict is None:
                try:
                    age = time.time() - entry.stat().st_mtime
                except OSError:
                    continue
                if age > FOREIGN_AGE:
                    foreign.append((entry, age))
    return gone, foreign


def stale_staging_folders(final: Path) -> list[Path]:
    """Staging folders beside ``final`` (or in it: an output folder whose parent is read-only),
    of any output, left by runs that are gone (:func:`staging_leftovers`)."""
    final = Path(final)
    return staging_leftovers([final.parent, final], (final.name,))[0]


def disk_usage(folder: Path) -> int:
    """Bytes the files under ``folder`` take on disk that removing it frees (a file with other
    hard links frees nothing; a sparse file only its blocks); no link is followed."""
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            try:
                st = os.lstat(os.path.join(root, name))
            except OSError:
                continue
            if st.st_nlink == 1:
                blocks = getattr(st, "st_blocks", None)
                total += blocks * 512 if blocks is not None else st.st_size
    return total


def final_folder(path: str | Path) -> Path:
    """The folder an output lands in: the parent of a staged file's staging folder, else the
    file's own folder (for names written relative to the output)."""
    path = Path(path).absolute()
    staging = _staging_pattern(path.name)
    return path.parent.parent if staging.match(path.parent.name) else path.parent


def protected_paths(path: Path) -> set[Path]:
    """``path`` (resolved) and the sidecars GDAL/OGR read with it: a Shapefile's parts, world
    files and an existing ``.prj`` of any input (ASCII grids, CSVs... take their CRS from it);
    and its existing default style, ``<stem>.qml``/``.sld``, which QGIS loads with it (an output
    of the same stem in another format would write its own there)."""
    path = Path(path).expanduser().resolve()
    out = {path} | {path.with_name(path.name + s) for s in SIDECAR_SUFFIXES}
    parts = SHAPEFILE_PARTS if path.suffix.lower() == ".shp" else ()
    out |= _stem_files(path, parts + WORLD_FILES)
    return out | {f for f in _stem_files(path, (".prj", *STYLE_SIDECARS)) if f.exists()}


def _stem_files(path: Path, suffixes: tuple[str, ...]) -> set[Path]:
    """``path`` with each of ``suffixes`` instead of its own, in lower and upper case."""
    return {path.with_suffix(c(s)) for s in suffixes for c in (str.lower, str.upper)}


def dataset_files(main: Path, own_only: bool = False) -> set[Path]:
    """The files GDAL reads with ``main`` (its sidecars; a Shapefile's other parts, .qmd
    aside); with ``own_only``, those that mean nothing without ``main`` (named after its whole
    name; a Shapefile's indexes): a leftover of a deleted file, safe to remove."""
    out = {main.with_name(main.name + s) for s in SIDECAR_SUFFIXES}
    if main.suffix.lower() == ".shp":
        out |= _stem_files(main, SHAPEFILE_ONLY if own_only else SHAPEFILE_PARTS[1:-1])
    return out


def open_elsewhere(paths: list[Path]) -> bool:
    """Whether another process holds a lock on one of ``paths`` (SQLite does while it has the
    database open, e.g. QGIS showing a GeoPackage), from Linux's /proc/locks (False elsewhere):
    nothing is opened, so no lock of this process is lost."""
    ids = set()
    for path in paths:
        try:
            st = os.stat(path)
        except OSError:
            continue
        ids.add(f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}")
    try:
        lines = Path("/proc/locks").read_text().splitlines() if ids else []
    except OSError:
        return False
    for fields in map(str.split, lines):  # "1: POSIX ADVISORY READ <pid> fe:00:<inode> 128 128"
        found = [i for i, field in enumerate(fields) if field in ids]
        if found and found[0] > 0 and fields[found[0] - 1] != str(os.getpid()):
            return True
    return False


COMMIT_WAIT = 120.0  # seconds a commit waits for another run's commit into the same folder


@contextmanager
def _folders_locked(folders: list[Path], name: str):
    """An exclusive ``flock`` on each of ``folders`` for the block: the commit of another run
    (another process, or another thread: each lock is its own open file) into one of them
    waits, so two runs writing the same files never interleave their moves (the ``.shp`` of
    one with the ``.dbf`` and ``.shx`` of the other). The folders are locked in sorted order
    (no deadlock); one that cannot be locked (no flock there) is skipped; one held longer than
    :data:`COMMIT_WAIT` is refused. Nothing is created in the folders."""
    fds: list[int] = []
    try:
        for folder in sorted(set(folders)) if fcntl is not None else []:
            try:
                fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
            except OSError:
                continue
            fds.append(fd)
            deadline = time.monotonic() + COMMIT_WAIT
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    if time.monotonic() > deadline:
                        raise ParameterError(name, f"another run has been moving its files into "
                                             f"'{folder}' for {COMMIT_WAIT:.0f} s: run again "
                                             "when it is done") from None
                    time.sleep(0.02)
                except OSError:  # a filesystem without flock
                    break
        yield
    finally:
        for fd in fds:
            os.close(fd)  # releases its lock


def write_error(exc: BaseException, name: str, path: Path | str) -> OutputWriteError:
    """A one-line error for a failed write of output ``name`` at ``path``."""
    code = getattr(exc, "errno", None)
    text = str(getattr(exc, "strerror", None) or exc).splitlines()[0] if str(exc) else ""
    if code in (errno.ENOSPC, errno.EDQUOT):
        what = "no space left on device" if code == errno.ENOSPC else "disk quota exceeded"
        message = f"{what} writing {name} '{path}'; nothing was written"
    elif code == errno.ENAMETOOLONG:
        message = f"{name}: file name too long: '{path}'"
    elif code in (errno.EACCES, errno.EPERM, errno.EROFS):
        message = (f"{name}: cannot write '{path}' ({text or 'permission denied'}): choose a "
                   "folder you can write to")
    else:
        message = f"cannot write {name} '{path}': {text}; nothing was written"
    return OutputWriteError(message, code, str(path))


class OutputStaging:
    """Hands out staged paths for final outputs; :meth:`commit` moves them, :meth:`rollback`
    deletes them (and the folders created for them)."""

    def __init__(self, record: bool = False) -> None:
        self._record = record  # list the commit's outputs in COMMITTED
        self._staged: dict[Path, Path] = {}  # final -> staged
        self._names: dict[Path, str] = {}  # final -> parameter name
        self._is_folder: set[Path] = set()  # finals that are output folders
        self._siblings: dict[Path, list[Path]] = {}  # final -> its declared layer files
        self._folders: list[Path] = []
        self._created_dirs: list[Path] = []  # output folders this run created, deepest last
        self.removed_stale: list[Path] = []  # staging folders of ended runs removed
        self.freed = 0  # bytes their removal freed
        self.foreign_staging: list[tuple[Path, float]] = []  # another machine's, old: (path, age)

    def stage(self, final: str | Path, name: str = "OUTPUT", siblings: list | None = None
              ) -> Path:
        """A staged path for output ``final``. ``siblings``: the files its declared layers go
        to beside it in a one-layer-per-file format (``<stem>_<layer>.shp``): one the run does
        not write (a layer left out this time) is an earlier run's, removed at the commit as a
        stale sidecar is (it would sit beside the new layers as if it were theirs)."""
        with _signals_held():  # a folder made is a folder remembered (and removed on rollback)
            staged = self._stage(final, name)
        if siblings:
            self._siblings[Path(final).expanduser().absolute()] = [
                Path(p).expanduser().absolute() for p in siblings]
        return staged

    def _stage(self, final: str | Path, name: str, folder_output: bool = False) -> Path:
        final = Path(final).expanduser().absolute()
        self._make_parent(final.parent, name)
        self._sweep([final.parent, final], final.name)
        try:
            folder = _mkdtemp(final, final.parent)
        except OSError as exc:
            if not (folder_output and exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS)
                    and final.is_dir() and not final.is_symlink()):
                raise write_error(exc, name, final) from None
            try:  # an existing output folder one may write to, in a folder one may not
                folder = _mkdtemp(final, final)
            except OSError as inner:
                raise write_error(inner, name, final) from None
        self._folders.append(folder)
        staged = folder / final.name
        self._staged[final] = staged
        self._names[final] = name
        _FINAL_OF[staged] = final
        return staged

    def _sweep(self, folders: list[Path], name: str) -> None:
        """Remove the staging folders of ended runs in ``folders`` (any output's: a killed
        ortho's GBs go with the next run writing there; an older version's, of ``name``)."""
        gone, foreign = staging_leftovers(folders, (name,))
        for folder in gone:
            size = disk_usage(folder)
            shutil.rmtree(folder, ignore_errors=True)
            if not os.path.lexists(folder):
                self.removed_stale.append(folder)
                self.freed += size
        known = {path for path, _ in self.foreign_staging}
        self.foreign_staging += [item for item in foreign if item[0] not in known]

    def stage_folder(self, final: str | Path, name: str = "OUTPUT") -> Path:
        """A staged, empty folder standing for output folder ``final``."""
        with _signals_held():
            staged = self._stage(final, name, folder_output=True)
        try:
            staged.mkdir()
        except OSError as exc:
            raise write_error(exc, name, final) from None
        self._is_folder.add(Path(final).expanduser().absolute())
        return staged

    def _make_parent(self, parent: Path, name: str) -> None:
        missing = []
        probe = parent
        while not probe.exists() and probe != probe.parent:
            if probe.is_symlink():  # dangling link: mkdir would fail obscurely
                break
            missing.append(probe)
            probe = probe.parent
        if probe.exists() and not probe.is_dir():
            raise ParameterError(name, f"'{parent}' is under '{probe}', which is a file, not a "
                                 "folder")
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise write_error(exc, name, parent) from None
        self._created_dirs.extend(reversed(missing))

    def staged_path(self, final: str | Path) -> Path | None:
        return self._staged.get(Path(final).expanduser().absolute())

    def written(self, final: str | Path) -> bool:
        staged = self.staged_path(final)
        return staged is not None and staged.exists()

    def items(self) -> list[tuple[str, Path, Path]]:
        """``(parameter name, final, staged)`` of every staged output."""
        return [(self._names[f], f, s) for f, s in self._staged.items()]

    def folder_files(self) -> list[tuple[str, Path, Path]]:
        """``(parameter name, final, staged)`` of every file written in a staged output folder."""
        out = []
        for final in self._is_folder:
            staged = self._staged[final]
            if staged.is_dir():
                out += [(self._names[final], final / f.relative_to(staged), f)
                        for f in sorted(staged.rglob("*")) if not f.is_dir()]
        return out

    def _moves(self) -> list[tuple[str, Path, Path]]:
        """``(name, source, target)`` of every file to move: each staged file first, then the
        files beside it in its private folder (sidecars, a Shapefile's parts, per-layer
        files), then the files of the output folders."""
        moves = []
        for final, staged in self._staged.items():
            if not staged.exists() or final in self._is_folder:
                continue
            items = sorted(staged.parent.iterdir(), key=lambda i: (
                i != staged, i.suffix != staged.suffix, i.name))  # datasets before their parts
            moves += [(self._names[final], item, final.parent / item.name) for item in items]
        moves += [(name, source, target) for name, target, source in self.folder_files()]
        return moves

    def commit(self, overwrite: bool = True, protected: set[Path] | None = None) -> list[Path]:
        """Move every staged file that was written, every file beside it in its private
        staging folder (sidecars) and every file of a staged output folder into place; return
        the final paths written.

        Nothing is moved when a target, or an old file to remove, is in ``protected``
        (resolved input paths, compared by path and by inode: refused whatever ``overwrite``
        says), when it exists without ``overwrite`` (:class:`OutputExistsError`; leftovers of a
        dataset that does not exist aside: see the module) or when a GeoPackage to replace is
        open in another program. A failure midway undoes the moves done (a replaced file is
        restored), so the run writes all of its files or none.
        """
        folders = [final.parent for final in self._staged] + [
            final for final in self._is_folder if final.is_dir()]
        name = next(iter(self._names.values()), "OUTPUT")
        with _folders_locked(folders, name), _signals_held():  # a signal meanwhile is raised
            written = self._commit(overwrite, protected or set())  # once the files are in place
            if self._record:
                COMMITTED.extend(written)
        return written

    def _commit(self, overwrite: bool, protected: set[Path]) -> list[Path]:
        moves = self._moves()
        written = [final for final, staged in self._staged.items() if staged.exists()
                   or final in self._is_folder]
        targets = {target for _, _, target in moves}
        owner = {part: target for target in targets for part in dataset_files(target) & targets}
        replace = set()  # existing targets a commit without overwrite may replace (leftovers)
        stale: dict[Path, str] = {}  # old files GDAL would read with a new one -> output name
        inodes = _ProtectedInodes(protected)  # stated once, at the first target that exists
        for name, _, target in moves:
            _check_target(name, target, protected, inodes)
            main = owner.get(target, target)
            if os.path.lexists(target):
                _check_free(name, target, main, overwrite)
                replace.add(target)
            if main != target:
                continue
            for old in dataset_files(target) - targets:
                if os.path.isfile(old) or os.path.islink(old):
                    _check_target(name, old, protected, inodes)
                    _check_free(name, old, target, overwrite)
                    stale[old] = name
            for sibling in self._siblings.get(target, []):
                if sibling in targets:
                    continue
                for old in {sibling} | dataset_files(sibling):
                    if old not in targets and (os.path.isfile(old) or os.path.islink(old)) \
                            and not _is_protected(old, protected, inodes):  # an input
                        if not overwrite:
                            raise OutputExistsError(name, f"'{old}' exists: a layer file of "
                                                    f"'{target}' that this run does not write "
                                                    "(an earlier run's); pass --overwrite to "
                                                    "remove it")
                        stale[old] = name
            journals = [target.with_name(target.name + s) for s in SQLITE_JOURNALS]
            if any(map(os.path.lexists, journals)) and open_elsewhere([target, *journals]):
                raise ParameterError(name, f"'{target}' is open in another program (QGIS?): "
                                     "close it there and run again")
        try:  # hard links to the files a commit replaces, to restore them if it fails
            first = next(iter(self._staged))  # named like a staging folder: cleaned if killed
            backups = _mkdtemp(first, self._folders[0].parent)
            self._folders.append(backups)
        except (OSError, IndexError, StopIteration):
            backups = None
        done: list[tuple[Path, Path | None, bool]] = []  # target, its backup, existed before
        try:
            # stale files first: an old -wal must never meet the new GeoPackage
            for k, (old, name) in enumerate(stale.items()):
                try:
                    done.append((old, _backup(old, backups, f"stale{k}"), True))
                    old.unlink()
                except FileNotFoundError:
                    pass
                except OSError as exc:
                    raise write_error(exc, name, old) from None
            for k, (name, item, target) in enumerate(moves):
                try:
                    self._make_target_parent(target, name)
                    if os.path.lexists(target) and (overwrite or target in replace):
                        done.append((target, _backup(target, backups, k), True))
                        os.replace(item, target)
                    else:
                        _move_no_replace(item, target)
                        done.append((target, None, False))
                except FileExistsError:
                    raise OutputExistsError(name, f"'{target}' appeared during the run (another"
                                            " run wrote it?); pass --overwrite to replace "
                                            "it") from None
                except OSError as exc:
                    raise write_error(exc, name, target) from None
        except BaseException:
            for target, backup, existed in reversed(done):  # undo: the run fails as a whole
                if backup is not None:
                    try:
                        os.replace(backup, target)
                    except OSError:
                        pass
                elif not existed:
                    _remove(target)
            raise
        self.rollback()  # the created folders that now hold results are not empty: kept
        return written

    def _make_target_parent(self, target: Path, name: str) -> None:
        """Create the (sub)folder of a file of an output folder, remembered for rollback."""
        if not target.parent.is_dir():
            self._make_parent(target.parent, name)

    def rollback(self) -> None:
        with _signals_held():
            self._rollback()

    def _rollback(self) -> None:
        for staged in list(self._staged.values()):
            _FINAL_OF.pop(staged, None)
        for folder in self._folders:
            shutil.rmtree(folder, ignore_errors=True)
        self._folders.clear()
        for folder in reversed(self._created_dirs):  # deepest first; only if still empty
            try:
                folder.rmdir()
            except OSError:
                pass
        self._created_dirs.clear()


def _backup(target: Path, folder: Path | None, key) -> Path | None:
    """A hard link to ``target`` in ``folder`` (to restore it if the commit fails), or None
    where links are impossible."""
    if folder is None:
        return None
    backup = folder / f"{key}"
    try:
        os.link(target, backup)
    except OSError:
        return None
    return backup


class _ProtectedInodes:
    """The ``(device, inode)`` of the protected files that exist, for the hard-link check of
    :func:`_is_protected`: stated at the first question and kept, so that a commit stats them
    once, not once per target that exists (and not at all when no target exists)."""

    def __init__(self, protected: set[Path]):
        self.protected = protected
        self.known: set[tuple[int, int]] | None = None  # None: not stated yet

    def __contains__(self, key: tuple[int, int]) -> bool:
        if self.known is None:
            self.known = set()
            for path in self.protected:
                try:
                    st = path.stat()
                except OSError:  # a sidecar that does not exist: no inode
                    continue
                self.known.add((st.st_dev, st.st_ino))
        return key in self.known


def _is_protected(target: Path, protected: set[Path],
                  inodes: _ProtectedInodes | None = None) -> bool:
    """Whether ``target`` is one of the ``protected`` paths, by path or by inode (a hard link).
    ``inodes``: the protected files' inodes, kept over a commit's calls (made here without)."""
    if not protected:
        return False
    if target.resolve() in protected:
        return True
    try:
        st = target.stat()
    except OSError:  # no such file: no inode to share
        return False
    if inodes is None:
        inodes = _ProtectedInodes(protected)
    return (st.st_dev, st.st_ino) in inodes


def _check_target(name: str, target: Path, protected: set[Path],
                  inodes: _ProtectedInodes | None = None) -> None:
    """Refuse a commit writing or removing ``target`` when it is an input or a folder
    (``inodes``: see :func:`_is_protected`)."""
    if _is_protected(target, protected, inodes):
        raise ParameterError(name, f"'{target}' is an input (or an input's sidecar); an input "
                             "is never overwritten: choose another output path")
    if target.is_dir() and not target.is_symlink():
        raise ParameterError(name, f"'{target}' is a folder; it cannot be replaced by a file")


def _check_free(name: str, path: Path, main: Path, overwrite: bool) -> None:
    """Refuse replacing or removing the existing ``path`` (``main``, or a file GDAL reads with
    ``main``) without ``overwrite``, unless it is a leftover of ``main``, which does not exist
    (its .aux.xml, -wal, .qix: no one else's)."""
    if overwrite or (path in dataset_files(main, own_only=True) and not os.path.lexists(main)):
        return
    if path == main:
        raise OutputExistsError(name, f"'{path}' exists (or appeared during the run: another "
                                "run wrote it?); pass --overwrite to replace it")
    raise OutputExistsError(name, f"'{path}' exists and GDAL would read it with '{main}'; pass "
                            "--overwrite to replace it")


def _move_no_replace(source: Path, target: Path) -> None:
    """Move ``source`` to ``target``; ``FileExistsError`` if ``target`` exists (atomic check).

    A hard link then unlink of the source: ``link`` never replaces. Folders and filesystems
    without hard links fall back to a checked rename.
    """
    if source.is_dir():
        if os.path.lexists(target):
            raise FileExistsError(errno.EEXIST, "exists", str(target))
        os.rename(source, target)
        return
    try:
        os.link(source, target)
    except FileExistsError:
        raise
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV,
                             errno.EMLINK, errno.ENOSYS):
            raise
        if os.path.lexists(target):
            raise FileExistsError(errno.EEXIST, "exists", str(target)) from None
        os.rename(source, target)
        return
    os.unlink(source)


def _remove(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    except OSError:
        pass


@contextmanager
def atomic_path(final: str | Path, name: str = "OUTPUT", overwrite: bool = True):
    """Context manager yielding a staged path for one file written outside the runner."""
    staging = OutputStaging()
    try:
        yield staging.stage(final, name)
        staging.commit(overwrite=overwrite)
    finally:
        staging.rollback()
