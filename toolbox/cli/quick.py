"""``toolbox --version``, ``list`` and ``help`` answered without click, logging, the registry or
any algorithm module: from the cached spec index when nothing was installed or edited since it
was written (:func:`toolbox.spec_cache.fresh_index`).

:func:`answer` handles only the plain forms (``--version``; ``list [--json]``; ``help ID
[--json]``; ``help --all [--json]``) and returns None for anything else (other commands, global
options, ``--help``, a missing or stale index, an unknown id): the click application
(:mod:`toolbox.cli.app`) then does the work, and builds the index. Both print the same bytes
(the texts come from :mod:`toolbox.cli.helptext`).
"""

from __future__ import annotations

import sys

from toolbox.version import __version__

HELP_FLAGS = {"--json", "--all"}


def answer(args: list[str]) -> int | None:
    """The exit code after printing the answer to ``toolbox *args``, or None when the click
    application must handle it."""
    if args == ["--version"]:
        return _echo(f"toolbox, version {__version__}")
    if not args or args[0] not in ("list", "help"):
        return None
    command, rest = args[0], args[1:]
    flags = {a for a in rest if a.startswith("-")}
    names = [a for a in rest if not a.startswith("-")]
    if command == "list" and (names or not flags <= {"--json"}):
        return None
    if command == "help" and (not flags <= HELP_FLAGS
                              or len(names) != (0 if "--all" in flags else 1)):
        return None
    from toolbox.spec_cache import fresh_index

    index = fresh_index()
    if index is None:
        return None
    from toolbox.cli import helptext

    specs = index["specs"]
    as_json = "--json" in flags
    if command == "list":
        text = (helptext.format_list_json if as_json else helptext.format_list)(list(specs.values()))
        return _echo(text) if text else 0
    if not names:
        every = list(specs.values())
        return _echo(helptext.format_help_all_json(every) if as_json
                     else helptext.format_help_all(every))
    spec = specs.get(index["aliases"].get(names[0], names[0]))
    if spec is None:
        return None  # the click command's message suggests close ids
    return _echo(helptext.format_help_json(spec) if as_json else helptext.format_help(spec))


def _echo(text: str) -> int:
    """Print ``text`` and a newline on stdout: exit code 0; 1 when the reader left (``toolbox
    list | head``), silently, as the click commands do."""
    try:
        sys.stdout.write(text + "\n")
        sys.stdout.flush()
    except BrokenPipeError:
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error while flushing at exit
        return 1
    return 0
