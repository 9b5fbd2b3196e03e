"""The ``toolbox`` command: list, help, run, batch, demo.

Parameters of ``run`` are the algorithm's UPPERCASE names: ``--CELL_SIZE 2`` or ``--CELL_SIZE=2``;
repeat an option for a multiple-layer parameter; a boolean given alone (``--OVERVIEWS``) is true.
User mistakes print one line on stderr and exit with code 2; a canceled run (Ctrl-C) exits 130.
"""

from __future__ import annotations

import json
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from toolbox.cli.terminal import ACTIVE, TerminalFeedback, setup_logging
from toolbox.errors import ParameterError, ToolboxError

EXIT_USER_ERROR = 2
EXIT_CANCELED = 130


def _handle_errors(func: Callable) -> Callable:
    """Turn toolbox errors into one-line messages and exit codes (no traceback)."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except ToolboxError as exc:
            if ACTIVE[0] is not None:
                ACTIVE[0].clear_line()
            click.echo(f"toolbox: error: {exc}", err=True)
            sys.exit(EXIT_USER_ERROR)
        except KeyboardInterrupt:
            if ACTIVE[0] is not None:
                ACTIVE[0].clear_line()
            click.echo("toolbox: canceled; no output was written", err=True)
            sys.exit(EXIT_CANCELED)

    return wrapper


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="photogrammetry-toolbox", prog_name="toolbox")
@click.option("-v", "--verbose", count=True, help="More messages (-vv for debug).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, errors only.")
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
    """
    setup_logging(verbose, quiet)
    ctx.obj = {"quiet": quiet, "verbose": verbose}


@main.command("list")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable JSON.")
@_handle_errors
def list_cmd(as_json: bool) -> None:
    """List the algorithms, grouped."""
    from toolbox.registry import spec_index

    specs = list(spec_index().values())
    if as_json:
        click.echo(json.dumps([{k: s[k] for k in ("id", "display_name", "group", "short_help")}
                               for s in specs], indent=2))
        return
    groups: dict[str, list] = {}
    for spec in specs:
        groups.setdefault(spec["group"], []).append(spec)
    width = max((len(s["id"]) for s in specs), default=10) + 2
    for group in sorted(groups):
        click.echo(f"{group}")
        for spec in groups[group]:
            click.echo(f"  {spec['id']:<{width}}{spec['short_help']}")


def format_help(alg) -> str:
    """Plain-text help of an algorithm, generated from its spec (an :class:`Algorithm` class or
    the dict of :meth:`Algorithm.spec`)."""
    spec = alg if isinstance(alg, dict) else alg.spec()
    lines = [f"{spec['id']}  -  {spec['display_name']}  [{spec['group']}]", ""]
    for par in spec["help"].split("\n\n"):
        keep = par.startswith(("  ", "-", "|")) or "\n-" in par or "\n  " in par
        lines += [par if keep else textwrap.fill(par, 96), ""]
    shown = [p for p in spec["parameters"] if not p.get("hidden")]
    for title, params in (("Parameters:", [p for p in shown if not p.get("advanced")]),
                          ("Advanced parameters:", [p for p in shown if p.get("advanced")])):
        if not params:
            continue
        lines.append(title)
        for p in params:
            default = "" if p["default"] is None else f" (default: {p['default']})"
            need = "required" if p.get("required", not p["optional"]) else "optional"
            lines.append(f"  --{p['name']} <{p['expected']}>  {need}{default}")
            text = " ".join(t for t in (p["description"], p.get("help", "")) if t)
            if text:
                lines.append(textwrap.indent(textwrap.fill(text, 88), "      "))
        lines.append("")
    lines += ["Outputs:"]
    for o in spec["outputs"]:
        lines.append(f"  {o['name']} ({o['type']}): {o['description']}")
        for layer in o.get("layers") or ():
            fields = ", ".join(f["name"] for f in layer["fields"])
            lines.append(f"      layer {layer['name']} ({layer['geometry_type'] or 'no geometry'})"
                         + (f": {fields}" if fields else ""))
    lines += ["", "Common options: --overwrite (replace outputs), --run-report FILE.json, --quiet,",
              "  --progress json (machine-readable progress on stderr)"]
    return "\n".join(lines)


@main.command("help")
@click.argument("algorithm_id", required=False)
@click.option("--json", "as_json", is_flag=True, help="Machine-readable JSON spec.")
@click.option("--all", "show_all", is_flag=True,
              help="Every algorithm; with --json one object {toolbox_version, algorithms: [...]}.")
