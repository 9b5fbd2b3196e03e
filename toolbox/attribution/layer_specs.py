"""Declared layers of the attribution outputs (light: parameters only, no kernels)."""

from __future__ import annotations

from toolbox.parameters import Layer, OutputVector

CODED = Layer("*", "Geometry", [("code", "string", "restitution code"),
                                ("description", "string", "from the code file"),
                                ("colour", "string", "#rrggbb")],
              "one layer per code (or per geometry type), named after it; styled")
MOVED_VERTICES = Layer("moved_vertices", "Point", [
    ("feature", "string"), ("vertex", "integer"), ("change", "string"), ("dx", "real"),
    ("dy", "real"), ("displacement", "real", "how far it moved")],
    "every vertex the tool moved, added or removed")


def edited_output(description: str) -> OutputVector:
    """The OUTPUT of an editing tool: the edited layer (named like the input's) and the
    ``moved_vertices`` layer."""
    return OutputVector("OUTPUT", description, layers=[CODED, MOVED_VERTICES])
