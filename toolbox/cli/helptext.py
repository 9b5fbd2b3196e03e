"""The text of ``toolbox list`` and ``toolbox help``, generated from the specs (dicts of
:meth:`Algorithm.spec`); used by the click commands and by the quick answers of
:mod:`toolbox.cli.quick`, which must print the same bytes. No click here."""

from __future__ import annotations

from toolbox.version import __version__

# json and textwrap are imported where used: both import ``re``, which ``toolbox list`` does
# not need

LIST_FIELDS = ("id", "display_name", "group", "short_help")


def format_list(specs: list[dict]) -> str:
    """``toolbox list``: the ids and short help texts under their group names ("" if none)."""
    groups: dict[str, list] = {}
    for spec in specs:
        groups.setdefault(spec["group"], []).append(spec)
    width = max((len(s["id"]) for s in specs), default=10) + 2
    lines = []
    for group in sorted(groups):
        lines.append(f"{group}")
        for spec in groups[group]:
            lines.append(f"  {spec['id']:<{width}}{spec['short_help']}")
    return "\n".join(lines)


def format_list_json(specs: list[dict]) -> str:
    """``toolbox list --json``: id, display name, group and short help of every algorithm."""
    import json

    return json.dumps([{k: s[k] for k in LIST_FIELDS} for s in specs], indent=2)


def format_help_json(spec: dict) -> str:
    """``toolbox help ID --json``: the spec as indented JSON."""
    import json

    return json.dumps(spec, indent=2)


def format_help_all(specs: list[dict]) -> str:
    """``toolbox help --all``: every algorithm's help, a blank line between them."""
    return "\n\n".join(format_help(s) for s in specs)


def format_help_all_json(specs: list[dict]) -> str:
    """``toolbox help --all --json``: ``{toolbox_version, algorithms: [spec, ...]}``."""
    import json

    return json.dumps({"toolbox_version": __version__, "algorithms": specs}, indent=2)


def format_help(alg) -> str:
    """Plain-text help of an algorithm, generated from its spec (an :class:`Algorithm` class or
    the dict of :meth:`Algorithm.spec`)."""
    import textwrap

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