@_handle_errors
def help_cmd(algorithm_id: str | None, as_json: bool, show_all: bool) -> None:
    """Describe one algorithm (or --all): method, parameters (types, defaults, ranges), outputs."""
    from toolbox.registry import get_spec, spec_index
    from toolbox.version import __version__

    if show_all == (algorithm_id is not None):
        raise click.UsageError("give one algorithm id, or --all")
    if show_all:
        specs = list(spec_index().values())
        if as_json:
            click.echo(json.dumps({"toolbox_version": __version__, "algorithms": specs}, indent=2))
        else:
            click.echo("\n\n".join(format_help(s) for s in specs))
        return
    spec = get_spec(algorithm_id)
    click.echo(json.dumps(spec, indent=2) if as_json else format_help(spec))


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
@click.argument("algorithm_id")
@click.option("--overwrite", is_flag=True, help="Replace existing outputs.")
@click.option("--run-report", "report", type=click.Path(dir_okay=False),
              help="Write a JSON run report (parameters, outputs, statistics, versions, timings).")
@click.option("--help", "show_help", is_flag=True, help="Show the algorithm's help.")
@click.option("--progress", type=click.Choice(["bar", "json", "none"]), default="bar",
              show_default=True, help="Progress on stderr: a bar (on a terminal), JSON lines "
              "(one object a line, for a GUI; see docs/cli.md) or none.")
@click.argument("args", nargs=-1, type=click.UNPROCESSED)
@click.pass_context
@_handle_errors
def run_cmd(ctx: click.Context, algorithm_id: str, overwrite: bool, report: str | None,
            show_help: bool, progress: str, args: tuple[str, ...]) -> None:
    """Run an algorithm: toolbox run ID --PARAM value ... (see 'toolbox help ID').

    Prints the outputs as JSON on stdout.
    """
    from toolbox.registry import get
    from toolbox.report import to_jsonable
    from toolbox.runner import run

    if progress == "json" and not show_help:
        _run_with_json_progress(ctx, algorithm_id, overwrite, report, args)
        return
    alg = get(algorithm_id)
    if show_help:
        click.echo(format_help(alg))
        return
    params = parse_parameter_args(list(args))
    feedback = TerminalFeedback(alg.id, quiet=ctx.obj["quiet"] or progress == "none")
    ACTIVE[0] = feedback
    try:
        outputs = run(alg.id, params, feedback=feedback, overwrite=overwrite, report=report)
    finally:
        feedback.finish()
        ACTIVE[0] = None
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
    ACTIVE[0] = feedback
    try:
        alg = get(algorithm_id)
        outputs = to_jsonable(run(alg.id, parse_parameter_args(list(args)), feedback=feedback,
                                  overwrite=overwrite, report=report))
    except ToolboxError as exc:
        feedback.error(str(exc))
        raise
    except KeyboardInterrupt:
        feedback.error("canceled; no output was written")
        raise
    except Exception as exc:  # a bug: still one JSON line for the reader, then the usual report
        feedback.error(f"internal error: {type(exc).__name__}: {exc}")
        raise
    finally:
        ACTIVE[0] = None
    feedback.result(outputs)
    click.echo(json.dumps(outputs, indent=2))


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
    from toolbox.batch import load_pipeline, run_pipeline
    from toolbox.report import to_jsonable

    extra = dict(v.split("=", 1) for v in variables if "=" in v)
    pipe = load_pipeline(pipeline, extra)
    if validate_only:
        click.echo(f"{pipeline}: {len(pipe.steps)} steps, valid")
        return
    feedback = TerminalFeedback("batch", quiet=ctx.obj["quiet"])
    ACTIVE[0] = feedback
    try:
        results = run_pipeline(pipe, feedback=feedback, overwrite=overwrite,
                               report_dir=report_dir)
    finally:
        feedback.finish()
        ACTIVE[0] = None
    click.echo(json.dumps(to_jsonable(results), indent=2))


@main.command("demo")
@click.option("--out", "out_dir", default="demo_out", show_default=True,
              type=click.Path(file_okay=False), help="Folder for sample data and outputs.")
@click.pass_context
@_handle_errors
def demo_cmd(ctx: click.Context, out_dir: str) -> None:
    """Run the main job on bundled sample data and print where the outputs are."""
    from toolbox.demo import run_demo

    feedback = TerminalFeedback("demo", quiet=ctx.obj["quiet"])
    ACTIVE[0] = feedback
    try:
        summary = run_demo(Path(out_dir), feedback=feedback)
    finally:
        feedback.finish()
        ACTIVE[0] = None
    click.echo(summary)


if __name__ == "__main__":  # pragma: no cover
    main()
