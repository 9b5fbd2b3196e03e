"""The click application of the ``toolbox`` command: list, help, run, batch, demo, warmup.

Parameters of ``run`` are the algorithm's UPPERCASE names: ``--CELL_SIZE 2`` or ``--CELL_SIZE=2``;
repeat an option for a multiple-layer parameter; a boolean given alone (``--OVERVIEWS``) is true.
User mistakes print one line on stderr and exit with code 2; a canceled run (Ctrl-C) exits 130.
"""

from __future__ import annotations

import io
import json
import re
import signal
import sys
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from toolbox.cli.helptext import (
    format_help,
    format_help_all,
    format_help_all_json,
    format_help_json,
    format_list,
    format_list_json,
)
from toolbox.errors import ParameterError, ToolboxError
from toolbox.version import __version__

EXIT_USER_ERROR = 2
EXIT_INTERNAL_ERROR = 3
EXIT_CANCELED = 130


def _terminal():
    """``toolbox.cli.terminal`` (progress bar, logging set-up), imported on first use:
    ``toolbox --version`` needs neither it nor ``logging``."""
    from toolbox.cli import terminal

    return terminal


def __getattr__(name: str):
    """The terminal module's names (``setup_logging``, ``ACTIVE``...), importable from here as
    before it became lazy (PEP 562)."""
    if name in ("ACTIVE", "DIRECT_STDERR", "STDERR_IS_TTY", "TerminalFeedback", "setup_logging"):
        return getattr(_terminal(), name)
    raise AttributeError(f"module 'toolbox.cli.app' has no attribute {name!r}")


def _one_line(text: str) -> str:
    """A message on one line (YAML and GDAL messages span several)."""
    return "; ".join(line.strip() for line in str(text).splitlines() if line.strip())


def _report_error(exc: BaseException, where: str) -> int:
    """Print ``exc`` as one line on stderr; return the exit code (2 user error, 3 bug or a lost
    service: a :class:`~toolbox.errors.ToolboxError` may carry its own ``exit_code``)."""
    if _terminal().ACTIVE[0] is not None:
        _terminal().ACTIVE[0].clear_line()
    if isinstance(exc, ToolboxError):
        click.echo(f"toolbox: error: {_one_line(exc)}", err=True)
        return getattr(exc, "exit_code", EXIT_USER_ERROR)
    detail = _one_line(f"{type(exc).__name__}: {exc}")
    step = getattr(exc, "step", None)  # a pipeline's step (toolbox.batch.step_label)
    where = f"{where}, {step}" if step else where
    click.echo(f"toolbox: internal error in {where}: {detail}; please report it (rerun with "
               "TOOLBOX_DEBUG=1 for the traceback)", err=True)
    return EXIT_INTERNAL_ERROR


def _handle_errors(func: Callable) -> Callable:
    """Turn toolbox errors into one-line messages and exit codes (no traceback); an interruption
    (Ctrl-C, SIGTERM, SIGHUP) exits 128 + signal number after the runner cleaned up."""
    import functools
    import os

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        where = kwargs.get("algorithm_id") or func.__name__.removesuffix("_cmd")
        committed = len(_committed())
        received: list[int] = []
        try:
            with _signals_as_interrupts(received), _native_stderr_filtered(), \
                    _python_warnings_as_messages():
                result = func(*args, **kwargs)
            if received:  # a library swallowed the interruption; the run ended all the same
                _exit_interrupted(received[0], None, committed)
            return result
        except KeyboardInterrupt as exc:
            _exit_interrupted(getattr(exc, "signum", signal.SIGINT), exc, committed)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except Exception as exc:
            if received:  # a library turned the interruption into its own error (lazrs...)
                _exit_interrupted(received[0], exc, committed)
            if isinstance(exc, BrokenPipeError):  # `toolbox list | head`: the reader left
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, sys.stdout.fileno())  # no second error while flushing at exit
                sys.exit(1)
            if os.environ.get("TOOLBOX_DEBUG") and not isinstance(exc, ToolboxError):
                raise
            sys.exit(_report_error(exc, where))

    return wrapper


def _committed() -> list:
    """The outputs this process moved into place so far (:data:`toolbox.io.staging.COMMITTED`;
    none before the staging module is loaded)."""
    staging = sys.modules.get("toolbox.io.staging")
    return staging.COMMITTED if staging is not None else []


