"""PAT-B exterior orientations (the block adjustment program's ``.ori`` output).

Three records per photo (PCI Geomatics, "Using Pat-B in OrthoEngine")::

    I16,16x,3F16.5   photo number, X0, Y0, Z0 of the projection centre
    5F16.12          a11, a12, a13, a21, a22 of the rotation matrix
    4F16.12          a23, a31, a32, a33

The matrix is PAT-B's omega-phi-kappa rotation, which is the product's ``R`` (it maps image
axes x right, y up, z back onto the ground axes: ``X - X0 = λ·R·x``;
:mod:`toolbox.photogrammetry.rotation` calls it the PATB convention), row by row. Direction
verified (tests/toolbox/exchange/test_exchange_patb_direction.py) against the documented PATB
convention: Pix4D's "R ... with angles ω, φ, κ (PATB convention)", ``X' = Rᵀ(X - T)``, and
Orthority's angles "to rotate from camera (PATB convention) to world", on the NGI block's
published angles (scipy's Rx·Ry·Rz as the oracle, OpenCV's projectPoints through the file).
The file states no angle unit (it holds no angles) and no CRS (the caller's applies). Reading
takes the numbers by whitespace, so hand-edited files with other spacing are read too; a line
``-99`` is skipped. Writing keeps the fixed columns; PAT-B's photo numbers are integers, so a
non-numeric id is written as it is and the notes say a strict PAT-B reader may refuse it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.exchange.model import OrientationSet, PhotoOrientation, opk_from_matrix


def _numbers(parts: list[str]) -> list[float] | None:
    try:
        return [float(p) for p in parts]
    except ValueError:
        return None


def _records(lines: list[str]) -> list[list[str]]:
    return [ln.split() for ln in lines if ln.strip() and ln.split() != ["-99"]
            and not ln.lstrip().startswith("#")]


def looks_like(lines: list[str]) -> bool:
    """A first photo's three records: id + 3 numbers, 5 then 4 numbers within [-1, 1]."""
    rows = _records(lines[:6])
    if len(rows) < 3 or len(rows[0]) != 4 or len(rows[1]) != 5 or len(rows[2]) != 4:
        return False
    values = _numbers(rows[0][1:]), _numbers(rows[1]), _numbers(rows[2])
    return all(v is not None for v in values) and \
        max(abs(v) for v in values[1] + values[2]) <= 1.0 + 1e-9


def read_patb(path: str | Path, crs: Any = None, angle_unit: str | None = None) -> OrientationSet:
    """Exterior orientations of a PAT-B file (``angle_unit`` is ignored: it holds matrices)."""
    from toolbox.exchange.geodesy import require_projected

    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputDataError(f"cannot read {path}: {exc}") from None
    rows = _records(lines)
    if not rows or len(rows) % 3:
        raise InputDataError(f"{path}: PAT-B holds three records per photo (id X0 Y0 Z0; a11 a12 "
                             f"a13 a21 a22; a23 a31 a32 a33), got {len(rows)} record(s)")
    out = OrientationSet(source=str(path), format="patb")
    out.crs = None if crs is None else require_projected(crs, str(path))
    for k in range(0, len(rows), 3):
        head, first, second = rows[k:k + 3]
        centre, matrix = _numbers(head[1:]), _numbers(first + second)
        if len(head) != 4 or centre is None or matrix is None or len(matrix) != 9:
            raise InputDataError(f"{path}: photo record {k // 3 + 1} is not 'id X0 Y0 Z0' "
                                 f"followed by the 9 matrix elements (got {head[:1]})")
        pid = head[0]
        out.add_photo(PhotoOrientation(pid, xyz=tuple(centre), opk=opk_from_matrix(
            np.reshape(matrix, (3, 3)), pid)), str(path))
    out.notes.append("rotation matrices (PAT-B's R, image -> ground)")
    if out.crs is None:
        out.notes.append("no CRS (PAT-B states none; give CRS)")
    return out


def write_patb(oset: OrientationSet, path: str | Path) -> Path:
    photos = [p for p in oset.photos.values() if p.oriented]
    if not photos:
        raise InputDataError("no photo has an exterior orientation to write")
    lines = []
    for p in photos:
        a = p.rotation.ravel()
        lines += [f"{p.id:>16}{'':16}" + "".join(f"{v:16.5f}" for v in p.xyz),
                  "".join(f"{v:16.12f}" for v in a[:5]), "".join(f"{v:16.12f}" for v in a[5:])]
    odd = [p.id for p in photos if not p.id.isdigit()]
    if odd:
        oset.notes.append(f"PAT-B photo numbers are integers; written as given: {', '.join(odd)}")
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
