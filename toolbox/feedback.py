"""Feedback: progress (0-100), log messages, timings and cancellation for a running algorithm.

Kernels never print: an algorithm reports through the feedback object it is given. The default
:class:`Feedback` is silent apart from the Python ``logging`` module; the CLI subclasses it to draw a
progress bar, and scripts can pass a ``progress_callback``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

from toolbox.errors import CanceledError

log = logging.getLogger("toolbox")


class Feedback:
    """Progress, messages, timings and cancellation for one run.

    Parameters
    ----------
    progress_callback : callable, optional
        Called as ``progress_callback(percent: float, message: str)`` whenever progress changes.
    """

    def __init__(self, progress_callback: Callable[[float, str], None] | None = None):
        self._callback = progress_callback
        self._canceled = threading.Event()
        self._cancel_reason: str | None = None
        self.progress = 0.0
        self.messages: list[tuple[str, str]] = []  # (level, text)
        self.timings: dict[str, float] = {}

    # -- progress -------------------------------------------------------------------------------
    def set_progress(self, percent: float, message: str = "") -> None:
        """Report overall progress in percent (clamped to 0-100)."""
        self.progress = min(100.0, max(0.0, float(percent)))
        if self._callback is not None:
            self._callback(self.progress, message)

    def step(self, start: float, end: float) -> SubFeedback:
        """A child feedback whose 0-100 maps onto ``start``-``end`` of this one (multi-step work)."""
        return SubFeedback(self, start, end)

    def iterate(self, items, total: int | None = None, start: float = 0.0, end: float = 100.0,
                message: str = "") -> Iterator:
        """Yield ``items``, advancing progress from ``start`` to ``end`` and honouring cancellation."""
        total = len(items) if total is None else total
        for i, item in enumerate(items):
            self.check_canceled()
            yield item
            self.set_progress(start + (end - start) * (i + 1) / max(total, 1), message)

    # -- messages -------------------------------------------------------------------------------
    def push_info(self, text: str) -> None:
        self.messages.append(("info", text))
        log.info(text)

    def push_warning(self, text: str) -> None:
        self.messages.append(("warning", text))
        log.warning(text)

    def push_debug(self, text: str) -> None:
        log.debug(text)

    @property
    def warnings(self) -> list[str]:
        return [text for level, text in self.messages if level == "warning"]

    # -- timings --------------------------------------------------------------------------------
    @contextmanager
    def timed(self, name: str):
        """Measure the wall time of a block; it appears under ``timings`` in the run report."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - t0

    # -- cancellation ---------------------------------------------------------------------------
    def cancel(self, reason: str | None = None) -> None:
        """Ask the running algorithm to stop (thread-safe); ``reason`` (e.g. "terminated by
        SIGTERM") replaces "canceled by the user" in the error."""
        if reason is not None and self._cancel_reason is None:
            self._cancel_reason = reason
        self._canceled.set()

    def is_canceled(self) -> bool:
        return self._canceled.is_set()

    def cancel_reason(self) -> str | None:
        return self._cancel_reason

    def check_canceled(self) -> None:
        """Raise :class:`CanceledError` if cancellation was requested."""
        if self.is_canceled():
            raise CanceledError(f"run {self.cancel_reason() or 'canceled by the user'}; no "
                                "output was written")


class SubFeedback(Feedback):
    """A view on a parent feedback covering the ``start``-``end`` slice of its progress.

    It keeps its own messages and timings (for a per-run report) and forwards them to the parent;
    cancellation is shared with the parent.
    """

    def __init__(self, parent: Feedback, start: float, end: float):
        super().__init__()
        self._parent = parent
        self._start, self._end = float(start), float(end)

    def set_progress(self, percent: float, message: str = "") -> None:
        self.progress = min(100.0, max(0.0, float(percent)))
        self._parent.set_progress(self._start + (self._end - self._start) * self.progress / 100.0,
                                  message)

    def push_info(self, text: str) -> None:
        self.messages.append(("info", text))
        self._parent.push_info(text)

    def push_warning(self, text: str) -> None:
        self.messages.append(("warning", text))
        self._parent.push_warning(text)

    def push_debug(self, text: str) -> None:
        self._parent.push_debug(text)

    # duplicate-ok: the step's timer times its own share and its parent's, like Feedback.timed
    @contextmanager
    def timed(self, name: str):
        t0 = time.perf_counter()
        try:
            with self._parent.timed(name):
                yield
        finally:
            self.timings[name] = self.timings.get(name, 0.0) + time.perf_counter() - t0

    def cancel(self, reason: str | None = None) -> None:
        self._parent.cancel(reason)

    def is_canceled(self) -> bool:
        return self._parent.is_canceled()

    def cancel_reason(self) -> str | None:
        return self._parent.cancel_reason()