def interrupted_message(signum: int, exc: BaseException | None = None,
                        committed: int = 0) -> str:
    """What an interrupted command says: canceled or terminated, and what stays written (the
    outputs moved into place before the signal: a run it reached after its commit, a batch's
    steps done) or that nothing was written."""
    what = "canceled" if signum == signal.SIGINT else \
        f"terminated by {signal.Signals(signum).name}"
    step = getattr(exc, "step", None)
    if step:
        what += f" during {step}"
    written = [str(p) for p in _committed()[committed:]]
    if not written:
        return f"{what}; no output was written"
    shown = ", ".join(written[:3]) + (f" and {len(written) - 3} more" if len(written) > 3 else "")
    now = "of that step " if step else "else "
    return (f"{what}; written before it and kept: {shown}; nothing {now}was written")


def _exit_interrupted(signum: int, exc: BaseException | None, committed: int) -> None:
    if _terminal().ACTIVE[0] is not None:
        _terminal().ACTIVE[0].clear_line()
    click.echo(f"toolbox: {interrupted_message(signum, exc, committed)}", err=True)
    sys.exit(128 + signum)


class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP, raised like Ctrl-C so that every cleanup runs."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextmanager
def _signals_as_interrupts(received: list[int] | None = None):
    """Handle SIGINT, SIGTERM and SIGHUP (Ctrl-C, timeout, kill, systemd, Docker, Slurm, a
    closed terminal) alike while a command runs: staged outputs are removed, the exit code is
    128 + signal. A library may swallow the exception (pyogrio's reading loop) or turn it into
    its own error (lazrs): so each signal is also appended to ``received`` and cancels the
    running command's feedback, whose next check (the runner's, before any output is moved into
    place) stops the run. One that comes while outputs are moved into place or a staging folder
    is removed waits until that is done (:func:`toolbox.io.staging.hold_signal`)."""
    def interrupt(signum, frame):
        staging = sys.modules.get("toolbox.io.staging")
        if staging is not None and staging.hold_signal(signum):
            return
        if received is not None:
            received.append(signum)
        terminal = sys.modules.get("toolbox.cli.terminal")
        if terminal is not None and terminal.ACTIVE[0] is not None:
            terminal.ACTIVE[0].cancel(f"terminated by {signal.Signals(signum).name}")
        raise Interrupted(signum)

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        try:
            previous[sig] = signal.signal(sig, interrupt)
        except (ValueError, OSError):  # not the main thread
            pass
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


# what GDAL and libtiff print themselves on file descriptor 2 when a write or read fails; the
# toolbox turns the failure into its own one-line error
NATIVE_NOISE = re.compile(rb"^(_tiff\w*Proc|TIFF\w+|ERROR \d+): ")


@contextmanager
def _native_stderr_filtered():
    """Pass everything written on stderr through, except the lines C libraries print directly
    (``_tiffWriteProc: No space left on device.`` once per block): a failure is reported once,
    as the toolbox's one-line error. ``TOOLBOX_DEBUG=1`` keeps them."""
    import os
    import threading

    if os.environ.get("TOOLBOX_DEBUG"):
        yield
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, AttributeError, ValueError):  # no real stderr (embedded, closed)
        yield
        return
    _terminal().STDERR_IS_TTY[0] = os.isatty(saved)
    try:  # only when sys.stderr is file descriptor 2 (not a test runner's buffer)
        if sys.stderr.fileno() == 2:
            _terminal().DIRECT_STDERR[0] = os.fdopen(os.dup(saved), "w", buffering=1,
                                         encoding=sys.stderr.encoding or "utf-8",
                                         errors="replace")
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        _terminal().DIRECT_STDERR[0] = None
    read_end, write_end = os.pipe()
    os.dup2(write_end, 2)
    os.close(write_end)

    def pump() -> None:
        pending = b""
        with os.fdopen(read_end, "rb", buffering=0) as pipe:
            while chunk := pipe.read(65536):
                *pieces, pending = re.split(rb"(?<=[\n\r])", pending + chunk)
                for piece in pieces:
                    if not NATIVE_NOISE.match(piece):
                        os.write(saved, piece)
        if pending and not NATIVE_NOISE.match(pending):
            os.write(saved, pending)

    thread = threading.Thread(target=pump, name="stderr-filter", daemon=True)
    thread.start()
    try:
        yield
    finally:
        try:
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        os.dup2(saved, 2)  # closes the pipe's last write end: the pump sees the end
        thread.join(timeout=10)
        os.close(saved)
        _terminal().STDERR_IS_TTY[0] = None
        if _terminal().DIRECT_STDERR[0] is not None:
            try:
                _terminal().DIRECT_STDERR[0].close()
            except (OSError, ValueError):
                pass
            _terminal().DIRECT_STDERR[0] = None


