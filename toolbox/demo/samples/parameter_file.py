"""The sample parameter files ("file dei parametri", S002 §2.2.1) of the demo sheets: one list
of entries in the thesis' order, the values per sheet (format of toolbox.io.parameter_file)."""

from __future__ import annotations

ENTRIES = (
    "tolleranza di identificazione",
    "tolleranza di riattacco planimetrico",
    "tolleranza di riattacco altimetrico",
    "unità di misura delle coordinate",
    "numero di cifre decimali",
    "traslazione delle coordinate",
    "tolleranza planimetrica di allineamento",
    "tolleranza planimetrica di squadratura",
    "tolleranza angolare di squadratura",
    "passo di spline",
    "tolleranza di chiusura",
    "tolleranza di fine polilinea",
)


def parameter_file_text(comments: list[str], values: tuple[str, ...],
                        extra: dict[str, str] | None = None, extra_comment: str = "") -> str:
    """The file: ``comments`` (each a ``#`` line), one line per entry of :data:`ENTRIES` with
    its value, then ``extra_comment`` and the ``extra`` entries (toolbox extensions)."""
    lines = [f"# {c}" for c in comments]
    lines += [f"{name:<40}= {value}" for name, value in zip(ENTRIES, values, strict=True)]
    if extra_comment:
        lines.append(f"# {extra_comment}")
    lines += [f"{name:<40}= {value}" for name, value in (extra or {}).items()]
    return "\n".join(lines) + "\n"
