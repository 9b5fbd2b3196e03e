"""The executor: run independent tile tasks on local threads or on a Dask distributed cluster.

Raster algorithms that work window by window (DEM gridding, orthophotos...) build one small,
picklable task per output window and hand them to :func:`map_tiles` with a module-level
function. Results come back **in task order**, so the caller writes windows in a fixed order and
the output file is the same byte for byte whichever executor computed the tiles. At most
``prefetch`` tasks are in flight, so memory stays bounded however many tiles there are.

Executors
---------
- local threads (default): a :class:`concurrent.futures.ThreadPoolExecutor`; kernels should
  release the GIL (numpy, scipy, numba ``nogil=True``) to use every core;
- a Dask distributed scheduler, when an address is given (``tcp://host:8786``) or set in the
  standard Dask configuration (environment variable ``DASK_SCHEDULER_ADDRESS``). The toolbox must
  be installed on the workers (they import the task function by name). The warnings a task
  gives on its worker (logged, or Python's ``warnings.warn``: numpy's RuntimeWarnings) come
  back with its result, or its error, and are given again on the client in task order, each
  once per map, as a local run gives them. A task cancelled (the run canceled, or stopped by
  an earlier task's error) is never collected: its warnings are lost.

Example
-------
>>> from toolbox.executor import map_tiles
>>> list(map_tiles(abs, [-1, -2, 3], workers=2))
[1, 2, 3]
"""

from __future__ import annotations

import os
import threading
import types
import uuid
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypeVar

from toolbox.errors import CanceledError, ParameterError, ServiceError
from toolbox.feedback import Feedback, current_runs, logged_warnings, working_for

T = TypeVar("T")
R = TypeVar("R")

SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"


@dataclass(frozen=True)
class Executor:
    """Where tiles run: ``kind`` is ``"local"`` (threads) or ``"dask"`` (scheduler ``address``)."""

    kind: str
    workers: int
    address: str | None = None
    source: str = "SCHEDULER"  # what named the address: the parameter or DASK_SCHEDULER_ADDRESS

    def describe(self) -> str:
        if self.kind == "dask":
            return f"dask scheduler {self.address}"
        return f"local threads ({self.workers})"


