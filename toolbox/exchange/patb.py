"""PAT-B style exterior orientation text: one line per photo, ``id X0 Y0 Z0 omega phi kappa``
(whitespace separated), the block closed by a line ``-99``.

The file states no angle unit: reading needs ANGLE_UNIT (PAT-B users mostly work in gon);
writing uses the unit asked for (default gon) and the report says which. The angles are the
omega-phi-kappa of :mod:`toolbox.photogrammetry.rotation` (PAT-B's own convention). No CRS in
the file either: the caller's CRS applies.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.errors import InputDataError, ParameterError
from toolbox.exchange.model import OrientationSet, PhotoOrientation
from toolbox.photogrammetry.rotation import angle_unit as canonical_unit
from toolbox.photogrammetry.rotation import from_radians, to_radians


def _numbers(parts: list[str]) -> bool:
    try:
        [float(p) for p in parts]
    except ValueError:
        return False
    return True


def looks_like(lines: list[str]) -> bool:
    """A ``-99`` line closing 7-field rows."""
    rows = [ln.split() for ln in lines if not ln.startswith("#")]
    return bool(rows) and any(r == ["-99"] for r in rows) and \
        all(len(r) == 7 and _numbers(r[1:]) for r in rows if r != ["-99"])


def read_patb(path: str | Path, crs: Any = None, angle_unit: str | None = None) -> OrientationSet:
    from toolbox.exchange.geodesy import require_projected

    path = Path(path)
    if angle_unit is None:
        raise ParameterError("ANGLE_UNIT", f"is required for {path.name}: PAT-B files do not "
                             "state their angle unit (rad, deg or gon)")
    unit = canonical_unit(angle_unit, "ANGLE_UNIT")
    out = OrientationSet(source=str(path), format="patb")
    out.crs = None if crs is None else require_projected(crs, str(path))
    for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        if parts == ["-99"]:
            break
        if len(parts) != 7 or not _numbers(parts[1:]):
            raise InputDataError(f"{path}, line {lineno}: expected id X0 Y0 Z0 omega phi kappa, "
                                 f"got {line.strip()[:80]!r}")
        values = [float(p) for p in parts[1:]]
        out.add_photo(PhotoOrientation(parts[0], xyz=tuple(values[:3]),
                                       opk=tuple(float(to_radians(a, unit))
                                                 for a in values[3:])), f"{path} line {lineno}")
    if not out.photos:
        raise InputDataError(f"{path} holds no orientation line")
    out.notes.append(f"angles in {unit} (as given)")
    if out.crs is None:
        out.notes.append("no CRS (PAT-B states none; give CRS)")
    return out


def write_patb(oset: OrientationSet, path: str | Path, angle_unit: str = "gon") -> Path:
    unit = canonical_unit(angle_unit, "ANGLE_UNIT")
    lines = [f"{p.id} {p.xyz[0]:.4f} {p.xyz[1]:.4f} {p.xyz[2]:.4f} "
             + " ".join(f"{from_radians(a, unit):.10f}" for a in p.opk)
             for p in oset.photos.values() if p.oriented]
    if not lines:
        raise InputDataError("no photo has an exterior orientation to write")
    path = Path(path)
    path.write_text("\n".join(lines + ["-99"]) + "\n", encoding="utf-8")
    oset.notes.append(f"PAT-B written with angles in {unit}")
    return path