# library warnings that say nothing to a user of the toolbox: the toolbox checks georeferencing
# itself, and deprecations are for the developers
QUIET_WARNINGS = ("NotGeoreferencedWarning", "DeprecationWarning", "PendingDeprecationWarning",
                  "FutureWarning", "SetuptoolsDeprecationWarning", "_BetaConfiguration")


def warning_message(message: Warning | str, category: type, filename: str) -> str | None:
    """A Python warning as one toolbox message line, naming the library it came from (None for
    the :data:`QUIET_WARNINGS`)."""
    if category.__name__ in QUIET_WARNINGS or issubclass(
            category, (DeprecationWarning, PendingDeprecationWarning, FutureWarning)):
        return None
    parts = Path(filename).parts
    source = next((parts[i + 1] for i, p in enumerate(parts[:-1])
                   if p in ("site-packages", "dist-packages")), Path(filename).stem)
    source = source.removesuffix(".py")
    return f"{_one_line(message)} ({source})"


@contextmanager
def _python_warnings_as_messages():
    """Python warnings raised while a command runs (rasterio's, numpy's...) become one-line
    toolbox warnings naming their library, not the raw ``file:line: Category: text`` plus a
    source line, each text once per run (Python shows a warning again whenever a filter
    changed: the same tile warning once per tile); the deprecation and georeferencing noise of
    :data:`QUIET_WARNINGS` is dropped. ``TOOLBOX_DEBUG=1`` shows them raw."""
    import os
    import warnings

    if os.environ.get("TOOLBOX_DEBUG"):
        yield
        return
    from toolbox.feedback import current_runs

    previous = warnings.showwarning
    shown: set[tuple[str, tuple[object, ...]]] = set()

    def show(message, category, filename, lineno, file=None, line=None):
        text = warning_message(message, category, filename)
        key = (text, current_runs())  # each text once per run (a tile's warning, every tile)
        if text is not None and key not in shown:
            import logging

            shown.add(key)
            logging.getLogger("toolbox").warning(text)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = previous


MALLOC_ARENAS = 2  # glibc's default is 8 per core: each thread (GDAL, OpenCV, workers) its own


def limit_malloc_arenas() -> None:
    """At most :data:`MALLOC_ARENAS` glibc malloc arenas in this process (unless the user set
    ``MALLOC_ARENA_MAX``): freed memory kept in per-thread arenas raised the peak resident
    memory of ``ortho:batch`` on 4 drone photos by 70 MB (410 -> 340 MB), at no measured cost
    in time. Nothing on other C libraries."""
    import ctypes
    import os

    if os.environ.get("MALLOC_ARENA_MAX") or not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL("libc.so.6").mallopt(-8, MALLOC_ARENAS)  # M_ARENA_MAX
    except (OSError, AttributeError):  # musl or another libc: nothing to tune
        pass


class OneLineErrorsGroup(click.Group):
    """A click group printing usage mistakes as one line (no ``Usage:`` block), exit 2."""

    def main(self, *args, **kwargs):
        kwargs["standalone_mode"] = False
        try:
            result = super().main(*args, **kwargs)
        except click.exceptions.UsageError as exc:
            command = exc.ctx.command_path if exc.ctx is not None else "toolbox"
            click.echo(f"toolbox: error: {_one_line(exc.format_message())} (see '{command} "
                       "--help')", err=True)
            sys.exit(EXIT_USER_ERROR)
        except click.exceptions.ClickException as exc:
            click.echo(f"toolbox: error: {_one_line(exc.format_message())}", err=True)
            sys.exit(exc.exit_code)
        except click.exceptions.Abort:
            click.echo("toolbox: canceled", err=True)
            sys.exit(EXIT_CANCELED)
        sys.exit(result if isinstance(result, int) else 0)


