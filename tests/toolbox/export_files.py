"""A restitution export file for tests: ``CODE c``, the entity's points, ``END``, per entity."""

from __future__ import annotations

E0, N0 = 1688600.0, 4799900.0  # EPSG:3003 offsets of the points


def write_export(path, entities):
    """``entities``: ``[(code, [(x, y, z), ...]), ...]`` with x, y as offsets from (E0, N0)."""
    lines = []
    for code, pts in entities:
        lines.append(f"CODE {code}")
        lines += [f"{E0 + x:.3f} {N0 + y:.3f} {z:.3f}" for x, y, z in pts]
        lines.append("END")
    path.write_text("\n".join(lines) + "\n")
    return path