class CollectingFeedback(Feedback):
    """Messages kept for the caller to report, not logged: for work run on a thread or a
    worker whose caller pushes the messages to the user itself (once)."""

    def push_info(self, text: str) -> None:
        self.messages.append(("info", text))

    def push_warning(self, text: str) -> None:
        self.messages.append(("warning", text))


#: the runs (their :func:`logged_warnings` handlers) the current thread works for: the run's own
#: thread, and the worker threads of :func:`toolbox.executor.thread_pool` for the tasks the run
#: submitted (:func:`working_for`); another run's threads, or a user's, are not the run's
_RUNS: ContextVar[tuple[object, ...]] = ContextVar("toolbox_runs", default=())
_KEEP_LOCK = threading.Lock()  # check-and-append of a warning's text: threads log at once


def current_runs() -> tuple[object, ...]:
    """The runs the calling thread works for: hand them to :func:`working_for` in a thread
    that works for it (what :func:`toolbox.executor.thread_pool` does for its tasks)."""
    return _RUNS.get()


@contextmanager
def working_for(runs: tuple[object, ...]):
    """While the block runs, the calling thread works for ``runs`` (:func:`current_runs` of the
    thread that handed it the work): the warnings it logs are theirs."""
    token = _RUNS.set(runs)
    try:
        yield
    finally:
        _RUNS.reset(token)


def _keep(feedback: Feedback | None, text: str) -> bool:
    """Add the warning ``text`` to ``feedback``'s messages and its parents' where it is not yet
    (the run's step feedback, then the caller's above it); True when ``feedback`` lacked it."""
    with _KEEP_LOCK:
        new = feedback is not None and text not in feedback.warnings
        while feedback is not None:
            if text not in feedback.warnings:
                feedback.messages.append(("warning", text))
            feedback = getattr(feedback, "_parent", None)
    return new


class _LoggedWarnings(logging.Handler):
    """Keeps the warnings logged on the ``toolbox`` logger by the run's threads (its own and the
    workers of its tasks: a library's Python warning the CLI logs, a deprecated parameter name,
    a reader's note such as a photo's EXIF orientation) that did not come through
    ``feedback.push_warning``, in ``feedback``'s messages, each text once: the run report lists
    every warning the console showed."""

    def __init__(self, feedback: Feedback):
        super().__init__(logging.WARNING)
        self.feedback = feedback

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno > logging.WARNING or self not in _RUNS.get():
            return
        try:
            text = record.getMessage()
        except Exception:  # noqa: BLE001 - a bad format string: not ours to fail on
            return
        _keep(self.feedback, text)


class _GdalWarnings(_LoggedWarnings):
    """The warnings GDAL reports through rasterio's logger (``rasterio._env``: an ignored
    creation option, a clamped nodata value, a libtiff note) by the run's threads: pushed to
    ``feedback`` (the console shows them, the run report lists them), each text once. The
    runner's own handler on that logger (:func:`toolbox.runner.failures.collect_gdal_errors`)
    keeps only errors, so they were shown nowhere."""

    def __init__(self, feedback: Feedback, run: object):
        super().__init__(feedback)
        self.run = run

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno != logging.WARNING or self.run not in _RUNS.get():
            return
        try:
            text = f"GDAL: {record.getMessage()}"
        except Exception:  # noqa: BLE001 - a bad format string: not ours to fail on
            return
        if _keep(self.feedback, text):
            log.warning(text)  # the console's (outside the lock: handlers take their own)


@contextmanager
def logged_warnings(feedback: Feedback):
    """While the block runs, warnings logged outside ``feedback`` (on the ``toolbox`` logger,
    and GDAL's through ``rasterio``'s) by the calling thread, or by a thread working for it
    (:func:`working_for`), are kept in its messages."""
    handler = _LoggedWarnings(feedback)
    gdal = _GdalWarnings(feedback, handler)
    rasterio_log = logging.getLogger("rasterio")
    token = _RUNS.set((*_RUNS.get(), handler))
    log.addHandler(handler)
    rasterio_log.addHandler(gdal)
    try:
        yield
    finally:
        log.removeHandler(handler)
        rasterio_log.removeHandler(gdal)
        _RUNS.reset(token)