@click.group(cls=OneLineErrorsGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="toolbox")  # not from the package metadata: faster
@click.option("-v", "--verbose", count=True, help="More messages (-vv for debug).")
@click.option("-q", "--quiet", is_flag=True,
              help="No progress bar, no information messages (warnings still show).")
@click.pass_context
def main(ctx: click.Context, verbose: int, quiet: bool) -> None:
    """Photogrammetric cartography toolbox: from oriented photos and restitution linework to
    GeoPackage and GeoTIFF map deliverables.

    \b
    toolbox list                     the algorithms, by group
    toolbox help dem:idw             parameters, defaults and ranges of one
    toolbox run dem:idw --INPUT pts.gpkg --CELL_SIZE 2 --OUTPUT dem.tif
    toolbox batch pipeline.yaml      several algorithms chained
    toolbox demo --out demo_out      the main job on bundled sample data
    toolbox warmup                   compile the numba kernels once (no first-run wait)
    """
    _terminal().setup_logging(verbose, quiet)
    ctx.obj = {"quiet": quiet, "verbose": verbose}


@main.command("list")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable JSON.")
@_handle_errors
def list_cmd(as_json: bool) -> None:
    """List the algorithms, grouped."""
    from toolbox.registry import spec_index

    specs = list(spec_index().values())
    text = format_list_json(specs) if as_json else format_list(specs)
    if text:
        click.echo(text)


@main.command("help")
@click.argument("algorithm_id", required=False)
@click.option("--json", "as_json", is_flag=True, help="Machine-readable JSON spec.")
@click.option("--all", "show_all", is_flag=True,
              help="Every algorithm; with --json one object {toolbox_version, algorithms: [...]}.")
@_handle_errors
def help_cmd(algorithm_id: str | None, as_json: bool, show_all: bool) -> None:
    """Describe one algorithm (or --all): method, parameters (types, defaults, ranges), outputs."""
    from toolbox.registry import get_spec, spec_index

    if show_all == (algorithm_id is not None):
        raise click.UsageError("give one algorithm id, or --all")
    if show_all:
        specs = list(spec_index().values())
        if as_json:
            click.echo(format_help_all_json(specs))
        else:
            click.echo(format_help_all(specs))
        return
    spec = get_spec(algorithm_id)
    click.echo(format_help_json(spec) if as_json else format_help(spec))


def parse_parameter_args(tokens: list[str]) -> dict[str, Any]:
    """``["--CELL_SIZE", "2", "--FLAG", "--INPUT=a.gpkg"]`` -> ``{"CELL_SIZE": "2", "FLAG":
    "true", "INPUT": "a.gpkg"}``; a repeated name collects a list."""
    params: dict[str, Any] = {}
    i = 0
    while i < len(tokens):
        token = tokens[i]
        if not token.startswith("--") or len(token) < 3:
            raise ParameterError("", f"unexpected argument {token!r}: parameters are given as "
                                 "--NAME value")
        key, eq, value = token[2:].partition("=")
        key = key.upper().replace("-", "_")
        if not eq:
            nxt = tokens[i + 1] if i + 1 < len(tokens) else None
            if nxt is None or (nxt.startswith("--") and len(nxt) > 2):
                value = "true"
            else:
                value, i = nxt, i + 1
        if key in params:
            previous = params[key]
            params[key] = (previous if isinstance(previous, list) else [previous]) + [value]
        else:
            params[key] = value
        i += 1
    return params


@main.command("run", context_settings={"ignore_unknown_options": True,
                                       "allow_extra_args": True, "help_option_names": []})
@click.argument("algorithm_id", required=False)
@click.option("--overwrite", is_flag=True, help="Replace existing outputs (never an input).")
@click.option("--run-report", "report", type=click.Path(dir_okay=False),
              help="Write a JSON run report (parameters, outputs, statistics, versions, timings).")
@click.option("--progress", type=click.Choice(["bar", "json", "none"]), default="bar",
              show_default=True, help="Progress on stderr: a bar (on a terminal), JSON lines "
              "(one object a line, for a GUI; see docs/cli.md) or none.")
