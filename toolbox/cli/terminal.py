"""Terminal side of feedback: a progress bar on stderr (only on a terminal) and log output."""

from __future__ import annotations

import json
import logging
import shutil
import sys
import time

from toolbox.feedback import Feedback

# whether the process's stderr is a terminal, set while the CLI filters file descriptor 2 (then
# sys.stderr writes into a pipe and cannot tell)
STDERR_IS_TTY: list[bool | None] = [None]
# the real stderr while the CLI filters file descriptor 2: the bar and the toolbox's messages are
# written there directly, in order with what goes to stdout (the filter's pipe would deliver them
# late, over the JSON printed at the end)
DIRECT_STDERR: list = [None]


def err_stream():
    """Where the toolbox's own terminal output goes: the real stderr."""
    return DIRECT_STDERR[0] if DIRECT_STDERR[0] is not None else sys.stderr


class TerminalFeedback(Feedback):
    """Draws ``label [#####-----]  45% message`` on stderr when it is a terminal and not quiet."""

    def __init__(self, label: str = "", quiet: bool = False, stream=None):
        super().__init__()
        self._stream = stream
        self.label = label
        tty = STDERR_IS_TTY[0] if STDERR_IS_TTY[0] is not None and stream is None \
            else self.stream.isatty()
        self.show_bar = not quiet and tty
        self._last_draw = 0.0
        self._drawn = 0  # characters on the bar's line

    @property
    def stream(self):
        return self._stream if self._stream is not None else err_stream()

    def set_progress(self, percent: float, message: str = "") -> None:
        super().set_progress(percent, message)
        if not self.show_bar:
            return
        now = time.monotonic()
        if self.progress < 100 and now - self._last_draw < 0.1:
            return
        self._last_draw = now
        filled = int(self.progress / 100 * 30)
        bar = "#" * filled + "-" * (30 - filled)
        line = f"{self.label} [{bar}] {self.progress:5.1f}% {message[:40]}".rstrip()
        # one terminal line: a wrapped bar cannot be cleared by a carriage return
        line = line[:max(10, shutil.get_terminal_size((100, 24)).columns - 1)]
        self.stream.write("\r" + line.ljust(self._drawn))
        self.stream.flush()
        self._drawn = max(self._drawn, len(line))

    def clear_line(self) -> None:
        if self._drawn:
            self.stream.write("\r" + " " * self._drawn + "\r")
            self.stream.flush()
            self._drawn = 0

    def finish(self) -> None:
        self.clear_line()


class BarAwareHandler(logging.StreamHandler):
    """Logging handler that clears the progress bar before printing a line."""

    def __init__(self, feedback_ref: list[TerminalFeedback | None]):
        super().__init__(sys.stderr)
        self.feedback_ref = feedback_ref
        self.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))

    def emit(self, record: logging.LogRecord) -> None:
        feedback = self.feedback_ref[0]
        if feedback is not None:
            feedback.clear_line()
        self.stream = err_stream()
        super().emit(record)


ACTIVE: list[TerminalFeedback | None] = [None]


def setup_logging(verbose: int, quiet: bool) -> None:
    level = logging.WARNING if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[
        min(verbose, 2)]
    logger = logging.getLogger("toolbox")
    logger.handlers[:] = [BarAwareHandler(ACTIVE)]
    logger.setLevel(level)
    logger.propagate = False


# -- --progress json: machine-readable progress for an out-of-process GUI -----------------------------
LEVELS = {logging.DEBUG: "debug", logging.INFO: "info", logging.WARNING: "warning"}


def json_line(stream, obj: dict) -> None:
    """Write one JSON object on one line and flush (a reader sees it at once)."""
    stream.write(json.dumps(obj, separators=(", ", ": ")) + "\n")
    stream.flush()


class JsonFeedback(Feedback):
    """``{"type": "progress", "percent": 42.0}`` lines on stderr: at most one every 0.05 s and one
    per 0.1 %, always 0 and 100; messages come through :class:`JsonLogHandler`."""

    def __init__(self, stream=None):
        super().__init__()
        self.stream = stream or sys.stderr
        self._last_draw = 0.0
        self._last_percent: float | None = None

    def set_progress(self, percent: float, message: str = "") -> None:
        super().set_progress(percent, message)
        shown = round(self.progress, 1)
        now = time.monotonic()
        if shown == self._last_percent or (now - self._last_draw < 0.05
                                           and shown not in (0.0, 100.0)):
            return
        self._last_draw, self._last_percent = now, shown
        json_line(self.stream, {"type": "progress", "percent": shown}
                  | ({"text": message} if message else {}))

    def result(self, outputs: dict) -> None:
        json_line(self.stream, {"type": "result", "outputs": outputs})

    def error(self, text: str) -> None:
        json_line(self.stream, {"type": "message", "level": "error", "text": text})

    def clear_line(self) -> None:
        pass

    def finish(self) -> None:
        pass


class JsonLogHandler(logging.Handler):
    """Every toolbox log record as ``{"type": "message", "level": ..., "text": ...}`` on stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        level = LEVELS.get(record.levelno, "error" if record.levelno > logging.WARNING else "debug")
        json_line(sys.stderr, {"type": "message", "level": level, "text": record.getMessage()})


def setup_json_logging(verbose: int) -> None:
    """Route the toolbox logger to :class:`JsonLogHandler` (info and up; debug with -vv)."""
    logger = logging.getLogger("toolbox")
    logger.handlers[:] = [JsonLogHandler()]
    logger.setLevel(logging.DEBUG if verbose >= 2 else logging.INFO)
    logger.propagate = False
