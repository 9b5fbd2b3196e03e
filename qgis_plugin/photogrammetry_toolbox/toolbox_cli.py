"""Talking to the toolbox command line, with no dependency on QGIS (unit-tested on its own).

The plugin runs the toolbox *out of process*, as QGIS's GDAL provider runs the GDAL commands:
QGIS's own Python has an older numpy and its GDAL bindings must not be disturbed, so the toolbox
lives in its own environment and is reached through its ``toolbox`` executable.

- :func:`find_executable`: the configured executable, else ``$PHOTOGRAMMETRY_TOOLBOX``, else
  ``toolbox`` on PATH, else the ``.venv`` of a source checkout next to the plugin.
- :func:`load_specs`: every algorithm spec in one call (``toolbox help --all --json``), cached per
  toolbox version in the user's cache folder.
- :func:`command_line`: the argument list of one run from parameter values already converted to
  the toolbox's text form.
- :func:`parse_progress`: one line of ``--progress json`` output.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import textwrap
from pathlib import Path

ENV_VARIABLE = "PHOTOGRAMMETRY_TOOLBOX"
PROVIDER_ID = "phototoolbox"


VERSIONS: dict[str, str] = {}  # executable -> the version load_specs found


class ToolboxNotFound(RuntimeError):
    """The toolbox executable cannot be found or does not run."""


def warmup_disabled() -> bool:
    """``PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP`` is set to 1, true or yes (not merely set: =0 keeps it)."""
    value = os.environ.get("PHOTOGRAMMETRY_TOOLBOX_NO_WARMUP", "")
    return value.strip().lower() in {"1", "true", "yes"}


def qgis_id(algorithm_id: str) -> str:
    """``dem:idw`` -> ``dem_idw`` (QGIS ids cannot contain ':')."""
    return algorithm_id.replace(":", "_")


def find_executable(configured: str | None = None) -> str:
    """The toolbox executable to run, or :class:`ToolboxNotFound` with what was tried."""
    tried = []
    candidates = [configured, os.environ.get(ENV_VARIABLE), "toolbox"]
    checkout = Path(__file__).resolve().parents[2] / ".venv" / "bin" / "toolbox"
    candidates.append(str(checkout))
    for candidate in candidates:
        if not candidate:
            continue
        tried.append(candidate)
        path = shutil.which(candidate) if os.sep not in candidate else (
            candidate if os.access(candidate, os.X_OK) else None)
        if path:
            return path
    raise ToolboxNotFound(
        "the photogrammetry toolbox executable was not found (tried: " + ", ".join(tried) +
        "). Install the toolbox in its own environment (make venv in its folder, or pip install "
        "photogrammetry-toolbox) and set its path in Processing > Options > Providers > "
        f"Photogrammetry toolbox, or in the {ENV_VARIABLE} environment variable.")


def _run(args: list[str], timeout: float = 120) -> str:
    try:
        done = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
    except OSError as exc:
        raise ToolboxNotFound(f"cannot run {args[0]}: {exc}") from None
    if done.returncode != 0:
        raise ToolboxNotFound(f"{' '.join(args)} failed: {done.stderr.strip()[:500]}")
    return done.stdout


def toolbox_version(executable: str) -> str:
    """``toolbox --version`` text (the cache key)."""
    return _run([executable, "--version"]).strip().split()[-1]


def cache_folder() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "photogrammetry-toolbox" / "qgis"


def load_specs(executable: str, use_cache: bool = True) -> list[dict]:
    """Every algorithm spec, from one ``toolbox help --all --json`` call (cached per version).

    Older toolboxes without ``--all`` are read with ``list --json`` and one ``help ID --json``
    per algorithm (slow; the cache makes it a one-off).
    """
    version = toolbox_version(executable)
    VERSIONS[executable] = version
    cache = cache_folder() / f"specs-{version}.json"
    if use_cache and cache.exists():
        try:
            return json.loads(cache.read_text(encoding="utf-8"))["algorithms"]
        except (OSError, ValueError, KeyError):
            pass
    try:
        doc = json.loads(_run([executable, "help", "--all", "--json"]))
        specs = doc["algorithms"] if isinstance(doc, dict) else doc
    except ToolboxNotFound:
        listing = json.loads(_run([executable, "list", "--json"]))
        specs = [json.loads(_run([executable, "help", item["id"], "--json"])) for item in listing]
    try:
        cache.parent.mkdir(parents=True, exist_ok=True)
        tmp = cache.with_suffix(".part")
        tmp.write_text(json.dumps({"toolbox_version": version, "algorithms": specs}),
                       encoding="utf-8")
        tmp.replace(cache)
    except OSError:
        pass  # a read-only cache folder only costs speed
    return specs


def _extent_parts(text: str, bare_crs: bool = False) -> tuple[list[str], str]:
    """The four numbers of an extent text and its `` [CRS]`` suffix ("" without one);
    ``bare_crs``: a CRS after a space without brackets is one too."""
    text = text.strip()
    crs = ""
    if "[" in text:
        text, crs = text.split("[", 1)
        crs = " [" + crs.rstrip("]").strip() + "]"
    elif bare_crs and " " in text:
        text, crs = text.split(" ", 1)
        crs = f" [{crs.strip()}]"
    return [v.strip() for v in text.split(",")], crs


def qgis_extent_to_toolbox(text: str) -> str:
    """QGIS's ``xmin,xmax,ymin,ymax [CRS]`` -> the toolbox's ``xmin,ymin,xmax,ymax [CRS]``."""
    (xmin, xmax, ymin, ymax), crs = _extent_parts(text)
    return f"{xmin},{ymin},{xmax},{ymax}{crs}"


def toolbox_extent_to_qgis(text: str) -> str:
    """The toolbox's ``xmin,ymin,xmax,ymax [CRS]`` -> QGIS's ``xmin,xmax,ymin,ymax [CRS]``."""
    (xmin, ymin, xmax, ymax), crs = _extent_parts(text, bare_crs=True)
    return f"{xmin},{xmax},{ymin},{ymax}{crs}"


def command_line(executable: str, algorithm_id: str, values: dict[str, object],
                 overwrite: bool = True) -> list[str]:
    """``toolbox run ID --progress json [--overwrite] --NAME value ...`` for the values given
    (None values are left out; a list repeats the option, as the CLI takes several layers)."""
    args = [executable, "run", algorithm_id, "--progress", "json"]
    if overwrite:
        args.append("--overwrite")
    for name, value in values.items():
        if value is None or value == "":
            continue
        if isinstance(value, (list, tuple)):
            for item in value:
                args += [f"--{name}", str(item)]
        elif isinstance(value, bool):
            args += [f"--{name}", "true" if value else "false"]
        else:
            args += [f"--{name}", str(value)]
    return args


_ROLE = re.compile(r":[a-z]+:`~?([^`<]*?)(?:\s*<[^>]*>)?`")
_LITERAL = re.compile(r"``([^`]+)``")
_INTERPRETED = re.compile(r"(?<![\w`])`([^`]+)`(?!`)")
_EMPHASIS = re.compile(r"\*\*([^*]+)\*\*|(?<![\w*])\*([^*\s][^*]*?)\*(?![\w*])")


def clean_help(text: str) -> str:
    """Help text for a QGIS dialog: reStructuredText markup and internal code references
    removed (``X`` -> X, :func:`a.b.c` -> c, **x** -> x), paragraphs as HTML breaks."""
    text = _ROLE.sub(lambda m: m.group(1).strip().split(".")[-1], text or "")
    text = _LITERAL.sub(r"\1", text)
    text = _INTERPRETED.sub(r"\1", text)
    text = _EMPHASIS.sub(lambda m: m.group(1) or m.group(2), text)
    paragraphs = [" ".join(p.split()) for p in textwrap.dedent(text).split("\n\n")]
    return "<br><br>".join(p for p in paragraphs if p)


def short_label(name: str, description: str, limit: int = 48) -> str:
    """A dialog label: the description's first clause, capitalised, then the parameter name
    (``cell size, CRS units (...)`` + CELL_SIZE -> ``Cell size [CELL_SIZE]``)."""
    first = re.split(r" \(|, |; |: | - ", description or "", maxsplit=1)[0].strip() or name
    if len(first) > limit:
        first = first[: limit - 1].rsplit(" ", 1)[0] + "…"
    return f"{first[:1].upper()}{first[1:]} [{name}]"


EXTENT_HELP = ("Draw it on the map or type it in QGIS's order: xmin, xmax, ymin, ymax [CRS] "
               "(the plugin passes it to the toolbox in its own order).")


def warmup_stamp(version: str) -> Path:
    return cache_folder() / f"warmup-{version}.started"


def start_warmup(executable: str, version: str) -> bool:
    """Compile the toolbox's numba kernels once per toolbox version, in the background, the
    first time the plugin loads it (so no first run waits ~30 s); True when started now."""
    stamp = warmup_stamp(version)
    if stamp.exists():
        return False
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        log = open(stamp.with_suffix(".log"), "w", encoding="utf-8")  # noqa: SIM115
        subprocess.Popen([executable, "-q", "warmup"], stdout=log, stderr=log,
                         stdin=subprocess.DEVNULL, start_new_session=True)
        stamp.write_text(executable, encoding="utf-8")
    except OSError:
        return False
    return True


def parse_progress(line: str) -> dict | None:
    """A ``--progress json`` line as a dict (``type`` progress/message/result), else None."""
    line = line.strip()
    if not line.startswith("{"):
        return None
    try:
        item = json.loads(line)
    except ValueError:
        return None
    return item if isinstance(item, dict) else None