@click.option("-q", "--quiet", "run_quiet", is_flag=True,
              help="No progress bar and no information messages (warnings still show).")
@click.option("-v", "--verbose", "run_verbose", count=True,
              help="More messages (-vv for debug), as before 'run'.")
@click.option("-h", "--help", "show_help", is_flag=True, help="Show the algorithm's help.")
@click.argument("args", nargs=-1, type=click.UNPROCESSED)
@click.pass_context
@_handle_errors
def run_cmd(ctx: click.Context, algorithm_id: str | None, overwrite: bool, report: str | None,
            progress: str, run_quiet: bool, run_verbose: int, show_help: bool,
            args: tuple[str, ...]) -> None:
    """Run an algorithm: toolbox run ID --PARAM value ... (see 'toolbox help ID').

    Prints the outputs as JSON on stdout.
    """
    from toolbox.registry import get
    from toolbox.report import to_jsonable
    from toolbox.runner import run

    limit_malloc_arenas()
    if algorithm_id is None:
        if show_help:
            click.echo(ctx.get_help())
            return
        raise click.UsageError("missing the algorithm id: toolbox run ID --PARAM value ... "
                               "('toolbox list' shows the ids)", ctx)
    if run_verbose:  # -v after 'run' (or after the id) counts as before it
        ctx.obj["verbose"] = ctx.obj.get("verbose", 0) + run_verbose
        _terminal().setup_logging(ctx.obj["verbose"], bool(ctx.obj.get("quiet")))
    if progress == "json" and not show_help:
        _run_with_json_progress(ctx, algorithm_id, overwrite, report, args)
        return
    alg = get(algorithm_id)
    if show_help:
        click.echo(format_help(alg))
        return
    quiet = _apply_quiet(ctx, run_quiet)
    params = parse_parameter_args(list(args))
    feedback = _terminal().TerminalFeedback(alg.id, quiet=quiet or progress == "none")
    _terminal().ACTIVE[0] = feedback
    try:
        outputs = run(alg.id, params, feedback=feedback, overwrite=overwrite, report=report)
    finally:
        feedback.finish()
        _terminal().ACTIVE[0] = None
    click.echo(json.dumps(to_jsonable(outputs), indent=2))


def _run_with_json_progress(ctx: click.Context, algorithm_id: str, overwrite: bool,
                            report: str | None, args: tuple[str, ...]) -> None:
    """``run --progress json``: progress, messages, then the result or the error as JSON lines on
    stderr (:class:`JsonFeedback`); the outputs also on stdout, as without it."""
    from toolbox.cli.terminal import JsonFeedback, setup_json_logging
    from toolbox.registry import get
    from toolbox.report import to_jsonable
    from toolbox.runner import run

    setup_json_logging(ctx.obj["verbose"])
    feedback = JsonFeedback()
    _terminal().ACTIVE[0] = feedback
    committed = len(_committed())
    try:
        alg = get(algorithm_id)
        outputs = to_jsonable(run(alg.id, parse_parameter_args(list(args)), feedback=feedback,
                                  overwrite=overwrite, report=report))
    except ToolboxError as exc:
        feedback.error(str(exc))
        raise
    except KeyboardInterrupt as exc:
        feedback.error(interrupted_message(getattr(exc, "signum", signal.SIGINT), exc, committed))
        raise
    except Exception as exc:  # a bug: still one JSON line for the reader, then the usual report
        feedback.error(f"internal error: {type(exc).__name__}: {exc}")
        raise
    finally:
        _terminal().ACTIVE[0] = None
    feedback.result(outputs)
    click.echo(json.dumps(outputs, indent=2))


def _apply_quiet(ctx: click.Context, quiet_here: bool) -> bool:
    """``--quiet`` given after the command (``toolbox run ID ... --quiet``) as before it: no
    progress bar, no information messages; warnings and errors still show."""
    quiet = bool(ctx.obj and ctx.obj.get("quiet")) or quiet_here
    if quiet_here:
        _terminal().setup_logging(0, True)
    return quiet


@main.command("batch")
@click.argument("pipeline", type=click.Path(exists=True, dir_okay=False))
@click.option("--overwrite", is_flag=True, help="Replace existing outputs.")
@click.option("--validate", "validate_only", is_flag=True,
              help="Check the pipeline (algorithms, parameter names, references) without running.")