def default_workers() -> int:
    """Number of local threads: the CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def local_executor(workers: int | None = None) -> Executor:
    """Local threads, ``workers`` or one per CPU of the process that calls it, whatever
    ``DASK_SCHEDULER_ADDRESS`` says: the windows of one task that the scheduler already placed
    (a photo of ortho:batch, on the client's threads or on a Dask worker)."""
    return Executor("local", default_workers() if workers is None else workers)


def scheduler_address(value: str | None = None) -> str | None:
    """The Dask scheduler to use: ``value`` when given, else Dask's configured
    ``scheduler-address`` (environment variable ``DASK_SCHEDULER_ADDRESS``), else ``None``
    (local threads). ``"local"`` forces local threads even when the variable is set."""
    if value is not None and str(value).strip():
        text = str(value).strip()
        return None if text.lower() in ("local", "threads", "none") else text
    env = os.environ.get(SCHEDULER_ENV, "").strip()
    if env:
        return env
    if not _dask_may_be_configured():  # no need to import dask (about 0.1 s) to read nothing
        return None
    try:
        import dask

        configured = dask.config.get("scheduler-address", default=None)
    except ImportError:  # the [dask] extra is not installed: local threads
        configured = None
    return str(configured) if configured else None


def _dask_may_be_configured() -> bool:
    """False when Dask's configuration cannot hold a ``scheduler-address``: dask is not imported
    yet (nothing was set in this process), no ``DASK_*`` environment variable exists and none of
    the places ``dask.config`` reads YAML from exists (``/etc/dask``, ``<prefix>/etc/dask``,
    ``~/.config/dask``; ``DASK_ROOT_CONFIG`` and ``DASK_CONFIG`` are ``DASK_*`` variables)."""
    import sys

    if "dask" in sys.modules or any(name.startswith("DASK_") for name in os.environ):
        return True
    import site

    prefixes = dict.fromkeys([sys.prefix, *getattr(site, "PREFIXES", [])])
    paths = ["/etc/dask", os.path.join(os.path.expanduser("~"), ".config", "dask"),
             *(os.path.join(prefix, "etc", "dask") for prefix in prefixes)]
    return any(os.path.exists(path) for path in paths)


def resolve_executor(scheduler: str | None = None, workers: int | None = None,
                     name: str = "SCHEDULER") -> Executor:
    """Decide the executor from the user's parameters (see :func:`scheduler_address`).

    Raises :class:`ParameterError` naming ``name`` when the address is not a Dask address.
    """
    address = scheduler_address(scheduler)
    if address is None:
        return Executor("local", workers or default_workers())
    given = scheduler is not None and str(scheduler).strip()
    source = name if given else (SCHEDULER_ENV if os.environ.get(SCHEDULER_ENV, "").strip()
                                 else "Dask's scheduler-address setting")
    if not is_scheduler_address(address):
        raise ParameterError(source, f"must be a Dask scheduler address such as "
                             f"tcp://host:8786, 'local' or empty, got {address!r}")
    return Executor("dask", workers or 0, address, source)


DASK_PROTOCOLS = ("tcp", "tls", "ucx", "ws", "wss")


def is_scheduler_address(address: str) -> bool:
    """``[protocol://]host:port`` with a Dask protocol, a host name or IP (IPv6 in brackets)
    and a port number 1-65535 (Dask's ``inproc://`` addresses are in-process only)."""
    protocol, sep, rest = address.partition("://")
    if not sep:
        protocol, rest = "tcp", address
    if protocol not in DASK_PROTOCOLS:
        return protocol == "inproc" and bool(rest)
    host, colon, port = rest.rpartition(":")
    if not (colon and port.isdigit() and 0 < int(port) < 65536 and host):
        return False
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    return all(ch.isascii() and (ch.isalnum() or ch in ".-_:") for ch in host)


def map_tiles(func: Callable[[T], R], tasks: Iterable[T], *, executor: Executor | None = None,
              scheduler: str | None = None, workers: int | None = None,
              prefetch: int | None = None, feedback: Any = None,
              total: int | None = None, start: float = 0.0, end: float = 100.0) -> Iterator[R]:
    """Yield ``func(task)`` for every task, in task order.

    Parameters
    ----------
    func : callable
        A module-level function (picklable by reference); pure: same task, same result.
    tasks : iterable
        Picklable task objects; consumed lazily, at most ``prefetch`` ahead of the results.
    executor : Executor, optional
        From :func:`resolve_executor`; else built from ``scheduler`` and ``workers``.
    prefetch : int, optional
        Tasks in flight (default: twice the workers, at least 4).
    feedback : toolbox.feedback.Feedback, optional
        Progress goes from ``start`` to ``end`` percent over ``total`` tasks; cancellation is
        checked before every submission and result (pending tasks are then cancelled).
    """
    executor = executor or resolve_executor(scheduler, workers)
    if executor.kind == "dask":
        yield from _map_dask(func, tasks, executor, prefetch, feedback, total, start, end)
    else:
        yield from _map_local(func, tasks, executor.workers, prefetch, feedback, total, start, end)


def _progress(feedback: Any, done: int, total: int | None, start: float, end: float) -> None:
    if feedback is not None and total:
        feedback.set_progress(start + (end - start) * done / total)


def _check(feedback: Any) -> None:
    if feedback is not None:
        feedback.check_canceled()


def _in_order(submit, tasks, limit: int, feedback, total, start, end,
              outcome: Callable[[Any], Any] = lambda future: future.result()) -> Iterator:
    """Submit tasks with ``submit(task) -> future`` keeping at most ``limit`` in flight; yield
    the results (``outcome(future)``) in task order. Pending futures are cancelled if the
    consumer stops early."""
    pending: deque = deque()
    done = 0
    try:
        iterator = iter(tasks)
        exhausted = False
        while True:
            while not exhausted and len(pending) < limit:
                _check(feedback)
                try:
                    task = next(iterator)
                except StopIteration:
                    exhausted = True
                    break
                pending.append(submit(task))
            if not pending:
                break
            future = pending.popleft()
            result = outcome(future)
            if hasattr(future, "release"):  # dask: drop the result from the cluster now
                future.release()
            done += 1
            _check(feedback)
            _progress(feedback, done, total, start, end)
            yield result
    finally:
        for future in pending:
            future.cancel()


def _map_local(func, tasks, workers, prefetch, feedback, total, start, end) -> Iterator:
    if workers <= 1:
        for done, task in enumerate(tasks, start=1):
            _check(feedback)
            result = func(task)
            _progress(feedback, done, total, start, end)
            yield result
        return
    with thread_pool(workers) as submit, one_blas_thread():
        yield from _in_order(lambda task: submit(func, task), tasks,
                             prefetch or max(4, 2 * workers), feedback, total, start, end)


_IDLE_POOLS: dict[int, list[Any]] = {}  # workers -> thread pools no call is using
_POOLS_LOCK = threading.Lock()
_TASK = threading.local()  # .stop: the Event of the thread_pool call running this thread's task


def abandoned() -> bool:
    """True in a task of a :func:`thread_pool` whose caller has left it (Ctrl-C, SIGTERM, an
    error): its result is no longer wanted. A compiled kernel that can run for many seconds is
    called in pieces that check this between them (and raise :class:`CanceledError`), so the
    caller's exit, which waits for its running tasks, waits for one piece, not a whole tile."""
    stop = getattr(_TASK, "stop", None)
    return stop is not None and stop.is_set()


def check_abandoned() -> None:
    """Raise :class:`toolbox.errors.CanceledError` when :func:`abandoned`."""
    if abandoned():
        raise CanceledError("run canceled; this task's result is no longer wanted")


def _task(stop: threading.Event, runs: tuple[object, ...], func: Callable[..., Any],
          *args: Any) -> Any:
    _TASK.stop = stop
    try:
        with working_for(runs):  # the warnings it logs are the submitting run's
            return func(*args)
    finally:
        _TASK.stop = None


@contextmanager
def thread_pool(workers: int) -> Iterator[Callable[..., Any]]:
    """``submit(func, *args) -> Future`` on a pool of ``workers`` threads that later calls reuse:
    a thread's first GDAL open pays for its PROJ context and GDAL's thread state (about 10 ms
    with the GIL held), which new threads for every photo and block paid again. A nested call
    (a photo's windows inside a block of photos) takes another pool, so no pool waits on its
    own threads. On exit every task submitted has finished (as ``shutdown(wait=True)``): none
    is left running after its caller returns."""
    from concurrent.futures import ThreadPoolExecutor, wait

    with _POOLS_LOCK:
        idle = _IDLE_POOLS.setdefault(workers, [])
        pool = idle.pop() if idle else None
    if pool is None:
        pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="tile")
    running: set = set()
    lock = threading.Lock()
    stop = threading.Event()  # set when the caller leaves: its running tasks may stop early

    def finished(future: Any) -> None:
        with lock:
            running.discard(future)

    def submit(func: Callable[..., Any], *args: Any) -> Any:
        future = pool.submit(_task, stop, current_runs(), func, *args)
        with lock:
            running.add(future)
        future.add_done_callback(finished)
        return future

    try:
        yield submit
    finally:
        stop.set()
        with lock:
            left = list(running)
        for future in left:
            future.cancel()
        wait(left)
        with _POOLS_LOCK:
            idle.append(pool)


#: cells a thread of :func:`in_row_bands` gets at least (a band of fewer is not worth a thread)
ROW_BAND_MIN_CELLS = 250_000


def in_row_bands(task: Callable[[int, int], Any], rows: int, cells_per_row: int = 1,
                 workers: int | None = None) -> None:
    """Call ``task(start, stop)`` on consecutive bands of ``range(rows)``, one band per local
    thread (:func:`thread_pool`), so a compiled ``nogil`` kernel that fills its rows of shared
    output arrays uses every core; a single call ``task(0, rows)`` when the whole is under
    ``2 *`` :data:`ROW_BAND_MIN_CELLS` cells or one thread is available. Exceptions
    propagate."""
    workers = default_workers() if workers is None else workers
    cells = rows * max(cells_per_row, 1)
    parts = max(1, min(workers, cells // max(ROW_BAND_MIN_CELLS, 1), rows))
    if parts == 1:
        task(0, rows)
        return
    edges = [rows * k // parts for k in range(parts + 1)]
    with thread_pool(parts) as submit:
        futures = [submit(task, a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]
        for future in futures:
            future.result()


_BLAS_CONTROLLER: list[Any] = [None, -1]  # threadpoolctl's controller, len(sys.modules) then


def one_blas_thread():
    """Context limiting BLAS/OpenMP libraries to one thread while our own threads run tiles
    (each tile's small solves would otherwise spin a BLAS thread pool per core and oversubscribe
    the machine: 10-100x slower on a busy 2-core host). The previous limits are restored on
    exit; no environment variable is changed. The libraries are looked up again only after new
    imports (a lookup walks every loaded shared library: 1.4 ms, with the GIL held)."""
    import sys
    from contextlib import nullcontext

    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - a dependency
        return nullcontext()
    with _POOLS_LOCK:
        if _BLAS_CONTROLLER[0] is None or _BLAS_CONTROLLER[1] != len(sys.modules):
            _BLAS_CONTROLLER[:] = [ThreadpoolController(), len(sys.modules)]
        controller = _BLAS_CONTROLLER[0]
    return controller.limit(limits=1, user_api="blas")


def _map_dask(func, tasks, executor, prefetch, feedback, total, start, end) -> Iterator:
    from toolbox.extras import require

    Client = require("distributed", "dask", "SCHEDULER (a Dask cluster)").Client
    where = f"the Dask scheduler {executor.address!r} ({executor.source})"
    with _quiet_dask_client():
        try:
            client = Client(executor.address, set_as_default=False)  # Dask's connect timeout
        except (OSError, TimeoutError) as exc:
            raise ServiceError(f"cannot connect to {where}: {_first_line(exc)}; nothing was "
                               "written (start the cluster, or use SCHEDULER=local)") from None
        except (ValueError, TypeError) as exc:  # Dask cannot parse it (':', 'tcp://:x'...)
            raise ParameterError(executor.source, f"must be a Dask scheduler address such as "
                                 f"tcp://host:8786, got {executor.address!r} "
                                 f"({_first_line(exc)})") from None
        try:
            cores = sum(client.nthreads().values()) or 1
            from toolbox.io.source_date import client_date

            folder, name, date = os.getcwd(), _task_name(func), client_date()
            # a partial or a callable object (a kernel holding a DEM, a map of windows) is
            # sent to the cluster once and each worker fetches it once, not once per task
            target = func if isinstance(func, types.FunctionType) else \
                client.scatter([func], hash=False)[0]

            def submit(task):
                return client.submit(_keeping_warnings, folder, target, task, date, pure=False,
                                     key=f"{name}-{uuid.uuid4().hex}")

            shown: set[str] = set()

            def outcome(future):
                try:
                    result, warnings = future.result()
                except Exception as exc:
                    _show(getattr(exc, "toolbox_warnings", ()), shown)
                    raise
                _show(warnings, shown)
                return result

            yield from _in_order(submit, tasks, prefetch or max(4, 2 * cores), feedback, total,
                                 start, end, outcome)
        except Exception as exc:
            if not _connection_lost(client, exc):
                raise  # the task's own error, re-raised by Dask with its type
            raise ServiceError(f"lost the connection to {where} while tiles were computed "
                               f"({type(exc).__name__}); nothing was written: rerun when the "
                               "cluster is back, or with SCHEDULER=local") from None
        finally:
            client.close()


def _task_name(func: Any) -> str:
    """The name Dask's dashboard shows for ``func``'s tasks (a partial's function's)."""
    return getattr(func, "__name__", None) or getattr(getattr(func, "func", None), "__name__",
                                                      None) or type(func).__name__


#: the working folder the running tasks of a Dask worker process share (the folder of their
#: client: :func:`_in_client_folder`), how many run there, and the tasks waiting per folder
_FOLDER: dict[str, Any] = {"path": None, "running": 0, "waiting": {}}
_FOLDER_TURN = threading.Condition()


def _in_client_folder(folder: str, func: Callable, task: Any, date: str | None = None) -> Any:
    """``func(task)`` on a Dask worker, in the client's working ``folder`` and with the client's
    ``SOURCE_DATE_EPOCH`` (``date``: :func:`toolbox.io.source_date.on_worker`): the user's relative
    paths (``--INPUT dem.tif``, a staged output folder beside it) name the files they meant, not
    files in the worker's own folder. A worker that does not see the folder (another machine
    without the same mount) stays where it is: relative paths then fail there as before, and
    absolute ones work.

    The working folder is the process's, not the thread's: tasks of two runs from two folders
    on one worker (two users of one cluster) each read 'dem.tif' of the other's folder when
    one changed it under the other (a wrong result, exit 0). The tasks of one folder run
    together; a task of another folder waits until they are done (and, while it waits, new
    tasks of the running folder wait too: no run waits forever)."""
    with _FOLDER_TURN:
        waiting = _FOLDER["waiting"]
        waiting[folder] = waiting.get(folder, 0) + 1
        while _FOLDER["running"] and (_FOLDER["path"] != folder or any(
                n for other, n in waiting.items() if other != folder)):
            _FOLDER_TURN.wait()
        waiting[folder] -= 1
        if not waiting[folder]:
            del waiting[folder]
        _FOLDER["path"] = folder
        _FOLDER["running"] += 1
        try:
            if os.getcwd() != folder and os.path.isdir(folder):
                os.chdir(folder)
        except OSError:  # the worker's own folder was removed, or the client's is not readable
            pass
    try:
        from toolbox.io.source_date import on_worker

        with on_worker(date):
            return func(task)
    finally:
        with _FOLDER_TURN:
            _FOLDER["running"] -= 1
            _FOLDER_TURN.notify_all()


def _keeping_warnings(folder: str, func: Callable, task: Any, date: str | None = None):
    """:func:`_in_client_folder` on a Dask worker, with the warnings the task gave there, in
    the order it gave them: those it logged (on the ``toolbox`` logger, and GDAL's through
    ``rasterio``'s: :func:`logged_warnings`) as their text, and the Python warnings it (or a
    local thread working for it) showed (``warnings.warn``: numpy's RuntimeWarnings, a
    library's) as ``(category, text, filename, lineno)`` (:func:`_recording_show`): the pair
    ``(result, warnings)``, or the task's error carrying them (``toolbox_warnings``). The worker
    is another process: the run's own handlers, and the client's ``warnings.showwarning``,
    never see them."""
    kept = Feedback()
    _record_python_warnings()
    try:
        with logged_warnings(kept), working_for((*current_runs(), _TaskWarnings(kept))):
            return _in_client_folder(folder, func, task, date), _given(kept)
    except Exception as exc:
        try:
            exc.toolbox_warnings = _given(kept)
        except AttributeError:  # an error without a __dict__: its warnings are lost
            pass
        raise


#: the level of a recorded Python warning in a task's :class:`Feedback` messages
_PYTHON_WARNING = "python warning"
_SHOW_BEFORE: list[Any] = [None]  # the process's warnings.showwarning that _recording_show wraps
_SHOW_LOCK = threading.Lock()


class _TaskWarnings:
    """In :func:`current_runs` of a thread running a Dask task (and of the local threads it
    starts: :func:`thread_pool` hands them on): the Python warnings it shows go to
    ``feedback``'s messages (:func:`_recording_show`), not to the worker's stderr."""

    def __init__(self, feedback: Feedback):
        self.feedback = feedback


def _record_python_warnings() -> None:
    """Have this process's ``warnings.showwarning`` be :func:`_recording_show` (installed once;
    again if a ``warnings.catch_warnings`` block of another thread restored an older one), and
    forget the warnings it has shown (the registries of ``warnings``' "default" action): an
    earlier task or run on this worker showed the same warning from the same line, which a
    local run, a new process, shows again."""
    import warnings

    with _SHOW_LOCK:
        if warnings.showwarning is not _recording_show:
            _SHOW_BEFORE[0] = warnings.showwarning
            warnings.showwarning = _recording_show
    forget = getattr(warnings, "_filters_mutated", None)  # what changing a filter calls
    if forget is not None:
        forget()


def _recording_show(message: Any, category: type, filename: str, lineno: int, file: Any = None,
                    line: str | None = None) -> None:
    """``warnings.showwarning`` of a Dask worker: a warning of a thread working for a task
    (:class:`_TaskWarnings`) is kept in the task's messages; any other is shown as before."""
    recorder = next((r for r in current_runs() if isinstance(r, _TaskWarnings)), None)
    if recorder is None:
        _SHOW_BEFORE[0](message, category, filename, lineno, file, line)
        return
    name = f"{category.__module__}:{category.__qualname__}"
    recorder.feedback.messages.append((_PYTHON_WARNING, (name, str(message), str(filename),
                                                         int(lineno))))


def _given(kept: Feedback) -> list[Any]:
    """The warnings of a task's ``kept`` messages, in order: a logged one's text, a Python
    one's ``(category, text, filename, lineno)``."""
    return [item for level, item in kept.messages if level in ("warning", _PYTHON_WARNING)]


def _category(name: str) -> type[Warning]:
    """The warning class ``module:qualname`` a worker named, UserWarning when the client
    cannot import it."""
    import importlib

    module, _, qualname = name.partition(":")
    try:
        found: Any = importlib.import_module(module)
        for part in qualname.split("."):
            found = getattr(found, part)
    except Exception:  # noqa: BLE001 - a class only the worker has: a plain warning
        return UserWarning
    return found if isinstance(found, type) and issubclass(found, Warning) else UserWarning


def _show(warnings: Iterable[Any], shown: set[Any]) -> None:
    """Give on the client each warning of a Dask task (:func:`_keeping_warnings`) that this
    map has not given yet, in the task's order: a logged one on the ``toolbox`` logger (the
    run, :func:`logged_warnings`, keeps it, the console shows it), a Python one through
    ``warnings.warn_explicit`` with its category, text, file and line, as the task's own
    ``warnings.warn`` does in a local run (the client's filters and ``showwarning`` decide:
    the CLI's makes it a one-line toolbox warning, the run keeps it)."""
    import logging
    import warnings as python_warnings

    for item in warnings:
        key = item if isinstance(item, str) else tuple(item[:2])
        if key in shown:
            continue
        shown.add(key)
        if isinstance(item, str):
            logging.getLogger("toolbox").warning(item)
        else:
            name, text, filename, lineno = item
            python_warnings.warn_explicit(text, _category(name), filename, lineno)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _connection_lost(client: Any, exc: BaseException) -> bool:
    """The client lost its scheduler (decided by the exception's type and the client's state,
    not its message): a future cancelled under us, a closed comm, a timeout, or a client no
    longer running."""
    from concurrent.futures import CancelledError

    from distributed.comm.core import CommClosedError

    if isinstance(exc, (CancelledError, CommClosedError)):
        return True
    if getattr(client, "status", "running") != "running":
        return True
    return isinstance(exc, (OSError, TimeoutError)) and getattr(
        getattr(client, "scheduler_comm", None), "comm", None) is None


def _quiet_dask_client():
    """Silence the client-side loggers of ``distributed`` while the client lives: a lost
    scheduler is reported once, as the toolbox's one-line error, not as their tracebacks."""
    import logging
    from contextlib import contextmanager

    names = ("distributed", "distributed.client", "distributed.core", "distributed.comm",
             "distributed.batched", "distributed.utils", "distributed.worker",
             "distributed.worker.state_machine", "distributed.scheduler", "tornado",
             "asyncio")

    @contextmanager
    def quiet():
        loggers = [logging.getLogger(n) for n in names]
        levels = [lg.level for lg in loggers]
        for lg in loggers:
            lg.setLevel(logging.CRITICAL + 1)
        try:
            yield
        finally:
            for lg, level in zip(loggers, levels, strict=True):
                lg.setLevel(level)

    return quiet()