@click.option("--report-dir", type=click.Path(file_okay=False),
              help="Write one JSON run report per step there.")
@click.option("--set", "variables", multiple=True, metavar="NAME=VALUE",
              help="Set a pipeline variable (used as ${NAME}).")
@click.pass_context
@_handle_errors
def batch_cmd(ctx: click.Context, pipeline: str, overwrite: bool, validate_only: bool,
              report_dir: str | None, variables: tuple[str, ...]) -> None:
    """Run several algorithms in order from a YAML pipeline; a step uses an earlier step's
    output as ${step.OUTPUT}. Prints every step's outputs as JSON."""
    from toolbox.batch import load_pipeline, run_pipeline, validate_pipeline
    from toolbox.errors import PipelineError
    from toolbox.report import to_jsonable

    bad = next((v for v in variables if "=" not in v or not v.split("=", 1)[0].strip()), None)
    if bad is not None:
        raise PipelineError(f"--set {bad!r}: expected NAME=VALUE (e.g. --set out=results)")
    extra = dict(v.split("=", 1) for v in variables)
    pipe = load_pipeline(pipeline, extra)
    existing: list[Path] = []
    # values too, before anything runs: nothing is written if a later step is wrong
    validate_pipeline(pipe, overwrite, existing if validate_only else None, report_dir)
    if validate_only:
        note = f" ({len(existing)} outputs exist: pass --overwrite to replace them)" \
            if existing else ""
        click.echo(f"{pipeline}: {len(pipe.steps)} steps, valid{note}")
        return
    feedback = _terminal().TerminalFeedback("batch", quiet=_apply_quiet(ctx, False))
    _terminal().ACTIVE[0] = feedback
    try:
        results = run_pipeline(pipe, feedback=feedback, overwrite=overwrite,
                               report_dir=report_dir)
    finally:
        feedback.finish()
        _terminal().ACTIVE[0] = None
    click.echo(json.dumps(to_jsonable(results), indent=2))


@main.command("demo")
@click.option("--out", "out_dir", default="demo_out", show_default=True,
              type=click.Path(file_okay=False), help="Folder for sample data and outputs.")
@click.pass_context
@_handle_errors
def demo_cmd(ctx: click.Context, out_dir: str) -> None:
    """Run the main job on bundled sample data and print where the outputs are."""
    from toolbox.demo import run_demo

    feedback = _terminal().TerminalFeedback("demo", quiet=ctx.obj["quiet"])
    _terminal().ACTIVE[0] = feedback
    try:
        summary = run_demo(Path(out_dir), feedback=feedback)
    finally:
        feedback.finish()
        _terminal().ACTIVE[0] = None
    click.echo(summary)


@main.command("warmup")
@click.pass_context
@_handle_errors
def warmup_cmd(ctx: click.Context) -> None:
    """Compile every numba kernel into the per-user cache, so that no first run waits for it,
    and build the kernels compiled ahead of time (runs load them without numba; needs a C
    compiler) (``make venv`` runs it once; about a minute)."""
    import numba

    from toolbox.warmup import warmup

    if not ctx.obj["quiet"]:
        click.echo("Compiling the numba kernels (about a minute)...", err=True)
    import logging

    toolbox_log = logging.getLogger("toolbox")
    level = toolbox_log.level
    toolbox_log.setLevel(logging.ERROR)  # the sample runs' warnings are not the user's
    try:
        steps = warmup()
    finally:
        toolbox_log.setLevel(level)
    import os

    from toolbox.aot import EXPORTS, aot_folder, module_path

    built = sum(os.path.isfile(module_path(name)) for name in EXPORTS)
    click.echo(f"Warm-up finished: {steps} runs; compiled kernels in {numba.config.CACHE_DIR}; "
               f"{built} of {len(EXPORTS)} ahead-of-time kernels in {aot_folder()}")
    if built < len(EXPORTS):
        click.echo("warning: the ahead-of-time kernels were not built (a C compiler and "
                   "Python's headers are needed): runs use numba's JIT (and numpy steps for the "
                   "bulk GeoPackage writer and the TIN's tables)", err=True)


if __name__ == "__main__":  # pragma: no cover
    main()
